"""Compiled stages of the instrument chain that are not linear filters: a rate limit."""

import numpy as np

from stiction_ros._jit import njit
from stiction_ros.kernels.arrays import Floats, Ints


@njit(cache=True, nogil=True, aot='f8[:](f8[::1], i8[::1], i8[::1], f8)')
def rate_limit(u: Floats, starts: Ints, stops: Ints, rate: float) -> Floats:
    """
    Return ``u`` with its change limited to ``rate`` per sample, at rest at each segment start.

    An actuator that cannot move faster than its air supply or motor allows
    follows a step as a ramp; ``rate`` <= 0 leaves ``u`` as it is.
    """
    out = u.copy()
    if rate <= 0.0:
        return out
    for s in range(starts.shape[0]):
        y = u[starts[s]]
        for i in range(starts[s], stops[s]):
            step = u[i] - y
            if step > rate:
                step = rate
            elif step < -rate:
                step = -rate
            y += step
            out[i] = y
    return out


def limited(u: np.ndarray, segments: list[tuple[int, int]], rate: float) -> Floats:
    """Return :func:`rate_limit` of ``u`` over ``segments`` (a list of (start, stop))."""
    starts = np.array([a for a, _ in segments], dtype=np.int64)
    stops = np.array([b for _, b in segments], dtype=np.int64)
    return rate_limit(np.ascontiguousarray(u, dtype=np.float64), starts, stops, float(rate))
