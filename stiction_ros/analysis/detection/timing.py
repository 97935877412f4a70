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
A filter between the controller and the historian (PV read through a
first-order lag the controller never saw) moves the law another way: a lag
commutes with it, so OP and SP seen through the same lag against the lagged
PV are the law again.  :func:`lag_profile` fits it through each lag of
``LAGS`` rows; a lag is found when the law through it explains at least
``MIN_LAG_R2`` and leaves at most ``1 / LAG_RATIO`` of what the best shift (or
none) leaves unexplained (chosen on the same training seeds, on grids one to
three times coarser, by :mod:`stiction_ros.study.lag`), and refined between
the grid's neighbours.  It is named, not undone (:data:`LEAD`): a PI law
with OP seen through a lag is a PID with derivative action on PV, so OP,
PV and SP cannot tell the filter from the controller.  Reading
PV back through the lag's exact inverse (:func:`undo_lag`; ``undo_lag=True``)
took a damped simulated PV back to the verdict of the loop, and turned a
sticky plant record's 0.56 into 0.04 (DETECTION.md, section 1).

Every shared plant record with a law to fit fits it best as given (R² 0.33-1.00
there, at most 0.91 one row off): their exports are not skewed, and none is
realigned (three fit no row of their own: LIC33101, and the two FIC10112 records,
whose PV is constant).
"""

from dataclasses import dataclass, replace

import numpy as np

from stiction_ros.kernels.lags import lag_from_rest
from stiction_ros.kernels.law import law_r2_shifts

__all__ = ['Alignment', 'alignment', 'HELD', 'LAG_RATIO', 'lag_profile', 'LAGS', 'law_profile',
           'law_r2', 'LEAD', 'MARGIN', 'MAX_SHIFT', 'MIN_LAG_R2', 'MIN_LAW_R2', 'propose',
           'propose_lag', 'realign', 'refine_lag', 'through_lag', 'UNDO_LAG', 'undo_lag']

# Rows of skew looked for either way: 5 rows of a 10 s export are 50 s.
MAX_SHIFT = 5
# The law must explain this share of OP's changes where the record is
# realigned, and this much more there than as given (chosen as the module says).
MIN_LAW_R2 = 0.3
MARGIN = 0.3
# First-order lags (rows) looked for on PV after the controller read it.
LAGS = (1.0, 2.0, 3.0, 5.0, 8.0)
# A lag is read when the law fitted through it explains at least this share of
# OP's changes and leaves at most 1 / LAG_RATIO of what the best shift (or no
# shift) leaves unexplained (chosen as :mod:`stiction_ros.study.lag` says).
MIN_LAG_R2 = 0.8
LAG_RATIO = 5.0
# Fewer rows than this inside OP's range: no law can be told from chance.
MIN_ROWS = 50
# Why a skew is not made once rows repeated in OP and PV alike were dropped.
HELD = 'rows repeated in OP and PV alike were dropped, so rows are not evenly spaced'
# Why a lag is named but not undone: F(OP) = PI(F(SP) - PV) is OP = PI(SP - F^-1 PV), a
# PID whose derivative acts on PV alone (backward difference, derivative time a/(1 - a)
# rows, about the lag less half a row), so OP, PV and SP, set-point steps included, cannot
# tell a filter after the controller from a controller with derivative action.  Undoing
# it helped simulated loops and ruined a sticky plant record (DETECTION.md, section 1).
LEAD = ('a PID controller with derivative action on PV of about that time reads the same '
        'from OP, PV and SP')
# Whether the detector reads PV back through the lag it found (see LEAD: not by default).
UNDO_LAG = False


@dataclass(frozen=True)
class Alignment:
    """The skew proposed between PV and OP, and the fit of the law that shows it."""

    shift: int            # PV rows late against OP (negative: early); 0: read as given
    r2_as_given: float    # the law's R² at no shift (NaN: too few rows to fit)
    r2_best: float        # its R² at the best shift
    best: int             # that best shift, proposed or not
    declined: str = ''    # why a shift the law proposed was not made ('' when none was)
    lag: float = 0.0      # rows of first-order lag read on PV against OP; 0: none
    lag_best: float = 0.0  # the lag that fits best, proposed or not (0: none fitted)
    r2_lag: float = float('nan')  # the law's R² through that lag
    declined_lag: float = 0.0  # a lag proposed but not read (``declined`` says why)

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
        if self.lag > 0:
            # PV as the controller read it: its noise white again, its phase the law's.
            return op, undo_lag(pv, self.lag), sp, np.arange(n)
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
        if not (self.shift or self.lag):
            return self
        return replace(self, shift=0, lag=0.0, declined=why, declined_lag=self.lag)

    def describe(self, sample_time: float) -> str:
        """Return the evidence line of a shift or lag made or declined ('' when none)."""
        if self.lag > 0 or self.declined_lag > 0:
            return self._describe_lag(sample_time)
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

    def _describe_lag(self, sample_time: float) -> str:
        lag = self.lag or self.declined_lag
        fit = (f"the controller's PI law fits OP's changes with R² {self.r2_lag:.2f} with OP "
               f'seen through it and at most {self.r2_best:.2f} at any shift')
        what = (f'PV reads through a first-order lag of about {lag:.3g} rows '
                f'({lag * sample_time:.4g} s) that the controller did not see')
        if self.declined == LEAD:
            return (f'OP and PV read as if PV went through a first-order lag of about '
                    f'{lag:.3g} rows ({lag * sample_time:.4g} s) after the controller '
                    f'({fit}), but {self.declined}: read as exported')
        if self.declined:
            return f'{what} ({fit}), but {self.declined}: read as exported'
        return (f'{what}: {fit} (a filter between the controller and the historian); the '
                'verdict, the signature vote and the stiction size read PV back through the '
                "lag's inverse")

    def to_json(self) -> dict:
        """Return the check as JSON types (None where the law could not be fitted)."""
        def num(v):
            return round(float(v), 4) if np.isfinite(v) else None
        return {'shift_rows': self.shift, 'law_r2_as_given': num(self.r2_as_given),
                'law_r2_best': num(self.r2_best), 'best_shift_rows': self.best,
                'lag_rows': self.lag, 'lag_found_rows': self.lag or self.declined_lag,
                'best_lag_rows': self.lag_best, 'law_r2_lag': num(self.r2_lag),
                'not_realigned_because': self.declined or None}


def through_lag(x: np.ndarray, lag: float) -> np.ndarray:
    """
    Return ``x`` through a first-order lag of ``lag`` rows, started at rest on its first row.

    ``y[k] = a y[k-1] + (1 - a) x[k]``, ``a = exp(-1 / lag)``: what a filter
    averaging continuously shows when read once a row.
    """
    if not lag > 0:
        raise ValueError(f'a lag needs a positive time constant, not {lag}')
    x = np.ascontiguousarray(x, dtype=np.float64)
    # A compiled loop, not scipy.signal: the default analysis imports no scipy (test_dsp).
    return lag_from_rest(x, float(np.exp(-1.0 / lag)))


def undo_lag(y: np.ndarray, lag: float) -> np.ndarray:
    """Return the ``x`` that :func:`through_lag` turns into ``y`` (its exact inverse)."""
    if not lag > 0:
        raise ValueError(f'a lag needs a positive time constant, not {lag}')
    y = np.asarray(y, dtype=np.float64)
    a = float(np.exp(-1.0 / lag))
    x = y.copy()
    x[1:] = (y[1:] - a * y[:-1]) / (1.0 - a)
    return x


def law_r2(op: np.ndarray, pv: np.ndarray, sp: np.ndarray | None, shift: int,
           lag: float = 0.0) -> float:
    """
    Return the R² of the velocity-form PI law with PV taken ``shift`` rows later than OP.

    ``lag`` > 0 (rows): the law fitted to OP and SP seen through the first-order
    lag PV may have been read through after the controller (:func:`through_lag`),
    since a lag that commutes with the law moves OP's side of it as it moved PV.
    NaN when fewer than ``MIN_ROWS`` rows with OP inside its range remain,
    or OP never changes there (or, with a lag, a row of OP or PV is missing).
    """
    return _fit_shift(_law_rows(op, pv, sp, lag), shift)


def _law_rows(op: np.ndarray, pv: np.ndarray, sp: np.ndarray | None,
              lag: float) -> tuple | None:
    """Return what the law is fitted on at any shift (None where it cannot be fitted)."""
    op = np.asarray(op, dtype=np.float64)
    pv = np.asarray(pv, dtype=np.float64)
    if op.size < MIN_ROWS + 2 or op.shape != pv.shape:
        return None
    sp = None if sp is None else np.broadcast_to(np.asarray(sp, np.float64), pv.shape)
    finite = np.isfinite(op)
    if not finite.any():
        return None
    # A gap (NaN) or either end of OP's range: not the law's rows.
    inside = finite & (op > np.min(op[finite])) & (op < np.max(op[finite]))
    if lag > 0:
        if not (finite.all() and np.isfinite(pv).all()
                and (sp is None or np.isfinite(sp).all())):
            return None
        # A row at OP's limit stays in the lagged OP for a few time constants.
        out = np.flatnonzero(~inside)
        for j in range(1, int(np.ceil(3.0 * lag)) + 1):
            inside[np.minimum(out + j, op.size - 1)] = False
        op = through_lag(op, lag)
        sp = None if sp is None else through_lag(sp, lag)
    e = -pv if sp is None else sp - pv
    d_op, d_e, e = np.diff(op), np.diff(e), e[1:]
    free = inside[1:] & inside[:-1]
    known = np.isfinite(d_e) & np.isfinite(e)
    return d_op, d_e, e, free, known


def _fit_shifts(rows: tuple | None, first: int, last: int) -> np.ndarray:
    """Return the law's R² on :func:`_law_rows`'s rows with PV ``first`` .. ``last`` rows later."""
    if rows is None:
        return np.full(last - first + 1, np.nan)
    d_op, d_e, e, free, known = rows
    return law_r2_shifts(d_op, d_e, e, free, known, int(first), int(last), MIN_ROWS)


def _fit_shift(rows: tuple | None, shift: int) -> float:
    """Return the law's R² on :func:`_law_rows`'s rows with PV ``shift`` rows later."""
    return float(_fit_shifts(rows, shift, shift)[0])


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
    return _fit_shifts(_law_rows(op, pv, sp, 0.0), -MAX_SHIFT, MAX_SHIFT)


def lag_profile(op: np.ndarray, pv: np.ndarray, sp: np.ndarray | None) -> np.ndarray:
    """Return the law's R² through every lag of :data:`LAGS` (NaN: not fitted)."""
    return np.array([law_r2(op, pv, sp, 0, lag) for lag in LAGS])


