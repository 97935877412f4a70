"""
Rows a historian interpolated: values computed between stored ones, not measured.

A historian that stores a tag less often than the export's grid may fill
the grid with straight lines between its stored values.  A row whose OP and
PV both lie exactly midway between their neighbours (within ``TOLERANCE`` of
the step across it, to the export's ninth digit), without repeating either,
was computed there: a noisy transmitter and the controller reading it do
not both land on the midpoint to the export's last digit.  Three of the 41
shared plant records have such rows, all levels of one unit: 2411LIC30102
of 30 August 105 of 750 (single rows between stored values 20 s apart), of
25 August 8, 2411LIC10201 2.  No simulated record of the training,
calibration and scoring seeds has one (0 of 9 500).

The detector reads them as they are: a line between two measurements is a
fair guess of the trend, unlike a hold.  The evidence names them, because
every figure scaled by the record's noise reads that noise low across them.

A record whose PV lies on such lines in more than half its rows is not
judged (:func:`lines_judgeable`): most of its trend was drawn by a historian
(a swinging-door or boxcar compression exported on a grid), not measured.
Read as measured, such records are called sticky far more often than they
are (docs/ROBUSTNESS.md: 117 more of 886 healthy simulated loops flagged
under compression).  PV alone is counted, since a compressing historian
keeps each tag's points at its own times.  A simulated PV without noise
can be read so too (a stuck valve before an integrator or a moving
average draws exact lines), and the reason says so: no measured PV does.
Chosen on training seeds 0-1499 only: as simulated, at most 23 % of PV's
rows lie midway (a quantised PV stepping one quantum a row); compressed at
two noise standard deviations, a median of 74 %.
"""

import numpy as np

from stiction_ros.analysis.detection.resolve import Judgeable

# |x[k] - (x[k-1] + x[k+1]) / 2| within this share of the step across it, plus
# the rounding of a value printed to 9 significant digits: the plant export's
# midpoints (8 decimals) pass, and so does nothing noisy, nor a simulated
# drifting sensor under a ramping OP (an OP step of 0.135 % off by 1.4e-4).
TOLERANCE = 1e-6
DIGITS = 1e-9
# More than this share of PV's rows on straight lines: not judged (as holds).
MAX_PV_LINES = 0.5


def _midway(x: np.ndarray) -> np.ndarray:
    """Return, for each inner sample, whether it is its neighbours' midpoint and moved."""
    step = np.abs(x[2:] - x[:-2])
    slack = TOLERANCE * step + DIGITS * np.abs(x[1:-1])
    mid = np.abs(x[1:-1] - 0.5 * (x[:-2] + x[2:])) <= slack
    return mid & (x[1:-1] != x[:-2])


def interpolated_rows(op: np.ndarray, pv: np.ndarray) -> np.ndarray:
    """Return a mask of the rows whose OP and PV are both their neighbours' midpoints."""
    op, pv = np.asarray(op, float), np.asarray(pv, float)
    out = np.zeros(len(op), bool)
    if len(op) >= 3:
        out[1:-1] = _midway(op) & _midway(pv)
    return out


def describe(mask: np.ndarray, sample_time: float) -> str:
    """Return one sentence for the evidence ('' when no row was interpolated)."""
    n = int(np.count_nonzero(mask))
    if not n:
        return ''
    rows = 'row lies' if n == 1 else 'rows lie'
    return (f'{n} of {len(mask)} {rows} exactly midway between their neighbours in both OP '
            f'and PV: interpolated between stored values (by the historian, or by the reader '
            f'for samples the file has no row for), not measured at '
            f'{sample_time:g} s; the noise the figures are scaled by reads low across them '
            '(export the raw samples to be sure)')


def pv_line_share(pv: np.ndarray) -> float:
    """Return the share of PV's rows that lie exactly midway between their neighbours."""
    pv = np.asarray(pv, float)
    return float(np.count_nonzero(_midway(pv)) / len(pv)) if len(pv) >= 3 else 0.0


def lines_judgeable(pv: np.ndarray) -> Judgeable:
    """Return ``cannot tell`` (code ``historian_lines``) when most of PV is straight lines."""
    share = pv_line_share(pv)
    if share > MAX_PV_LINES:
        return Judgeable(False, 'historian_lines',
                         f'{share:.0%} of the PV rows lie exactly on straight lines between '
                         'their neighbours: most of the trend was drawn between stored '
                         'values, not measured (a compressed or interpolated export, or the '
                         "reader's filling of samples the file has no row for); export the "
                         'raw samples (compression off). A simulation without measurement '
                         'noise looks the same: add noise to its PV')
    return Judgeable(True)
