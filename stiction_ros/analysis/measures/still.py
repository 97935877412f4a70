"""
Whether the valve moved at all: MV within its noise, or a trace of OP's travel, as OP moved.

A valve that never breaks away shows how large its friction band is only from
below (wider than OP's moves away from where it stuck), and nothing of how it
moves: no slip, no timing, no calibration.  Sizes fitted to such a record and
a search for the physics a model left out would both read the noise.
"""

from dataclasses import dataclass

import numpy as np

from stiction_ros.analysis.detection.resolve import robust_noise

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


# Whether the loop controlled PV while MV read still, read at the set point's steps:
# PV's median over the ``SETTLE_ROWS`` before a step against its median over the last
# ``SETTLE_ROWS`` before the next step, as a share of the step.  A loop that controls PV
# settles on each new set point (integral action: a share near 1); one whose valve
# never moved does not answer at all (near 0).  Steps must go both ways, and every
# step must agree, so that a load that moved PV by chance at one step cannot decide.
SETTLE_ROWS = 10
TRACK_SHARE = (0.5, 1.5)
IGNORE_SHARE = 0.3


@dataclass(frozen=True)
class SetPointTest:
    """How PV answered the set point's steps (both ways) in a record whose MV read still."""

    follows: bool
    steps: tuple[float, ...]        # each step's size (PV units)
    shares: tuple[float, ...]       # PV's settled change over each step

    def sentence(self) -> str:
        """Return what it means, in words."""
        shares = ', '.join(f'{x:.2f}' for x in self.shares)
        if self.follows:
            return (f"PV settled on each of the set point's {len(self.steps)} steps, up and "
                    f'down (its change over each a share {shares} of the step): the loop '
                    "controlled PV, so the valve moved and MV's reading is dead or frozen")
        return (f"PV did not answer any of the set point's {len(self.steps)} steps, up and "
                f'down (its change over each a share {shares} of the step), so the valve did '
                'not move and the reading is not dead')

    def to_json(self) -> dict:
        """Return the test as JSON types."""
        return {'follows': self.follows, 'steps': [round(h, 6) for h in self.steps],
                'shares': [round(x, 4) for x in self.shares]}


def set_point_test(pv: np.ndarray, sp: np.ndarray, segments) -> SetPointTest | None:
    """
    Return how PV answered SP's steps on the longest segment, or None when it cannot tell.

    A step is a change of SP by over ``MOVED`` noise widths of PV from one
    row to the next (changes closer than ``SETTLE_ROWS`` are one step); it
    is read when ``SETTLE_ROWS`` rows precede it and twice that follow it
    before the next.  Follows: every step's share inside ``TRACK_SHARE``;
    ignores: every share under ``IGNORE_SHARE`` in size; both need steps up
    and down.  A set point that ramps, moves one way only or never settles
    long enough cannot tell.
    """
    segments = [(a, b) for a, b in segments if b - a > 3 * SETTLE_ROWS]
    if not segments:
        return None
    a, b = max(segments, key=lambda s: s[1] - s[0])
    y = np.asarray(pv[a:b], dtype=np.float64)
    r = np.asarray(sp[a:b], dtype=np.float64)
    if not (np.isfinite(y).all() and np.isfinite(r).all()):
        return None
    noise = max(robust_noise(y), 1e-12)
    moves = np.flatnonzero(np.abs(np.diff(r)) > MOVED * noise) + 1
    events: list[list[int]] = []
    for m in moves.tolist():
        if events and m - events[-1][1] <= SETTLE_ROWS:
            events[-1][1] = m
        else:
            events.append([m, m])
    starts = [0] + [e[0] for e in events] + [len(y)]
    steps, shares = [], []
    for i, (first, last) in enumerate(events):
        if first - starts[i] < SETTLE_ROWS or starts[i + 2] - last < 2 * SETTLE_ROWS:
            continue
        h = float(r[last] - r[first - 1])
        if abs(h) <= MOVED * noise:
            continue
        before = np.median(y[first - SETTLE_ROWS:first])
        after = np.median(y[starts[i + 2] - SETTLE_ROWS:starts[i + 2]])
        steps.append(h)
        shares.append(float((after - before) / h))
    if not (any(h > 0 for h in steps) and any(h < 0 for h in steps)):
        return None
    if all(TRACK_SHARE[0] <= x <= TRACK_SHARE[1] for x in shares):
        return SetPointTest(True, tuple(steps), tuple(shares))
    if all(abs(x) < IGNORE_SHARE for x in shares):
        return SetPointTest(False, tuple(steps), tuple(shares))
    return None
