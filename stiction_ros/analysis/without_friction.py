"""
The valve without friction that the verdict with MV weighs a claim against.

A real position reading differs from OP first through timing and its
instruments: it follows OP late (dead time), through an actuator or
transmitter lag, reading a little off in offset and gain.  Before the
verdict calls the misfit of an ideal valve friction, or its absence, it fits
that chain to MV::

    OP -> dead time d -> rate limit -> first-order lag tau -> travel stops
       -> offset + gain * position -> MV

on a grid of ``d`` (quarter samples up to 4, whole samples beyond) and
``tau`` (:data:`TAU_GRID`), then refines both by a compass search, with
offset and gain solved in closed form at every point; a rate limit
(:func:`_rate`) and a travel stop at either end (:func:`_stops`) are then kept
where they fit significantly.  Numpy and the built lag and rate kernels only:
the default analysis loads no scipy.  ``--explain`` fits the
fuller chain (a second lag, a rate limit, travel stops) with scipy's
optimisers, from the same limits, grid and dead-time shift
(:mod:`stiction_ros.analysis.mismatch.instrument`).
"""

from collections.abc import Callable
import math

import numpy as np

from stiction_ros.analysis.fit_core import carried_runs
from stiction_ros.analysis.measures.still import Still, still_valve
from stiction_ros.analysis.verdict import explains
from stiction_ros.kernels.chain import limited
from stiction_ros.kernels.lags import lag_from_rest

# Longest dead time and lag looked for, in samples and in seconds (the smaller wins):
# an actuator a minute late is a broken loop, not a calibration question.
MAX_DELAY = (60.0, 30.0)
MAX_LAG = (60.0, 120.0)
TAU_GRID = (0.0, 0.3, 0.6, 1.0, 1.6, 2.5, 4.0, 6.0, 9.0, 14.0, 20.0, 30.0, 45.0, 60.0)
# Samples the search reads at most: a day of 1e6 samples costs no more than 20 000.
MAX_SEARCH = 20_000
# The compass search after the grid: at most this many moves, down to this step (samples).
MAX_MOVES = 120
STEP_END = 0.01
# Travel stops: levels tried on each side, and the samples a stop must hold to count
# (as --explain's ACTIVE_SAMPLES: a stop that no excursion reaches is no stage).
STOP_LEVELS = 41
STOP_SAMPLES = 8
# The chi-square quantile (one degree of freedom, 1 %) a stop's or a rate limit's SSE
# reduction must pass, on the residuals' effective number of samples (significant).
STOP_CHI2 = 6.635
# The share of the chain's SSE a stop or a rate limit must remove (a real one removes most
# of it: on the development seeds a missing stop left 2-25 times MV's noise variance).
MIN_STAGE_DROP = 1.0 / 3.0
# Rate limits tried, as shares of OP's largest step in a sample; and the moves of the
# joint refinement of dead time, lag and rate (each tries 26 neighbours).
RATE_LEVELS = (0.03, 0.05, 0.08, 0.12, 0.18, 0.25, 0.35, 0.5, 0.7)
RATE_MOVES = 40


def limits(sample_time: float) -> tuple[float, float]:
    """Return the largest dead time and lag (samples) looked for at ``sample_time``."""
    return (min(MAX_DELAY[0], MAX_DELAY[1] / sample_time),
            min(MAX_LAG[0], MAX_LAG[1] / sample_time))


def indices(segments) -> np.ndarray:
    """Return the sample indices covered by ``segments``."""
    return np.concatenate([np.arange(a, b) for a, b in segments])


def shift(x: np.ndarray, d: float, segments) -> np.ndarray:
    """
    Return ``x`` delayed by ``d`` samples (linear interpolation) within each run.

    A run is a segment, or several joined across gaps where ``x`` is known
    (``fit_core.carried_runs``): a dead time reads OP from a gap in MV.
    """
    out = np.array(x, dtype=np.float64, copy=True)
    if d == 0.0:
        return out
    for a, b in carried_runs(segments, x):
        # A negative d (a fraction of a sample) reads ahead; the last value is held.
        pos = np.clip(np.arange(b - a) - d, 0.0, b - a - 1)
        i0 = np.floor(pos).astype(np.int64)
        frac = pos - i0
        i1 = np.minimum(i0 + 1, b - a - 1)
        seg = np.asarray(x[a:b], dtype=np.float64)
        out[a:b] = seg[i0] * (1.0 - frac) + seg[i1] * frac
    return out


