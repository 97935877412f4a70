"""
Compiled kernels of the data-driven valve models (Kano, Choudhury, He, Stenman).

Each kernel advances a model over an input array from the state array the model
holds (``st``, the layout its module documents), writing the position into
``y`` and the final state back into ``st``, exactly as the model's pure-Python
kernel does.  The state travels in local variables inside the loop and is
loaded and stored once per call: read and written through the array every
sample, LLVM cannot keep it in registers.

The pure-Python kernels stay next to their models as the reference: the tests
compare these with them sample for sample (``ValveModel.simulate_reference``).
"""

import math

from stiction_ros._jit import njit
from stiction_ros.kernels.arrays import Floats
# Kano's step, the breakaway rule and the clamp are identify's compiled ones.
from stiction_ros.kernels.characteristics import apply_characteristic
from stiction_ros.kernels.valve_steps import _breakaway, _clip, _kano_step


_characteristic = njit(cache=True)(apply_characteristic)


@njit(cache=True, aot='void(f8[::1], f8[::1], f8[::1], f8, f8, f8)')
def kano_run(u: Floats, y: Floats, st: Floats, S: float, J: float, a: float) -> None:
    """Kano's model (``stiction_ros.models.kano`` state layout)."""
    fd = 0.5 * (S - J)
    yk, u1, u2, us, d, uf = st[0], st[1], st[2], st[3], st[5], st[6]
    resting = st[4] == 1.0
    for k in range(u.shape[0]):
        uf, u1, u2, us, resting, d, yk = _kano_step(u[k], a, S, J, fd, uf, u1, u2, us,
                                                    resting, d, yk)
        y[k] = yk
    st[0], st[1], st[2], st[3], st[5], st[6] = yk, u1, u2, us, d, uf
    st[4] = 1.0 if resting else 0.0


@njit(cache=True)
def _choudhury_step(x: float, xprev: float, sprev: float, pos: float, xss: float,
                    stuck: float, direction: float, S: float, J: float,
                    fd: float) -> tuple[float, float, float, float, float]:
    """Return ``(pos, xss, stuck, direction, slope sign)`` after filtered input ``x``."""
    dx = x - xprev
    s = 0.0 if dx == 0.0 else math.copysign(1.0, dx)
    if x <= 0.0 or x >= 100.0:
        d = -1.0 if x <= 0.0 else 1.0
        pos = 0.0 if x <= 0.0 else 100.0
        return pos, pos + d * fd, 1.0, d, s
    if stuck == 0.0 and s != sprev:
        stuck = 1.0
        xss = xprev
    if stuck == 1.0:
        d = _breakaway(direction, x - xss, S, J)
        if d != 0.0:
            direction = d
            stuck = 0.0
    if stuck == 0.0:
        pos = _clip(x - direction * fd)
    return pos, xss, stuck, direction, s


@njit(cache=True, aot='void(f8[::1], f8[::1], f8[::1], f8, f8, f8, b1, i8, f8, b1)')
def choudhury_run(u: Floats, y: Floats, st: Floats, S: float, J: float, lam: float, ma_in: bool,
                  char: int, rangeability: float, ma_out: bool) -> None:
    """Choudhury's model (``stiction_ros.models.choudhury`` state layout)."""
    if lam == 1.0 and not ma_in and not ma_out and char == 0:
        _choudhury_plain(u, y, st, S, J)
        return
    fd = 0.5 * (S - J)
    out, pos, xprev, sprev, xss, stuck, direction, xf = (st[0], st[1], st[2], st[3], st[4],
                                                         st[5], st[6], st[7])
    for k in range(u.shape[0]):
        uin = (u[k] - 4.0) * 6.25 if ma_in else u[k]
        x = lam * uin + (1.0 - lam) * xf
        xf = x
        pos, xss, stuck, direction, sprev = _choudhury_step(x, xprev, sprev, pos, xss, stuck,
                                                            direction, S, J, fd)
        xprev = x
        flow = _characteristic(char, pos, rangeability)
        out = 4.0 + flow * 0.16 if ma_out else flow
        y[k] = out
    st[0], st[1], st[2], st[3], st[4], st[5], st[6], st[7] = (out, pos, xprev, sprev, xss,
                                                              stuck, direction, xf)


@njit(cache=True)
def _choudhury_plain(u: Floats, y: Floats, st: Floats, S: float, J: float) -> None:
    """
    Run :func:`choudhury_run` for % in and out, no prefilter and a linear characteristic.

    The common case, with the unit conversions, the filter and the characteristic
    left out rather than evaluated as identities every sample (docs/BENCHMARKS.md has
    the speed), with the same result to the bit (the filter with lambda 1 passes the
    input exactly, and the linear characteristic is the position).
    """
    fd = 0.5 * (S - J)
    pos, xprev, sprev, xss, stuck, direction, x = (st[1], st[2], st[3], st[4], st[5], st[6],
                                                   st[7])
    for k in range(u.shape[0]):
        x = u[k]
        pos, xss, stuck, direction, sprev = _choudhury_step(x, xprev, sprev, pos, xss, stuck,
                                                            direction, S, J, fd)
        xprev = x
        y[k] = pos
    if u.shape[0]:
        st[0] = pos
    st[1], st[2], st[3], st[4], st[5], st[6], st[7] = (pos, xprev, sprev, xss, stuck,
                                                       direction, x)


@njit(cache=True)
def he_run(u: Floats, y: Floats, st: Floats, S: float, J: float) -> None:
    """He's model (``stiction_ros.models.he`` state layout)."""
    fs = 0.5 * (S + J)
    fd = 0.5 * (S - J)
    yk, uprev, ur = st[0], st[1], st[2]
    for k in range(u.shape[0]):
        uk = _clip(u[k])
        c = ur + uk - uprev
        if abs(c) > fs:
            sg = math.copysign(1.0, c)
            yk = _clip(uk - sg * fd)
            ur = sg * fd
        else:
            ur = c
        uprev = uk
        y[k] = yk
    st[0], st[1], st[2] = yk, uprev, ur


@njit(cache=True)
def stenman_run(u: Floats, y: Floats, st: Floats, band: float) -> None:
    """Stenman's model (state: the position)."""
    yk = st[0]
    for k in range(u.shape[0]):
        uk = _clip(u[k])
        if abs(uk - yk) >= band:
            yk = uk
        y[k] = yk
    st[0] = yk
