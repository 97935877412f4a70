"""
One BLAS thread per worker process, for pools that already use every core.

NumPy's BLAS starts a thread per core in each process.  In a pool of one
process per core, the detector's many small least-squares fits
(``analysis.detection.prediction_error``) then fight over the cores: with two
workers on the project's two-core machine one record's fit took 2.7 s
instead of 0.5 s.  A pool passes :func:`one_blas_thread` as its initializer.
"""


def one_blas_thread() -> None:
    """Limit this process's BLAS and OpenMP pools to one thread (no-op without threadpoolctl)."""
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:     # only a speed matter; scikit-learn's installs bring it
        return
    threadpool_limits(1)
