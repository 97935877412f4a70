"""Compiled steps of the exact discrete plant (``stiction_ros.sim.plant``)."""

import numpy as np

from stiction_ros._jit import njit
from stiction_ros.kernels.arrays import Floats


@njit(cache=True)
def plant_output(c: Floats, x: Floats, d: float, held: float, pv0: float) -> float:
    """Return PV before noise and disturbances, ``pv0 + c x + d held``."""
    acc = 0.0
    for i in range(x.shape[0]):
        acc += c[i] * x[i]
    return pv0 + acc + d * held


@njit(cache=True)
def plant_advance_into(phi: Floats, x: Floats, g0: Floats, now: float, g1: Floats, older: float,
                       fractional: bool, out: Floats) -> None:
    """Write the state one sample on, ``phi x + g0 now (+ g1 older)``, into ``out``."""
    n = x.shape[0]
    for i in range(n):
        acc = 0.0
        for j in range(n):
            acc += phi[i, j] * x[j]
        out[i] = acc + g0[i] * now
        if fractional:
            out[i] += g1[i] * older


@njit(cache=True)
def plant_advance(phi: Floats, x: Floats, g0: Floats, now: float, g1: Floats, older: float,
                  fractional: bool) -> Floats:
    """Return the state one sample on (see :func:`plant_advance_into`)."""
    out = np.empty(x.shape[0])
    plant_advance_into(phi, x, g0, now, g1, older, fractional, out)
    return out
