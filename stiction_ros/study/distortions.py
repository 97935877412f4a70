"""
What instruments and historians do to a loop's trend before anyone reads it.

Each distortion takes the record as the loop made it (OP, PV, SP, sample
time) and returns it as an export would show it.  None of them touches the
valve: a verdict that changes under one was moved by the instrument or the
timing, not by friction.  Used by :mod:`stiction_ros.study.robustness`.
"""

from dataclasses import dataclass

import numpy as np
from scipy.signal import lfilter


@dataclass(frozen=True)
class Trend:
    """OP, PV and SP as exported, with their sample time in seconds (SP None: not exported)."""

    op: np.ndarray
    pv: np.ndarray
    sp: np.ndarray | None
    sample_time: float


def lag_filter(x: np.ndarray, tau_samples: float) -> np.ndarray:
    """
    Return ``x`` through a first-order lag of ``tau_samples`` (a sensor's or a filter's).

    ``y[k] = a y[k-1] + (1 - a) x[k]`` with ``a = exp(-1 / tau_samples)``: the
    lag of a sensor averaging continuously, read at each sample with no added
    sample of delay; started at rest on the first sample, so a constant
    passes unchanged.
    """
    if tau_samples <= 0:
        raise ValueError(f'a lag needs a positive time constant, not {tau_samples}')
    x = np.asarray(x, dtype=np.float64)
    a = np.exp(-1.0 / tau_samples)
    y, _ = lfilter([1.0 - a], [1.0, -a], x, zi=[a * x[0]])
    return y


def shift_pv(t: Trend, samples: int) -> Trend:
    """
    Return ``t`` with PV (and SP) ``samples`` later than OP (earlier when negative).

    A clock skew or a late time stamp between two tags of one export; the
    rows that lose their partner are cut from both ends.
    """
    k = int(samples)
    if k == 0:
        return t
    n = len(t.op)
    if abs(k) >= n:
        raise ValueError(f'a shift of {k} samples leaves nothing of {n}')
    sp = t.sp
    if k > 0:   # row i shows OP of i and PV of i - k
        return Trend(t.op[k:], t.pv[:n - k], None if sp is None else sp[:n - k], t.sample_time)
    k = -k
    return Trend(t.op[:n - k], t.pv[k:], None if sp is None else sp[k:], t.sample_time)


def swinging_door(x: np.ndarray, deviation: float) -> np.ndarray:
    """
    Return the indices a swinging-door historian keeps of ``x`` at ``deviation``.

    The first and last samples are always kept.  When the straight line
    from the last kept point to the newest sample would miss a sample in
    between by more than ``deviation``, the sample before the newest is
    kept, so the lines between kept points never miss a sample by more
    than ``deviation``.
    """
    x = np.asarray(x, dtype=np.float64)
    if deviation < 0:
        raise ValueError(f'a compression deviation cannot be negative: {deviation}')
    n = len(x)
    if n <= 2:
        return np.arange(n)
    kept, a = [0], 0
    # The slopes from the last kept point that pass within ``deviation`` of
    # every sample since (the doors); a line to a later sample must fit between.
    up, down = np.inf, -np.inf
    for i in range(1, n):
        slope = (x[i] - x[a]) / (i - a)
        if not down <= slope <= up:
            a = i - 1
            kept.append(a)
            up, down = np.inf, -np.inf
        dt = i - a
        up = min(up, (x[i] + deviation - x[a]) / dt)
        down = max(down, (x[i] - deviation - x[a]) / dt)
    if kept[-1] != n - 1:
        kept.append(n - 1)
    return np.array(kept)


def compress(x: np.ndarray, deviation: float) -> np.ndarray:
    """Return ``x`` as a swinging-door historian exports it: its kept points joined by lines."""
    keep = swinging_door(x, deviation)
    return np.interp(np.arange(len(x)), keep, np.asarray(x, dtype=np.float64)[keep])


def every(t: Trend, k: int) -> Trend:
    """Return every ``k``-th row of ``t`` (an export on a coarser grid)."""
    if k < 1:
        raise ValueError(f'keep every k-th row needs k of 1 or more, not {k}')
    return Trend(t.op[::k], t.pv[::k], None if t.sp is None else t.sp[::k], t.sample_time * k)
