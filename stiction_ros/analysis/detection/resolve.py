"""
Whether a record can be judged at all: the `cannot tell` answers and their reasons.

A detector that votes on a record it cannot read is worse than one that
declines.  These checks run before any signature or learned model and are
deliberately plain, each with a reason an engineer can act on:

* too short: fewer than ``MIN_SAMPLES`` usable samples;
* PV constant: the measurement never moves (a frozen transmitter, a dead
  historian tag, a zero flow, or 3.5e-44: a whole number's bits read as a
  float by the export), so nothing in it can show a valve;
* cycling against OP's limits: OP swings from one limit to the other again
  and again (and stands at one in a share of the samples), as too much gain
  or an on-off action drives a loop with any valve; a valve driven from stop
  to stop shows nothing of its friction, and the simulated loops the detector
  learned from keep OP inside its range;
* no excitation: OP never moves beyond its own resolution, so the valve was
  never asked to move (manual mode, saturated output);
* under-sampled: the loop's own cycle is shorter than ``MIN_PERIOD_SAMPLES``
  samples, or alternates sample to sample, so stick-slip cannot be resolved
  and any size estimate would be an alias;
* not in control: the set point lies farther from PV than PV's whole range,
  on one side all record, while OP moves with no trend to speak of.  With
  integral action an error of one sign drives OP one way until it saturates,
  so this OP is not acting on this error (an override selector chose another
  controller, the output tracks, or the SP column is another loop's): reading
  the record as a closed loop would judge a valve by a controller that is not
  driving it.

:func:`period_sanity` (in :mod:`stiction_ros.analysis.oscillation`) is the
rule every oscillation-based signature obeys: a cycle shorter than
``MIN_PERIOD_SAMPLES`` samples or longer than a quarter of the record is
unresolvable and gets no vote.
"""

from dataclasses import dataclass

import numpy as np

from stiction_ros.analysis.oscillation import MIN_PERIOD_SAMPLES, period_sanity

__all__ = ['alternating', 'cycle_judgeable', 'in_control', 'Judgeable', 'judgeable', 'lag1',
           'limit_swings',
           'MIN_PERIOD_SAMPLES', 'MIN_SAMPLES', 'period_sanity', 'robust_noise']

MIN_SAMPLES = 200
# Distinct-value and spread floors that separate a frozen signal from a quiet one.
MIN_DISTINCT = 5
RELATIVE_FLOOR = 1e-9
# OP moving less than this (% of span, peak to peak) never asked the valve to move.
MIN_OP_TRAVEL = 0.05
# |PV| at or below this throughout reads as zero.
ZERO = 1e-12
# Below this a 32-bit float is subnormal: no transmitter reads there.
FLOAT32_TINY = float(np.finfo(np.float32).tiny)
# Lag-1 autocorrelation below this means a cycle near the Nyquist frequency.
ALTERNATING = -0.35
# Not in control: |median(SP - PV)| at least this many times PV's range, the
# error of one sign in at least ONE_SIGNED of the samples, OP at a limit in
# less than half of them and its trend over the record under NET_OP of its
# range.  No simulated record of 18 000 (training, calibration, scoring and CNN seeds)
# comes near: the largest offset among one-signed errors is 0.61 ranges.
SP_OUTSIDE = 1.0
ONE_SIGNED = 0.99
NET_OP = 0.5
OP_LIMITS = (0.5, 99.5)
# Cycling against the limits: OP goes from one limit (OP_LIMITS) to the other at least
# this often (twice there and back), and stands at a limit in at least LIMIT_SHARE of
# the samples (four trips in a long record that is otherwise inside its range are not
# a cycle).  In the 7 500 training and calibration records OP never goes from one
# limit to the other more than once; of the first network's corpus of 40 000, two
# records do so 4 times or more.  Detuned past stability, healthy loops read as
# stiction (docs/DETECTION.md section 1).
LIMIT_SWINGS = 4
LIMIT_SHARE = 0.05


@dataclass(frozen=True)
class Judgeable:
    """Whether a record can be judged; ``reason`` says why not, ``code`` names the rule."""

    ok: bool
    code: str = ''
    reason: str = ''

    def to_json(self) -> dict:
        """Return the JSON-able fields."""
        return {'ok': self.ok, 'code': self.code, 'reason': self.reason}


def robust_noise(x: np.ndarray) -> float:
    """Return the white-noise standard deviation of ``x`` from its first differences (MAD)."""
    d = np.diff(np.asarray(x, dtype=np.float64))
    if d.size < 2:
        return 0.0
    return float(1.4826 * np.median(np.abs(d - np.median(d))) / np.sqrt(2.0))


