"""
Whether the valve moved at all: MV within its own noise while OP travelled.

A valve that never breaks away shows how large its friction band is only from
below (wider than OP's travel), and nothing of how it moves: no slip, no
timing, no calibration.  Sizes fitted to such a record and a search for the
physics a model left out would both read the noise.
"""

from dataclasses import dataclass

import numpy as np

# MV's spread (1st to 99th percentile) must pass this many noise widths to count as
# motion: Gaussian noise alone spans about 4.7 of them, so 8 leaves a margin.
MOVED = 8.0


@dataclass(frozen=True)
class Still:
    """A valve that did not move: MV's and OP's spread (%) and MV's noise width (%)."""

    mv_spread: float
    op_spread: float
    noise: float

    def sentence(self) -> str:
        """Return what it means, in words."""
        return (f'MV stayed within its noise (it spread {self.mv_spread:.2g} %, noise '
                f'{self.noise:.2g} %) while OP travelled {self.op_spread:.2g} %: the valve '
                f'did not break away (its friction band is wider than the travel of OP here, '
                f'so S is bounded below only), or the position signal is frozen. Nothing '
                f'of how it moves can be read: a valve travel test, or a record with '
                f'larger OP moves, tells')


def still_valve(op: np.ndarray, mv: np.ndarray, segments) -> Still | None:
    """
    Return a :class:`Still` when MV did not move beyond its noise while OP did, else None.

    The noise width is read from MV's sample-to-sample differences (a robust
    standard deviation, divided by the square root of 2), so that a drift or
    a step counts as motion; a reading with no noise at all (steps of a
    quantum, mostly zero differences) counts any change as motion.
    """
    idx = np.concatenate([np.arange(a, b) for a, b in segments]) if segments else \
        np.arange(0)
    if len(idx) < 10:
        return None
    u, y = np.asarray(op, dtype=np.float64)[idx], np.asarray(mv, dtype=np.float64)[idx]
    dy = np.concatenate([np.diff(np.asarray(mv, dtype=np.float64)[a:b])
                         for a, b in segments if b - a > 1])
    noise = 1.4826 * float(np.median(np.abs(dy - np.median(dy)))) / np.sqrt(2.0)
    mv_spread = float(np.subtract(*np.percentile(y, [99, 1])))
    op_spread = float(np.subtract(*np.percentile(u, [99, 1])))
    if noise <= 0.0 or mv_spread > MOVED * noise or op_spread <= MOVED * noise:
        return None
    return Still(mv_spread, op_spread, noise)
