"""
Whether the valve moved at all: MV within its noise, or a trace of OP's travel, as OP moved.

A valve that never breaks away shows how large its friction band is only from
below (wider than OP's moves away from where it stuck), and nothing of how it
moves: no slip, no timing, no calibration.  Sizes fitted to such a record and
a search for the physics a model left out would both read the noise.
"""

from dataclasses import dataclass

import numpy as np

from stiction_ros.kernels.lags import lag_from_rest

# MV's spread (1st to 99th percentile) must pass this many noise widths to count as
# motion: Gaussian noise alone spans about 4.7 of them, so 8 leaves a margin.
MOVED = 8.0
# A reading that follows OP this well (correlation) moves with it, however noisy.
FOLLOWS = 0.3
# A position within this much of a stop (%) is held there: a travel limit, a
# positioner's tight shut-off, not friction.
NEAR_STOP = 2.0
# With no noise to measure (a constant or frozen reading), OP must travel this far
# (%) for the stillness to mean anything.
VISIBLE = 0.5
# A reading that spreads less than this share of OP's travel does not follow OP,
# however far past its noise it drifts: no position answers its command at a
# twentieth of its size (a stuck valve's reading that drifts, a dead transmitter).
FOLLOW_SHARE = 0.05


@dataclass(frozen=True)
class Still:
    """A valve that did not move: MV's and OP's spread (%) and MV's noise width (%)."""

    mv_spread: float
    op_spread: float
    noise: float
    # True when MV moved past its noise but by under FOLLOW_SHARE of OP's travel.
    drifted: bool = False

    def sentence(self) -> str:
        """Return what it means, in words."""
        how = (f'MV moved only {self.mv_spread:.2g} % (noise {self.noise:.2g} %), under '
               f"{100 * FOLLOW_SHARE:.0f} % of OP's travel and not with it, a drift of the "
               'reading rather than a response,' if self.drifted else
               f'MV stayed within its noise (it spread {self.mv_spread:.2g} %, noise '
               f'{self.noise:.2g} %)')
        return (f'{how} while OP travelled {self.op_spread:.2g} %: the valve '
                f'did not break away (its friction band is wider than the moves of OP away '
                f'from where it stuck, between half and all of that travel, so S is bounded '
                f'below only), or it is held (no air, a handwheel, a locked positioner), or '
                f'the position signal is frozen or dead. Nothing of how it moves can be read: a '
                f'valve travel test, or a record with larger OP moves, tells')


def still_valve(op: np.ndarray, mv: np.ndarray, segments) -> Still | None:
    """
    Return a :class:`Still` when MV did not follow OP's travel, else None.

    The noise width is read from MV's sample-to-sample differences (a robust
    standard deviation, divided by the square root of 2), so that a drift or
    a step counts as motion; a reading in steps of a quantum with mostly equal
    neighbours has at least the quantum's own noise (q / sqrt 12).  Still:
    MV within its noise (and not correlated with OP, which a noisy reading
    that follows OP is), or past it by under ``FOLLOW_SHARE`` of OP's travel
    (``drifted``).  A reading at a stop is not still.
    """
    segments = [(a, b) for a, b in segments if b - a > 1]
    if sum(b - a for a, b in segments) < 10:
        return None
    u = np.concatenate([np.asarray(op[a:b], dtype=np.float64) for a, b in segments])
    y = np.concatenate([np.asarray(mv[a:b], dtype=np.float64) for a, b in segments])
    ok = np.isfinite(u) & np.isfinite(y)
    u, y = u[ok], y[ok]
    if len(y) < 10:
        return None
    dy = np.concatenate([np.diff(np.asarray(mv[a:b], dtype=np.float64))
                         for a, b in segments])
    dy = dy[np.isfinite(dy)]
    noise = 1.4826 * float(np.median(np.abs(dy - np.median(dy)))) / np.sqrt(2.0)
    steps = np.abs(dy[dy != 0.0])
    if len(steps):
        noise = max(noise, float(steps.min()) / np.sqrt(12.0))
    mv_spread = float(np.subtract(*np.percentile(y, [99, 1])))
    op_spread = float(np.subtract(*np.percentile(u, [99, 1])))
    median = float(np.median(y))
    if min(median, 100.0 - median) < NEAR_STOP:
        return None
    if op_spread <= max(VISIBLE, MOVED * noise):
        return None
    if mv_spread < FOLLOW_SHARE * op_spread and mv_spread > MOVED * noise:
        return Still(mv_spread, op_spread, noise, drifted=True)
    if noise > 0.0 and mv_spread > MOVED * noise:
        return None
    if np.std(y) > 0.0 and np.std(u) > 0.0 and np.corrcoef(u, y)[0, 1] > FOLLOWS:
        return None
    return Still(mv_spread, op_spread, noise)