def propose_lag(shifts: np.ndarray, lags: np.ndarray, min_r2: float = MIN_LAG_R2,
                ratio: float = LAG_RATIO) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """
    Return (lag proposed, best lag, its R²) for each row of shift and lag R² profiles.

    A lag is proposed when the law through it explains at least ``min_r2`` and
    leaves at most ``1 / ratio`` of what the best shift leaves unexplained:
    R² is read as a share of variance, so a law that fits 0.99 where it fits
    0.95 otherwise is told as well as one of 0.9 against 0.5.  Ties go to the
    shorter lag.
    """
    shifts = np.atleast_2d(np.asarray(shifts, dtype=np.float64))
    lags = np.atleast_2d(np.asarray(lags, dtype=np.float64))
    r2 = np.where(np.isfinite(lags), lags, -np.inf)
    i = np.argmax(r2, axis=1)
    best, top = np.asarray(LAGS)[i], r2[np.arange(len(r2)), i]
    other = np.clip(np.max(np.where(np.isfinite(shifts), shifts, -np.inf), axis=1), 0, 1)
    # No law as given, no lag: the shifts would be no reference to beat.
    ok = ((top >= min_r2) & (1.0 - other >= ratio * (1.0 - top)) & (top > other)
          & np.isfinite(shifts[:, MAX_SHIFT]))
    fitted = np.isfinite(top)
    return (np.where(ok, best, 0.0), np.where(fitted, best, 0.0),
            np.where(fitted, top, np.nan))


