"""
Rows a historian repeated: held values that are not measurements.

A plant historian that has no fresh value for a tag exports the last one
again.  When OP and PV (and SP) all repeat the previous row exactly, in a
record whose PV otherwise changes at every sample, nothing was measured
there: a noisy transmitter never repeats its value to the last digit in the
same sample as the controller repeats its output.  Such rows freeze the
trend for a while and then jump, and no simulated record holds any: on
simulated records put through the plant's kinds of holds the detector lost
0.065 in balanced accuracy (below).  Of the 41 shared plant records, 36 have some (most of
them 1-10 single rows of 751; five have 15-42 % of their rows held, in
blocks of 6-13 rows or as a hundred single repeats).

Held rows are dropped before the detector reads the record: the fresh rows
are the measurements, and a source that updates slower than the export grid
(the plant's commonest kind: single repeats) is then read at its own pace.
Dropping was chosen against drawing straight lines across the holds, on
simulated calibration records with the plant's kinds of holds put in
(blocks of 6-13 rows every 25-45, or single repeats at 1-15 % of rows, each
replacing samples or inserted between them): balanced accuracy 0.869 clean,
0.804 with the holds, 0.823 with lines, 0.837 with the holds dropped
(535 records, the shipped model; DETECTION.md section 1).  A straight line
carries no noise, so every figure scaled by the record's noise stays biased
after that repair.

A PV on a coarse grid (a quantised transmitter, a constant PV), or an OP
that stands while PV moves, repeats values for reasons of its own, so the
rule applies only where PV changes in all but ``FINE_GRAINED`` of the rows
where OP does, and not where OP stands at its limit (within 0.5 % of 0 or
100 %: a saturated output beside a frozen transmitter; one simulated sensor
fault does this).  No simulated record of the training, calibration and
scoring seeds holds a row by this rule (0 of 8 000).
"""

from dataclasses import dataclass

import numpy as np

from stiction_ros.analysis.detection.resolve import Judgeable

# PV may stand still in at most this share of the rows where OP moved for its
# repeats to count as the historian's: a quantised PV stands far more often.
FINE_GRAINED = 0.05
# Beyond this share of held rows the trend is mostly the historian's, not the transmitter's.
MAX_HELD = 0.5
# From this share on the holds are the first thing the evidence says.
NOTABLE = 0.05
# OP (in % of span, as historian exports and the nodes give it) at or beyond
# these stands at its limit: the detector's ``op_saturated`` reads it the same way.
SATURATED = (0.5, 99.5)


@dataclass
class StaleRows:
    """Which rows were held (a mask over the record), how many, and in how many runs."""

    held: np.ndarray

    @property
    def runs(self) -> int:
        """Return the number of runs of consecutive held rows."""
        return len(_runs(self.held)[0])

    @property
    def count(self) -> int:
        """Return the number of held rows."""
        return int(self.held.sum())

    @property
    def kept(self) -> np.ndarray:
        """Return the input row of each fresh row, in order."""
        return np.flatnonzero(~self.held)

    @property
    def share(self) -> float:
        """Return the held rows' share of the record."""
        return float(self.held.mean()) if len(self.held) else 0.0

    def describe(self, sample_time: float) -> str:
        """Return one sentence for the evidence ('' when no row was held)."""
        if not self.count:
            return ''
        longest = _longest_run(self.held)
        span = f'{longest * sample_time:.0f} s'
        if self.runs == 1:
            where = f'one run of {longest} rows = {span}' if longest > 1 else span
        elif longest == 1:
            where = f'{self.runs} single rows of {span} each'
        else:
            where = f'{self.runs} runs, the longest {longest} rows = {span}'
        verb = 'repeats' if self.count == 1 else 'repeat'
        return (f'{self.count} of {len(self.held)} rows {verb} the previous row exactly in OP '
                f'and PV ({where}): held values (by the historian, or over an invalid '
                f'sample), not measurements; the detector read the fresh rows only')


def _runs(mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    edges = np.diff(np.concatenate(([0], mask.astype(np.int8), [0])))
    return np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)


def _longest_run(mask: np.ndarray) -> int:
    starts, ends = _runs(mask)
    return int((ends - starts).max()) if len(starts) else 0


def stale_rows(op: np.ndarray, pv: np.ndarray, sp: np.ndarray | None = None) -> StaleRows:
    """
    Return the rows that repeat the previous one exactly in OP, PV and SP.

    Parameters
    ----------
    op, pv : ndarray
        One contiguous stretch of finite samples.
    sp : ndarray, optional
        The set point; a row whose SP changed is fresh.

    Returns
    -------
    StaleRows
        ``held`` is all False where PV is not fine-grained (see the module).

    """
    op, pv = np.asarray(op, float), np.asarray(pv, float)
    held = np.zeros(len(op), bool)
    if len(op) < 3:
        return StaleRows(held)
    same_op, same_pv = np.diff(op) == 0.0, np.diff(pv) == 0.0
    moved = ~same_op
    if not moved.any() or np.mean(same_pv[moved]) > FINE_GRAINED:
        return StaleRows(held)
    # An OP standing at its limit repeats for a reason (saturation), and a
    # frozen transmitter may happen to stand still with it.
    free = (op[1:] > SATURATED[0]) & (op[1:] < SATURATED[1])
    same = same_op & same_pv & free
    if sp is not None:
        same &= np.diff(np.asarray(sp, float)) == 0.0
    held[1:] = same
    return StaleRows(held)


def drop_held(op: np.ndarray, pv: np.ndarray, sp: np.ndarray | None = None) -> tuple:
    """
    Return ``(op, pv, sp, StaleRows)`` without the held rows.

    ``StaleRows.kept`` maps a row of the result to its row in the input.
    The inputs are not changed; with no held row they are returned as they are.
    """
    found = stale_rows(op, pv, sp)
    if not found.count:
        return op, pv, sp, found
    keep = ~found.held
    return (np.asarray(op)[keep], np.asarray(pv)[keep],
            None if sp is None else np.asarray(sp)[keep], found)


def holds_judgeable(found: StaleRows, sample_time: float) -> Judgeable:
    """Return ``cannot tell`` (code ``historian_holds``) when most rows were held."""
    if found.share > MAX_HELD:
        return Judgeable(False, 'historian_holds',
                         f'{found.count} of {len(found.held)} rows repeat the previous row '
                         f'exactly (historian holds): most of the trend was not measured; '
                         f'export the raw samples or a shorter sample time')
    return Judgeable(True)