def _frozen(x: np.ndarray) -> bool:
    scale = max(float(np.max(np.abs(x))), 1.0)
    return (np.unique(x).size < MIN_DISTINCT
            or float(np.ptp(x)) <= RELATIVE_FLOOR * scale or float(np.ptp(x)) < 1e-30)


def _constant_pv_reason(op: np.ndarray, pv: np.ndarray) -> str:
    k = int(np.unique(pv).size)
    values = 'one value' if k == 1 else f'{k} distinct values'
    low, high = float(np.min(op)), float(np.max(op))
    top = float(np.max(np.abs(pv)))
    if k == 1 and 0.0 < top < FLOAT32_TINY:
        # A real measurement never sits on one subnormal: these are the bits of
        # a whole number (25 for 3.5e-44) read as a 32-bit float.
        bits = int(np.array(pv[0], dtype=np.float32).view(np.int32))
        return (f'PV is {float(pv[0]):.4g} in every sample, the bits of the whole number '
                f'{bits} read as a 32-bit float: the export most likely read this tag with '
                f'the wrong data type; check the historian export. The record shows '
                f'nothing of the valve')
    fraction = 0.0 <= low and high <= 1.0
    if top <= ZERO and (high - low >= MIN_OP_TRAVEL or (fraction and high > low)):
        # Nothing passed, or the range bottomed out: neither shows the valve move.
        unit = '' if fraction else ' %'
        hint = (' (OP stays within 0-1: if it is a fraction of the stroke, give it in %)'
                if fraction else '')
        return (f'PV reads zero in every sample while OP moved between {low:.3g} and '
                f'{high:.3g}{unit}{hint}: for a flow, nothing passed (the valve shut, stuck '
                f'or not off its seat at this OP, or the line blocked in upstream) or the '
                f'transmitter is below its low-flow cut-off; a level or pressure at exactly '
                f'zero is more likely the bottom of its measuring range. The record shows '
                f'nothing of how the valve moves')
    return (f'PV is constant ({values}, range {float(np.ptp(pv)):.3g}): the measurement '
            f'shows nothing of the valve; check the transmitter or the historian tag')


def lag1(x: np.ndarray) -> float:
    """Return the lag-1 autocorrelation of ``x`` about its mean (0 for a constant)."""
    x = x - x.mean()
    den = float(np.dot(x, x))
    return float(np.dot(x[1:], x[:-1]) / den) if den > 0 else 0.0


def judgeable(op: np.ndarray, pv: np.ndarray, sample_time: float,
              sp: np.ndarray | None = None) -> Judgeable:
    """
    Return whether OP and PV (held, contiguous) can be judged for stiction, and why not.

    ``sp`` (the same samples, or None) adds the not-in-control check.
    """
    op = np.asarray(op, dtype=np.float64)
    pv = np.asarray(pv, dtype=np.float64)
    n = len(pv)
    if n < MIN_SAMPLES:
        return Judgeable(False, 'too_short',
                         f'too short: {n} usable samples, at least {MIN_SAMPLES} needed')
    if _frozen(pv):
        return Judgeable(False, 'pv_constant', _constant_pv_reason(op, pv))
    # Before the frozen-OP check: an OP slammed between 0 and 100 % has two values.
    swings = limit_swings(op)
    # The share only where the swings are there: most records never reach a limit.
    at_limit = (float(np.mean((op <= OP_LIMITS[0]) | (op >= OP_LIMITS[1])))
                if swings >= LIMIT_SWINGS else 0.0)
    if at_limit >= LIMIT_SHARE:
        return Judgeable(False, 'limit_cycling',
                         f'OP swung from one limit to the other {swings} times (at 0 or 100 % '
                         f'in {100 * at_limit:.0f} % of the samples): the loop cycles against '
                         f"OP's limits, as too much controller gain or an on-off action makes "
                         f'it do with any valve, and a valve driven from stop to stop shows '
                         f'nothing of its friction (the simulated loops the detector learned '
                         f'from keep OP inside its range); retune it, or read a stretch where '
                         f'OP stays inside its range')
    if _frozen(op) or float(np.ptp(op)) < MIN_OP_TRAVEL:
        # Some historians export OP as a 0-1 fraction; every threshold here is in %.
        fraction = (0.0 < float(np.ptp(op)) and float(np.max(np.abs(op))) <= 1.0
                    and not _frozen(op))
        travel = float(np.ptp(op))
        if fraction:
            return Judgeable(False, 'no_excitation',
                             f'OP stays within 0-1 and moved through {travel:.3g}: if it is a '
                             f'fraction of the stroke ({100 * travel:.3g} % of it), give it in '
                             f'% (x 100), as every threshold here reads it; read as %, the '
                             f'valve was never asked to move')
        return Judgeable(False, 'no_excitation',
                         f'OP never moved more than {travel:.3g} % (manual mode or '
                         f'saturated?): the valve was never asked to move')
    d_pv = np.diff(pv)
    if alternating(op, pv):
        return Judgeable(False, 'under_sampled',
                         f'OP and PV alternate from sample to sample: the loop cycles faster '
                         f'than 2-3 samples of {sample_time:g} s, so stick-slip cannot be '
                         f'resolved; record at a shorter sample time')
    if float(np.std(d_pv)) == 0.0:
        return Judgeable(False, 'pv_constant', 'PV does not vary')
    return in_control(op, pv, sp)


