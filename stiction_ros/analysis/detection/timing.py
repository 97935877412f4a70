"""
Whether OP and PV were exported on one clock: the controller's own law as the reference.

A PI controller computes OP from the PV of the same scan, so in its velocity
form ``dOP[t] = a de[t] + b e[t]`` (``e = SP - PV``) the change of OP is a
linear function of the error of the same row, to the export's rounding.  A
historian that stamps one tag late (a clock skew between two tags, a
gateway's buffer, an export that joins tags by time) moves that law to
another row: PV ``k`` rows late against OP fits best paired with the OP of
``k`` rows earlier.  That is a fact about the instruments, not the valve,
and ``make robustness`` shows what it costs the verdict (docs/ROBUSTNESS.md:
a skew of three rows loses a fifth of the sticky loops found).

:func:`alignment` fits the law at every shift up to ``MAX_SHIFT`` rows and
proposes a shift only when the law is identified there (R² at least
``MIN_LAW_R2``) and explains clearly more than as given (by ``MARGIN``); the
detector then reads the record realigned and says so.  A loop run by
another law (derivative action on a noisy PV, a remote set point not in the
export, a controller scanning much faster than the export) identifies no
law, and the record is read as given.  Rows where OP sits at either end of
its recorded range are left out of the fit: there the anti-windup, not the
law, sets OP.

The two thresholds were chosen on training seeds 0-1499 alone, exported on a
grid two and three times coarser than the controller's scan (so that the
law holds only roughly, as on a real export) and skewed by up to three rows
either way (:mod:`stiction_ros.study.skew`): the pair that realigns the most
skewed records right while realigning at most 0.5 % of the unskewed ones.
Every shared plant record with a law to fit fits it best as given (R² 0.33-1.00
there, at most 0.91 one row off): their exports are not skewed, and none is
realigned (three fit no row of their own: LIC33101, and the two FIC10112 records,
whose PV is constant).
"""

from dataclasses import dataclass, replace

import numpy as np

__all__ = ['Alignment', 'alignment', 'HELD', 'law_profile', 'law_r2', 'MARGIN', 'MAX_SHIFT',
           'MIN_LAW_R2', 'propose', 'realign']

# Rows of skew looked for either way: 5 rows of a 10 s export are 50 s.
MAX_SHIFT = 5
# The law must explain this share of OP's changes where the record is
# realigned, and this much more there than as given (chosen as the module says).
MIN_LAW_R2 = 0.3
MARGIN = 0.3
# Fewer rows than this inside OP's range: no law can be told from chance.
MIN_ROWS = 50
# Why a skew is not made once rows repeated in OP and PV alike were dropped.
HELD = 'rows repeated in OP and PV alike were dropped, so rows are not evenly spaced'


@dataclass(frozen=True)
class Alignment:
    """The skew proposed between PV and OP, and the fit of the law that shows it."""

    shift: int            # PV rows late against OP (negative: early); 0: read as given
    r2_as_given: float    # the law's R² at no shift (NaN: too few rows to fit)
    r2_best: float        # its R² at the best shift
    best: int             # that best shift, proposed or not
    declined: str = ''    # why a shift the law proposed was not made ('' when none was)

    @property
    def checked(self) -> bool:
        """Return whether the law could be fitted at all."""
        return bool(np.isfinite(self.r2_as_given))

    def apply(self, op: np.ndarray, pv: np.ndarray, sp: np.ndarray | None) -> tuple:
        """
        Return ``(op, pv, sp, rows)`` realigned by :attr:`shift`.

        ``rows`` are the indices into the given OP of the rows kept (the
        evidence names OP's rows); PV and SP are moved together, since a
        controller's set point and measurement come from one block.
        """
        n, k = len(op), self.shift
        if k == 0:
            return op, pv, sp, np.arange(n)
        if k > 0:    # PV late: OP of row t goes with PV of row t + k
            cut_op, cut_pv = slice(0, n - k), slice(k, n)
        else:
            cut_op, cut_pv = slice(-k, n), slice(0, n + k)
        sp2 = None if sp is None else np.broadcast_to(sp, np.shape(pv))[cut_pv]
        return op[cut_op], pv[cut_pv], sp2, np.arange(n)[cut_op]

    def decline(self, why: str) -> 'Alignment':
        """Return this check with its shift not made, and why."""
        return replace(self, shift=0, declined=why) if self.shift else self

    def describe(self, sample_time: float) -> str:
        """Return the evidence line of a shift made or declined ('' when none)."""
        k = abs(self.shift or (self.best if self.declined else 0))
        if k == 0:
            return ''
        side = 'late' if (self.shift or self.best) > 0 else 'early'
        fit = (f"the controller's PI law fits OP's changes with R² {self.r2_best:.2f} so "
               f'paired and {self.r2_as_given:.2f} as exported')
        rows = f'{k} row{"s" if k > 1 else ""} ({k * sample_time:.4g} s) {side} against OP'
        if self.declined:
            return f'PV looks {rows} ({fit}), but {self.declined}: read as exported'
        return (f'PV is {rows}: {fit} (a clock skew between the two tags); the verdict, the '
                'signature vote and the stiction size read it realigned')

    def to_json(self) -> dict:
        """Return the check as JSON types (None where the law could not be fitted)."""
        def num(v):
            return round(float(v), 4) if np.isfinite(v) else None
        return {'shift_rows': self.shift, 'law_r2_as_given': num(self.r2_as_given),
                'law_r2_best': num(self.r2_best), 'best_shift_rows': self.best,
                'not_realigned_because': self.declined or None}