# Whether the loop controlled PV while MV read still: PV against SP's moves through
# a closed-loop lag of each of these rows.  A loop that controls PV follows its set
# point at a gain near 1 (integral action); one whose valve never moved does not.
CLOSED_LOOP_LAGS = (0.0, 2.0, 5.0, 10.0, 20.0, 50.0, 100.0)
TRACKS_R2 = 0.5
TRACK_GAIN = (0.5, 1.5)
IGNORES_R2 = 0.1


@dataclass(frozen=True)
class SetPointTest:
    """How PV answered SP's moves (both ways) in a record whose MV read still."""

    follows: bool
    r2: float
    gain: float
    lag_rows: float

    def sentence(self, sample_time: float) -> str:
        """Return what it means, in words."""
        if self.follows:
            lag = (f' through a lag of {self.lag_rows * sample_time:.3g} s' if self.lag_rows
                   else '')
            return (f"PV followed the set point's moves up and down (R² {self.r2:.2f}, gain "
                    f'{self.gain:.2f}{lag}): the loop controlled PV, so the valve moved, and '
                    "MV's reading is dead or frozen")
        return (f"PV did not follow the set point's moves up and down either (R² "
                f'{self.r2:.2g}), so the valve did not move and the reading is not dead')

    def to_json(self) -> dict:
        """Return the test as JSON types."""
        return {'follows': self.follows, 'r2': round(self.r2, 4),
                'gain': round(self.gain, 4), 'lag_rows': self.lag_rows}


def _spread(v: np.ndarray) -> float:
    return float(np.subtract(*np.percentile(v, [99, 1])))


def set_point_test(pv: np.ndarray, sp: np.ndarray, segments) -> SetPointTest | None:
    """
    Return how PV answered SP's moves on the longest segment, or None when it cannot tell.

    SP must rise and fall by ``MOVED`` noise widths of PV (a single step
    could match a drift by chance).  PV follows: R² of PV on SP through the
    best lag of ``CLOSED_LOOP_LAGS`` at least ``TRACKS_R2``, at a gain inside
    ``TRACK_GAIN``.  PV ignores: R² under ``IGNORES_R2`` while SP spread at
    least as far as PV (so that no load can have hidden a response).
    """
    segments = [(a, b) for a, b in segments if b - a > 10]
    if not segments:
        return None
    a, b = max(segments, key=lambda s: s[1] - s[0])
    y = np.asarray(pv[a:b], dtype=np.float64)
    r = np.asarray(sp[a:b], dtype=np.float64)
    if not (np.isfinite(y).all() and np.isfinite(r).all()) or np.var(y) <= 0.0:
        return None
    dy = np.diff(y)
    noise = 1.4826 * float(np.median(np.abs(dy - np.median(dy)))) / np.sqrt(2.0)
    rise = float(np.max(r - np.minimum.accumulate(r)))
    fall = float(np.max(np.maximum.accumulate(r) - r))
    if min(rise, fall) <= MOVED * max(noise, 1e-12):
        return None
    best = (-np.inf, 0.0, 0.0)
    ones = np.ones(len(y))
    for lag in CLOSED_LOOP_LAGS:
        x = r if lag == 0.0 else lag_from_rest(np.ascontiguousarray(r), float(np.exp(-1.0 / lag)))
        coef, *_ = np.linalg.lstsq(np.column_stack([x, ones]), y, rcond=None)
        r2 = 1.0 - float(np.var(y - coef[0] * x - coef[1])) / float(np.var(y))
        if r2 > best[0]:
            best = (r2, float(coef[0]), lag)
    r2, gain, lag = best
    if r2 >= TRACKS_R2 and TRACK_GAIN[0] <= gain <= TRACK_GAIN[1]:
        return SetPointTest(True, r2, gain, lag)
    if r2 < IGNORES_R2 and _spread(r) >= _spread(y):
        return SetPointTest(False, max(r2, 0.0), gain, lag)
    return None