def alternating(op: np.ndarray, pv: np.ndarray) -> bool:
    """Return whether OP and PV alternate from sample to sample (a cycle of 2-3 samples)."""
    return bool(lag1(np.diff(op)) < ALTERNATING - 0.2 and lag1(pv - np.mean(pv)) < ALTERNATING)


def limit_swings(op: np.ndarray) -> int:
    """Return how often OP went from one of its limits (``OP_LIMITS``) to the other."""
    side = np.where(op <= OP_LIMITS[0], -1, np.where(op >= OP_LIMITS[1], 1, 0))
    side = side[side != 0]
    return int(np.count_nonzero(side[1:] != side[:-1]))


def in_control(op: np.ndarray, pv: np.ndarray, sp: np.ndarray | None) -> Judgeable:
    """Return whether OP can be acting on SP - PV at all (the not-in-control check)."""
    if sp is None:
        return Judgeable(True)
    err = np.asarray(sp, dtype=np.float64) - pv
    known = np.isfinite(err)
    if known.sum() < len(err) // 2:
        return Judgeable(True)
    # A flagged SP sample says nothing either way; the rest still do.
    err = err[known]
    offset = float(np.median(err))
    one_signed = float(np.mean(np.sign(err) == np.sign(offset)))
    span = float(np.ptp(pv))
    at_limit = float(np.mean((op <= OP_LIMITS[0]) | (op >= OP_LIMITS[1])))
    # OP's trend over the record (least squares), which wind-up would make
    # nearly all of its range.
    t = np.arange(len(op), dtype=np.float64)
    net = abs(float(np.polyfit(t, op, 1)[0])) * (len(op) - 1)
    if (abs(offset) >= SP_OUTSIDE * span and one_signed >= ONE_SIGNED and at_limit < 0.5
            and net < NET_OP * float(np.ptp(op))):
        side = 'below' if offset > 0 else 'above'
        return Judgeable(False, 'not_in_control',
                         f'not in control: PV stays {side} the set point in '
                         f'{100 * one_signed:.0f} % of the samples, {abs(offset):.3g} away '
                         f"({abs(offset) / span:.1f} times PV's range), yet OP does not wind "
                         f'up: OP is not acting on this error (an override or selector, '
                         f"output tracking, or another loop's set point); check which "
                         f'controller drives the valve')
    return Judgeable(True)


def cycle_judgeable(oscillating: bool, period_s: float | None,
                    sample_time: float) -> Judgeable:
    """
    Return whether a record whose error cycles regularly can be judged.

    A regular cycle of fewer than ``MIN_PERIOD_SAMPLES`` samples is the
    loop's main behaviour and its shape is lost between samples: whether
    the valve sticks in it cannot be told, and a band sized from it would
    be an alias.
    """
    if oscillating and period_s and period_s / sample_time < MIN_PERIOD_SAMPLES:
        return Judgeable(False, 'under_sampled',
                         f'under-sampled: the loop cycles every {period_s:.4g} s, only '
                         f'{period_s / sample_time:.1f} samples of {sample_time:g} s; stick-slip '
                         f'in it cannot be resolved (at least {MIN_PERIOD_SAMPLES:g} samples a '
                         f'cycle: record at {period_s / MIN_PERIOD_SAMPLES:.3g} s or faster, or '
                         'faster still: at this sampling the true cycle may alias to a longer '
                         'one)')
    return Judgeable(True)
