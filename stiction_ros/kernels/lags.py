"""
A first-order lag started at rest on its input's first row (the timing check's filter).

``analysis.detection.timing`` reads the controller's law through a lag for
every lag of its grid, on every record: as a Python loop that was a third of
the check's time.  This is the same recursion in the same order, so it gives
the Python loop's bits (test/test_lag_check.py holds it to that loop).
"""

import numpy as np

from stiction_ros._jit import njit
from stiction_ros.kernels.arrays import Floats


@njit(cache=True, nogil=True, aot='f8[:](f8[::1], f8)')
def lag_from_rest(x: Floats, a: float) -> Floats:
    """Return ``y[k] = a y[k - 1] + (1 - a) x[k]`` with ``y[-1] = x[0]``."""
    n = x.shape[0]
    y = np.empty(n)
    if n == 0:
        return y
    b = 1.0 - a
    acc = x[0]
    for k in range(n):
        acc = a * acc + b * x[k]
        y[k] = acc
    return y