def law_r2(op: np.ndarray, pv: np.ndarray, sp: np.ndarray | None, shift: int) -> float:
    """
    Return the R² of the velocity-form PI law with PV taken ``shift`` rows later than OP.

    NaN when fewer than ``MIN_ROWS`` rows with OP inside its range remain,
    or OP never changes there.
    """
    op = np.asarray(op, dtype=np.float64)
    pv = np.asarray(pv, dtype=np.float64)
    if op.size < MIN_ROWS + 2 or op.shape != pv.shape:
        return float('nan')
    e = -pv if sp is None else np.broadcast_to(np.asarray(sp, np.float64), pv.shape) - pv
    d_op, d_e, e = np.diff(op), np.diff(e), e[1:]
    finite = np.isfinite(op)
    if not finite.any():
        return float('nan')
    # A gap (NaN) or either end of OP's range: not the law's rows.
    inside = finite & (op > np.min(op[finite])) & (op < np.max(op[finite]))
    free = inside[1:] & inside[:-1]
    known = np.isfinite(d_e) & np.isfinite(e)
    n, k = len(d_op), int(shift)
    lo, hi = max(0, -k), min(n, n - k)
    if hi - lo < MIN_ROWS:
        return float('nan')
    use = free[lo:hi] & known[lo + k:hi + k]
    y = d_op[lo:hi][use]
    if y.size < MIN_ROWS:
        return float('nan')
    x = np.column_stack([d_e[lo + k:hi + k][use], e[lo + k:hi + k][use], np.ones(y.size)])
    var = float(np.var(y))
    if not var > 0.0:
        return float('nan')
    coef, *_ = np.linalg.lstsq(x, y, rcond=None)
    return float(max(0.0, 1.0 - np.var(y - x @ coef) / var))


def propose(profiles: np.ndarray, min_r2: float = MIN_LAW_R2,
            margin: float = MARGIN) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """
    Return (shift proposed, best shift, its R²) for each row of R² profiles.

    A row holds the law's R² at shifts ``-MAX_SHIFT`` .. ``MAX_SHIFT`` (NaN
    where it could not be fitted).  Ties go to the smaller skew.
    """
    profiles = np.atleast_2d(np.asarray(profiles, dtype=np.float64))
    shifts = np.arange(-MAX_SHIFT, MAX_SHIFT + 1)
    order = np.argsort(np.abs(shifts), kind='stable')
    r2 = np.where(np.isfinite(profiles), profiles, -np.inf)
    i = order[np.argmax(r2[:, order], axis=1)]
    best, top = shifts[i], r2[np.arange(len(r2)), i]
    given = np.nan_to_num(profiles[:, MAX_SHIFT], nan=np.inf)
    ok = (best != 0) & (top >= min_r2) & (top - given >= margin)
    return np.where(ok, best, 0), best, top


def law_profile(op: np.ndarray, pv: np.ndarray, sp: np.ndarray | None) -> np.ndarray:
    """Return the law's R² at every shift ``-MAX_SHIFT`` .. ``MAX_SHIFT`` (NaN: not fitted)."""
    return np.array([law_r2(op, pv, sp, k) for k in range(-MAX_SHIFT, MAX_SHIFT + 1)])


def alignment(op: np.ndarray, pv: np.ndarray, sp: np.ndarray | None) -> Alignment:
    """Return the :class:`Alignment` of a record: the skew its controller's law shows, if any."""
    r2 = law_profile(op, pv, sp)
    given = float(r2[MAX_SHIFT])
    if not np.isfinite(given):
        return Alignment(0, float('nan'), float('nan'), 0)
    shift, best, top = propose(r2)
    return Alignment(int(shift[0]), given, float(top[0]), int(best[0]))


def realign(op: np.ndarray, pv: np.ndarray, sp: np.ndarray | None, dropped: int = 0) -> tuple:
    """
    Return ``(Alignment, op, pv, sp, rows)``: the record as the detector reads it.

    ``dropped``: rows repeated in OP and PV alike that were left out before
    (``stale.drop_held``); a skew is then named but not made (:data:`HELD`).
    """
    skew = alignment(op, pv, sp)
    if dropped:
        skew = skew.decline(HELD)
    return (skew, *skew.apply(op, pv, sp))