def refine_lag(op: np.ndarray, pv: np.ndarray, sp: np.ndarray | None,
               lag: float) -> tuple[float, float]:
    """
    Return (lag, R²): the lag between the grid's neighbours of ``lag`` the law fits best.

    The grid of :data:`LAGS` only finds a lag; a filter's time constant is
    seldom a whole number of rows, and undoing a lag of 3 rows where PV went
    through 4 leaves a quarter of the phase in.
    """
    i = LAGS.index(lag)
    lo = LAGS[i - 1] if i else LAGS[0] / 2
    hi = LAGS[i + 1] if i + 1 < len(LAGS) else 1.5 * LAGS[-1]
    from scipy.optimize import minimize_scalar   # only where a lag was found
    got = minimize_scalar(lambda v: -law_r2(op, pv, sp, 0, float(v)), bounds=(lo, hi),
                          method='bounded', options={'xatol': 0.02})
    near = round(float(got.x), 2)
    r2, r2_near = law_r2(op, pv, sp, 0, lag), law_r2(op, pv, sp, 0, near)
    return (near, r2_near) if r2_near > r2 else (lag, r2)


def alignment(op: np.ndarray, pv: np.ndarray, sp: np.ndarray | None,
              undo_lag: bool | None = None) -> Alignment:
    """
    Return the :class:`Alignment` of a record: the skew or lag its controller's law shows.

    A lag found is named and, unless ``undo_lag`` (None: :data:`UNDO_LAG`),
    declined with :data:`LEAD`.
    """
    r2 = law_profile(op, pv, sp)
    given = float(r2[MAX_SHIFT])
    if not np.isfinite(given):
        return Alignment(0, float('nan'), float('nan'), 0)
    shift, best, top = propose(r2)
    lag, lag_best, lag_top = (float(v[0]) for v in propose_lag(r2, lag_profile(op, pv, sp)))
    if lag:
        lag, lag_top = refine_lag(op, pv, sp, lag)
    undo = UNDO_LAG if undo_lag is None else undo_lag
    if lag and not undo and shift[0]:
        # Named only, a lag must not cost the shift the record is read with without it.
        return Alignment(int(shift[0]), given, float(top[0]), int(best[0]),
                         lag_best=lag_best, r2_lag=lag_top)
    # A lag explains what no shift does; where it does not, a shift may.
    got = Alignment(0 if lag else int(shift[0]), given, float(top[0]), int(best[0]),
                    lag=lag, lag_best=lag_best, r2_lag=lag_top)
    return got.decline(LEAD) if lag and not undo else got


def realign(op: np.ndarray, pv: np.ndarray, sp: np.ndarray | None, dropped: int = 0,
            undo_lag: bool | None = None) -> tuple:
    """
    Return ``(Alignment, op, pv, sp, rows)``: the record as the detector reads it.

    ``dropped``: rows repeated in OP and PV alike that were left out before
    (``stale.drop_held``); a skew is then named but not made (:data:`HELD`).
    """
    skew = alignment(op, pv, sp, undo_lag)
    if dropped:
        skew = skew.decline(HELD)
    return (skew, *skew.apply(op, pv, sp))