def lagged(x: np.ndarray, tau: float, runs) -> np.ndarray:
    """Return ``x`` through a first-order lag of ``tau`` samples, at rest at each run start."""
    out = np.array(x, dtype=np.float64, copy=True)
    if tau <= 0.0:
        return out
    p = math.exp(-1.0 / tau)
    for a, b in runs:
        out[a:b] = lag_from_rest(np.ascontiguousarray(out[a:b]), p)
    return out


def calibrated(y: np.ndarray, mv: np.ndarray, idx: np.ndarray) -> tuple[float, float, float]:
    """Return (offset, gain, SSE) of the least-squares ``mv = offset + gain * y`` on ``idx``."""
    yy, mm = y[idx], mv[idx]
    ym, mm_mean = float(yy.mean()), float(mm.mean())
    dy, dm = yy - ym, mm - mm_mean
    syy = float(dy @ dy)
    gain = float(dy @ dm) / syy if syy > 0.0 else 1.0
    offset = mm_mean - gain * ym
    r = mm - offset - gain * yy
    return offset, gain, float(r @ r)


def _first(segments, n: int) -> list:
    """Return ``segments`` cut after their first ``n`` samples."""
    out, left = [], n
    for a, b in segments:
        if left <= 0:
            break
        out.append((int(a), int(min(b, a + left))))
        left -= b - a
    return out


def fit_without_friction(op: np.ndarray, mv: np.ndarray, segments,
                         sample_time: float) -> dict:
    """
    Return the best valve without friction for MV: its MSE and its stages.

    Returns
    -------
    dict
        ``mse`` on the segments' samples, ``dead_time_s`` and ``lag_s``
        (seconds), ``offset`` and ``gain`` (MV = offset + gain x OP
        through the dead time, rate limit, lag and stop), ``rate_pct_s``
        (the actuator's largest speed, % per second; None where no rate
        limit fits),
        ``stop_low`` and ``stop_high``
        (MV held at or beyond these, % of span; None where no stop fits).

    """
    # A valve cannot travel past its stops whatever OP asks, as for the ideal valve.
    op = np.clip(np.asarray(op, dtype=np.float64), 0.0, 100.0)
    mv = np.asarray(mv, dtype=np.float64)
    # The search reads the first MAX_SEARCH samples (each point costs a pass over them);
    # the chain found is then scored on every sample.
    search = _first(segments, MAX_SEARCH)
    end = search[-1][1]
    op_s, mv_s = op[:end], mv[:end]
    idx = indices(search)
    runs = carried_runs(search, op_s)
    d_max, tau_max = limits(sample_time)
    d_axis = np.unique(np.r_[np.arange(0.0, min(d_max, 4.0) + 1e-9, 0.25),
                             np.arange(4.0, d_max + 1e-9, 1.0)])
    t_axis = [t for t in TAU_GRID if t <= tau_max]
    cache: dict = {}
    rate = 0.0

    def _at_rate(r: float) -> Callable[[float, float], float]:
        def sse_r(d: float, tau: float) -> float:
            key = (round(d, 9), round(tau, 9), r)
            if key not in cache:
                u = shift(op_s, d, search)
                y = lagged(limited(u, runs, r) if r > 0.0 else u, tau, runs)
                cache[key] = calibrated(y, mv_s, idx)[2]
            return cache[key]
        return sse_r

    def sse(d: float, tau: float) -> float:
        return _at_rate(rate)(d, tau)

    here, d, tau = min((sse(d, t), d, t) for d in d_axis for t in t_axis)
    # A dead time and a lag trade off along a valley, which steps that only shrink
    # would stop short in: a compass search from the grid's best.
    here, (d, tau) = _compass(lambda p: sse(*p), here, (d, tau), (0.5, max(0.3, 0.5 * tau)),
                              (d_max, tau_max), (STEP_END, STEP_END), MAX_MOVES)
    rate, tau = _rate(shift(op_s, d, search), mv_s, idx, runs, t_axis, tau, here)
    if rate > 0.0:
        # The ramps read as a longer dead time and a shorter lag before the rate was
        # known, and the SSE is steep in the rate: the three are searched again together,
        # shorter dead times on a grid first (the rate by its logarithm).
        grid = [(_at_rate(r)(x, t), x, t, r)
                for r in rate * np.array([0.7, 0.85, 1.0, 1.15, 1.3])
                for x in np.arange(max(d - 4.0, 0.0), d + 1e-9, 0.5) for t in t_axis]
        here, d, tau, rate = min(grid + [(sse(d, tau), d, tau, rate)])
        _, (d, tau, log_rate) = _compass(
            lambda p: _at_rate(math.exp(p[2]))(p[0], p[1]), here, (d, tau, math.log(rate)),
            (0.5, max(0.3, 0.5 * tau), 0.1), (d_max, tau_max, math.inf),
            (STEP_END, STEP_END, 0.005), RATE_MOVES)
        rate = math.exp(log_rate)
    idx = indices(segments)
    full = carried_runs(segments, op)
    u = shift(op, d, segments)
    # Without a rate limit the kernel is not called: nothing to build or load.
    y = lagged(limited(u, full, rate) if rate > 0.0 else u, tau, full)
    low, high, (offset, gain, total) = _stops(y, mv, idx, calibrated(y, mv, idx))
    return {'mse': total / len(idx), 'dead_time_s': float(d * sample_time),
            'lag_s': float(tau * sample_time), 'offset': float(offset), 'gain': float(gain),
            'rate_pct_s': float(rate / sample_time) if rate > 0.0 else None,
            'stop_low': low, 'stop_high': high}


