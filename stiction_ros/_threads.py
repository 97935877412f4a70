"""
One BLAS thread per worker process, for pools that already use every core.

NumPy's BLAS starts a thread per core in each process.  In a pool of one
process per core, the detector's many small least-squares fits
(``analysis.detection.prediction_error``) then fight over the cores: with two
workers on the project's two-core machine one record's fit took 2.7 s
instead of 0.5 s.  A pool passes :func:`one_blas_thread` as its initializer.

Limiting the libraries already loaded is not enough: SciPy brings its own
OpenBLAS, loaded only when a worker first needs it, which then started a
thread per core again (a pool simulating the detector's corpus ran 4 times
slower: 800 records in 17.2 s against 3.6 s).  So the environment that a
library reads when it loads says one thread too.
"""

from concurrent.futures import ProcessPoolExecutor
import os
from typing import Any, Callable, Iterable, Iterator

THREAD_VARIABLES = ('OMP_NUM_THREADS', 'OPENBLAS_NUM_THREADS', 'MKL_NUM_THREADS')


def one_blas_thread() -> None:
    """Limit this process's BLAS and OpenMP pools, loaded or not yet, to one thread."""
    for name in THREAD_VARIABLES:
        os.environ[name] = '1'
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:     # only a speed matter; scikit-learn's installs bring it
        return
    threadpool_limits(1)


def pool_map(fn: Callable[[Any], Any], items: Iterable, jobs: int,
             chunksize: int = 1) -> Iterator:
    """
    Yield ``fn(item)`` for each item, in order: in ``jobs`` worker processes when above 1.

    Each worker runs :func:`one_blas_thread` first; with one job the items
    run here, in this process.
    """
    if jobs > 1:
        with ProcessPoolExecutor(jobs, initializer=one_blas_thread) as pool:
            yield from pool.map(fn, items, chunksize=chunksize)
    else:
        yield from map(fn, items)
