"""
One BLAS thread per worker process, for pools that already use every core.

NumPy's BLAS starts a thread per core in each process.  In a pool of one
process per core, the detector's many small least-squares fits
(``analysis.detection.prediction_error``) then fight over the cores: with two
workers on the project's two-core machine one record's fit took 2.7 s
instead of 0.5 s.  A pool passes :func:`one_blas_thread` as its initializer
(:func:`worker_pool` does, and leaves Ctrl-C to the parent).

Limiting the libraries already loaded is not enough: SciPy brings its own
OpenBLAS, loaded only when a worker first needs it, which then started a
thread per core again (a pool simulating the detector's corpus ran 4 times
slower: 800 records in 17.2 s against 3.6 s).  So the environment that a
library reads when it loads says one thread too.
"""

from concurrent.futures import ProcessPoolExecutor
from contextlib import contextmanager
import os
import signal
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


def _worker_start() -> None:
    # Ctrl-C at a terminal reaches the whole process group.  Only the parent answers
    # it (and stops the workers): a worker that took it too would die between two
    # tasks, and the parent, waiting for the queued ones, hung.
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    one_blas_thread()


@contextmanager
def worker_pool(jobs: int) -> Iterator[ProcessPoolExecutor]:
    """
    Yield a pool of ``jobs`` worker processes, each with one BLAS thread, deaf to Ctrl-C.

    Left normally, the pool is shut down once its work is done.  Left by an
    exception (Ctrl-C in this process, or a caller that stopped reading), the
    queued tasks are dropped and the workers stopped at once, not waited for.
    """
    pool = ProcessPoolExecutor(jobs, initializer=_worker_start)
    try:
        yield pool
    except BaseException:
        # No public call stops a running task before Python 3.14's terminate_workers();
        # the workers are taken first, as shutdown() forgets them.
        workers = list((getattr(pool, '_processes', None) or {}).values())
        pool.shutdown(wait=False, cancel_futures=True)
        for proc in workers:
            proc.terminate()
        raise
    pool.shutdown(wait=True)


def pool_map(fn: Callable[[Any], Any], items: Iterable, jobs: int,
             chunksize: int = 1) -> Iterator:
    """
    Yield ``fn(item)`` for each item, in order: in ``jobs`` worker processes when above 1.

    The workers are those of :func:`worker_pool`; with one job the items
    run here, in this process.
    """
    if jobs > 1:
        with worker_pool(jobs) as pool:
            yield from pool.map(fn, items, chunksize=chunksize)
    else:
        yield from map(fn, items)