def _compass(f: Callable[[tuple], float], here: float, x: tuple, step: tuple, upper: tuple,
             end: tuple, moves: int) -> tuple[float, tuple]:
    """
    Return (value, point) of a compass search for the least ``f`` from ``x`` (``f(x)`` = ``here``).

    Every neighbour a step away along any mix of the axes is tried (a
    diagonal follows a valley); the steps halve where none is better, until
    each is under its ``end`` or after ``moves`` moves.  The first two axes
    are held within 0 and their ``upper`` bound; a third is free.
    """
    for _ in range(moves):
        trials = []
        for m in np.ndindex(*(3,) * len(x)):
            if any(k != 1 for k in m):
                p = tuple(v + (k - 1) * h for v, k, h in zip(x, m, step))
                trials.append(tuple(min(max(v, 0.0), hi) if i < 2 else v
                                    for i, (v, hi) in enumerate(zip(p, upper))))
        there, y = min((f(p), p) for p in trials)
        if there < here:
            here, x = there, y
        elif all(h < e for h, e in zip(step, end)):
            break
        else:
            step = tuple(h / 2 for h in step)
    return here, x


def _rate(u: np.ndarray, mv: np.ndarray, idx: np.ndarray, runs, t_axis, tau: float,
          sse: float) -> tuple[float, float]:
    """
    Return (rate limit per sample, lag): the actuator's largest speed where one fits.

    An actuator that cannot move faster than its air supply allows turns OP's
    steps into ramps, which a lag imitates only in part.  The rate is looked
    for on :data:`RATE_LEVELS` shares of OP's largest step (``u``: OP through
    the dead time), each with every lag of ``t_axis`` up to ``tau``, and kept
    where it limits at least :data:`STOP_SAMPLES` steps and the SSE drop is
    :func:`significant`; else (0, ``tau``).  ``sse``: the chain's SSE without it.
    """
    # Steps within each run: the limiter rests at each run's start, across no gap.
    steps = np.concatenate([np.abs(np.diff(u[a:b])) for a, b in runs])
    top = float(np.max(steps)) if len(steps) else 0.0
    if top <= 0.0:
        return 0.0, tau
    best = (sse, 0.0, tau)
    # The lag had imitated part of the ramps: with a rate limit it is no longer.
    shorter = sorted({t for t in t_axis if t < tau} | {tau})
    for r in top * np.asarray(RATE_LEVELS):
        ramped = limited(u, runs, float(r))
        for t in shorter:
            there = calibrated(lagged(ramped, t, runs), mv, idx)[2]
            if there < best[0]:
                best = (there, float(r), t)
    there, rate, t = best
    if rate <= 0.0 or int(np.sum(steps > rate)) < STOP_SAMPLES:
        return 0.0, tau
    y = lagged(limited(u, runs, rate), t, runs)
    offset, gain, _ = calibrated(y, mv, idx)
    if significant(sse, there, mv[idx] - offset - gain * y[idx]):
        return rate, t
    return 0.0, tau


def significant(sse: float, there: float, residual: np.ndarray) -> bool:
    """
    Return whether a stage that lowers the SSE from ``sse`` to ``there`` is no noise-fitting.

    It must remove :data:`MIN_STAGE_DROP` of the SSE, and pass the
    likelihood ratio of one more parameter against :data:`STOP_CHI2`,
    counted on the effective number of samples of ``residual`` (the richer
    chain's): residuals that follow each other (a slow misfit, as a sticking
    valve leaves) carry fewer independent samples than they number, and a
    stage that only bends such a misfit must pass on those.
    """
    if there <= 0.0:
        return sse > 0.0
    if there > (1.0 - MIN_STAGE_DROP) * sse:
        # A stage that removes a small part of the misfit is not what the misfit is: a
        # stop or a rate limit bending the rests and jumps a sticking valve leaves.
        return False
    n = len(residual)
    if n < 3:
        return False
    r = residual - residual.mean()
    den = float(r @ r)
    rho = float(r[:-1] @ r[1:]) / den if den > 0.0 else 0.0
    rho = min(max(rho, 0.0), 0.999)
    return n * (1.0 - rho) / (1.0 + rho) * math.log(sse / there) > STOP_CHI2


Calibration = tuple[float, float, float]


def _stops(y: np.ndarray, mv: np.ndarray, idx: np.ndarray,
           fit: Calibration) -> tuple[float | None, float | None, Calibration]:
    """
    Return (low stop, high stop, (offset, gain, SSE)): the valve held at a travel stop.

    A valve held short of what OP asks at one end of its travel (a limit stop,
    a positioner's range) is no friction.  A stop is looked for on the
    chain's position ``y`` (before the calibration, which is solved again at
    each level: a stop left out pulls the gain down) between its 85th and
    100th percentile (15th and 0th), on :data:`STOP_LEVELS` levels, and kept
    where it holds at least :data:`STOP_SAMPLES` samples and its SSE drop is
    :func:`significant`.  One end only, the more significant:
    stops at both ends of a narrow travel are a limit cycle's reversals, where
    a sticking valve rests, not two limits.  ``fit``: (offset, gain, SSE)
    without a stop.  The stop is returned in MV's units, None where none fits.
    """
    # The levels are chosen on at most MAX_SEARCH samples, as the chain's stages are.
    near = idx[:MAX_SEARCH]
    y_near, mv_near, n_idx = y[near], mv[near], np.arange(len(near))
    best: tuple[float, int, float, Calibration] | None = None
    for side, clip, qs in ((1, np.minimum, (0.85, 1.0)), (0, np.maximum, (0.0, 0.15))):
        a, b = (float(v) for v in np.quantile(y_near, qs))
        if not b > a:
            continue
        levels = np.linspace(a, b, STOP_LEVELS)
        at = float(min(levels, key=lambda x: calibrated(clip(y_near, x), mv_near, n_idx)[2]))
        held = int(np.sum(y[idx] > at) if side else np.sum(y[idx] < at))
        if held < STOP_SAMPLES:
            continue
        stopped = clip(y, at)
        there = calibrated(stopped, mv, idx)
        residual = mv[idx] - there[0] - there[1] * stopped[idx]
        if significant(fit[2], there[2], residual):
            ratio = math.inf if there[2] <= 0.0 else fit[2] / there[2]
            if best is None or ratio > best[0]:
                best = (ratio, side, at, there)
    if best is None:
        return None, None, fit
    _, side, at, fit = best
    offset, gain, _ = fit
    stop = offset + gain * at
    # A reversed reading (a negative gain) holds MV at its other end.
    return (None, stop, fit) if (side == 1) == (gain >= 0.0) else (stop, None, fit)


def follows_op(op: np.ndarray, mv: np.ndarray, segments, sample_time: float,
               noise: float | None, chain: dict | None = None) -> bool:
    """
    Return whether MV follows OP through timing, though it spread within its noise.

    OP's spread can be mostly its own noise (a controller acting on a noisy PV
    every sample) while MV, behind an actuator or transmitter lag, follows
    only its slow part: then MV's spread is small against OP's, and the two
    correlate weakly sample by sample.  A valve without friction that fits MV
    down to its noise with a working calibration says MV moved with OP; a
    dead or held reading needs a gain near zero, which no working reading has.
    ``chain``: that valve, where the fits already have it.
    """
    chain = chain or fit_without_friction(op, mv, segments, sample_time)
    return explains(chain, noise)


def still_reading(op: np.ndarray, mv: np.ndarray, segments, sample_time: float,
                  fit: dict) -> tuple[Still | None, bool]:
    """
    Return (the still valve of ``still_valve`` or None, whether :func:`follows_op` overruled it).

    The verdict and ``--explain`` read a valve as still by this one test;
    ``fit`` is a fit's report entry (its ``mv_noise_var``, and its
    ``frictionless`` valve where one was fitted), ``{}`` where there is none.
    """
    still = still_valve(op, mv, segments)
    if still is not None and not still.drifted and follows_op(
            op, mv, segments, sample_time, fit.get('mv_noise_var'), fit.get('frictionless')):
        return None, True
    return still, False
