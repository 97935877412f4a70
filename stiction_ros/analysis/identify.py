"""
Identify S and J (and optionally the input filter) from measured OP and MV.

The MSE of eq. 2.8 as a function of (S, J) is piecewise smooth with jumps
wherever a breakaway instant moves by a sample, so gradient methods and a
single coarse grid both fail: a shift of 0.02 % in S can multiply the MSE.
The search is a coarse-to-fine grid on multiples of ``resolution``:

1. a coarse grid over the whole plausible box (S up to the OP range, J up to
   the MV range), keeping the best ``keep`` distinct candidates, because the
   best coarse point is often not next to the global optimum;
2. around every kept candidate, a finer grid spanning the coarse cell, and
   so on down to ``resolution`` (0.01 % by default);
3. a candidate is abandoned as soon as its running error sum passes the
   ``keep``-th best found so far on its grid (``sse_kernels.grid_sse_best``),
   so only the kept ones are scored exactly; the grid is visited in a spread
   order, so that bound is tight after a few points.

The uncertainty interval of each parameter is the projection of the joint
95 % region: the grid pairs whose likelihood-ratio statistic
``N ln(MSE / MSE_min)`` (Gaussian errors) stays under the chi-square quantile
with two degrees of freedom (5.99).  S and J trade off along ridges, so a
profile along each axis alone would be too narrow.  The region is searched in
a window about the best pair, and need not be one piece: play without a
slip jump at a smaller S can fit as well as a jump (a reading late by a
dead time makes a slip look like a smooth move), so play is scored on its
own and J's range reaches 0 where it lies inside.
"""

from dataclasses import dataclass, field
import functools
import math
import time

import numpy as np

from stiction_ros.analysis import fit_core
from stiction_ros.errors import IdentifyError
from stiction_ros.kernels import sse as sse_kernels
from stiction_ros.models.lags import first_order_pole

KERNELS = {'kano': 0, 'choudhury': 1}
CHI2_95_2DOF = 5.991464547107979
# An MSE this small against MV's squared travel (an RMS error of a millionth of it) is
# an exact fit, rounding apart; the 95 % region is then the pairs that fit as exactly.
EXACT_MSE = 1e-12


@dataclass
class Fit:
    """One model's parameters and its MSE (eq. 2.8) on the record."""

    model: str
    S: float
    J: float
    mse: float
    source: str
    samples: int
    filter_name: str | None = None
    filter_value: float | None = None
    S_interval: tuple | None = None
    J_interval: tuple | None = None
    evaluations: int = 0
    seconds: float = 0.0
    extra: dict = field(default_factory=dict)

    def to_json(self):
        """Return the fit as a JSON-able dict, the report's ``fits`` entry."""
        out = {'model': self.model, 'S': self.S, 'J': self.J, 'mse': self.mse,
               'source': self.source, 'samples': self.samples}
        if self.filter_name:
            out[self.filter_name] = self.filter_value
        if self.S_interval is not None:
            out['S_interval'] = list(self.S_interval)
            out['J_interval'] = list(self.J_interval)
        if self.source == 'identified':
            out['evaluations'] = self.evaluations
            out['seconds'] = round(self.seconds, 4)
        out.update(self.extra)
        return out


def segment_bounds(n, segments=None):
    """Return (starts, stops) int arrays for the kernels; the whole record by default."""
    if segments is None:
        segments = [(0, n)]
    segments = [(int(a), int(b)) for a, b in segments if b - a >= 2]
    if not segments:
        raise IdentifyError('no stretch of at least 2 valid samples to fit on')
    return (np.array([a for a, _ in segments], dtype=np.int64),
            np.array([b for _, b in segments], dtype=np.int64))


class ValveProblem(fit_core.Problem):
    """The data and model of one identification (OP -> MV): scores (S, J) pairs."""

    def __init__(self, model, op, mv, segments=None, filter_value=None, sample_time=1.0):
        if model not in KERNELS:
            raise IdentifyError(f'unknown model {model!r}; choose from {sorted(KERNELS)}')
        op = np.ascontiguousarray(op, dtype=np.float64)
        mv = np.ascontiguousarray(mv, dtype=np.float64)
        if op.shape != mv.shape:
            raise IdentifyError('op and mv must have the same length')
        super().__init__(op, mv, *segment_bounds(len(op), segments))
        self.model = model
        self.op, self.mv = self.u, self.y
        self.sample_time = float(sample_time)
        self.filter_name = 'tau' if model == 'kano' else 'lam'
        self.filter_value = filter_value
        self.f = self._kernel_filter(filter_value)

    def _kernel_filter(self, value):
        if self.model == 'kano':
            return first_order_pole(value or 0.0, self.sample_time)
        return 1.0 if value is None else float(value)

    def grid(self, s_values, j_values, limit=math.inf):
        """Return the SSE on the grid ``s_values`` x ``j_values`` (abandoned past ``limit``)."""
        s = np.ascontiguousarray(s_values, dtype=np.float64)
        j = np.ascontiguousarray(j_values, dtype=np.float64)
        self.evaluations += s.size * j.size
        return sse_kernels.grid_sse(KERNELS[self.model], self.op, self.mv, self.starts,
                                    self.stops, s, j, self.f, float(limit))

    def points_best(self, s_pts, j_pts, keep, known=(), limit=math.inf):
        """
        Score pairs in the given order: exact for the ``keep`` best, bounds elsewhere.

        ``known``: exact sums already found elsewhere, which tighten the bound
        from the first pair on (``sse_kernels.points_sse_best``).
        """
        s = np.ascontiguousarray(s_pts, dtype=np.float64)
        j = np.ascontiguousarray(j_pts, dtype=np.float64)
        best = np.full(keep, float(limit))
        known = np.sort(np.asarray(known, dtype=np.float64))[:keep]
        best[:known.size] = np.minimum(known, best[:known.size])
        best.sort()
        self.evaluations += s.size
        return sse_kernels.points_sse_best(KERNELS[self.model], self.op, self.mv, self.starts,
                                           self.stops, s, j, self.f, best)

    def grid_best(self, s_values, j_values, keep):
        """Return grid SSEs exact for the ``keep`` best pairs (bounds elsewhere)."""
        ns, nj = len(s_values), len(j_values)
        order = sse_kernels.spread_order(ns * nj)
        s_values = np.asarray(s_values, dtype=np.float64)
        j_values = np.asarray(j_values, dtype=np.float64)
        scores = np.empty(ns * nj)
        scores[order] = self.points_best(s_values[order // nj], j_values[order % nj], keep)
        return scores.reshape(ns, nj)

    def mse(self, S, J):
        """Return the exact MSE of eq. 2.8 at (S, J)."""
        return float(self.grid([S], [J])[0, 0]) / self.n

    def output(self, S, J):
        """Return the MV the model predicts at (S, J), as scored: NaN off the segments."""
        sim = np.full(len(self.op), np.nan)
        sse_kernels.valve_output(KERNELS[self.model], self.op, self.mv, self.starts, self.stops,
                                 float(S), float(J), self.f, sim)
        out = np.full(len(self.op), np.nan)
        for a, b in zip(self.starts, self.stops):
            out[a:b] = sim[a:b]
        return out


def _axis(lo, hi, step, res):
    """Return grid points on multiples of ``res`` from lo to hi (clipped at 0) every ``step``."""
    k = max(1, int(round(step / res)))
    a = max(0, int(math.floor(lo / res)))
    b = max(a, int(math.ceil(hi / res)))
    return np.arange(a, b + 1, k) * res


def _key(item, res):
    return (round(item[1] / res), round(item[2] / res))


def _keep_best(scores, s_values, j_values, keep):
    """Return the ``keep`` lowest-scoring (sse, S, J), ties broken by smaller S + J."""
    flat = np.argsort(scores, axis=None, kind='stable')[:keep]
    out = []
    for idx in flat:
        i, j = np.unravel_index(idx, scores.shape)
        out.append((float(scores[i, j]), float(s_values[i]), float(j_values[j])))
    return out


def search(problem, s_max, j_max, resolution=0.01, coarse_points=96, keep=12, progress=None):
    """
    Return (sse, S, J) of the best pair on multiples of ``resolution``.

    ``coarse_points`` sets the coarse step (the larger box side over that
    many points); each level refines five-fold around the ``keep`` best.
    With 48 points a loop whose OP spans 70 % (step 1.5 %) lost the true
    basin of S = 3.42 to a wrong one ten times worse; 96 found it.
    """
    res = float(resolution)
    step = max(res, max(s_max, j_max) / coarse_points)
    step = res * max(1, round(step / res))
    s_axis = _axis(0.0, s_max, step, res)
    j_axis = _axis(0.0, j_max, step, res)
    scores = problem.grid_best(s_axis, j_axis, keep)
    best = _keep_best(scores, s_axis, j_axis, keep)
    level = 0
    while step > res:
        level += 1
        fine = res * max(1, round(step / 5 / res))
        # Every kept candidate's neighbourhood at the finer step, each pair once, the
        # best candidate's first: scored against the kept sums, the bound is tight at once.
        seen = {_key(item, res) for item in best}
        pts = {}
        for _, s0, j0 in best:
            for s in _axis(s0 - step, s0 + step, fine, res):
                for j in _axis(j0 - step, j0 + step, fine, res):
                    key = (round(s / res), round(j / res))
                    if key not in seen and key not in pts:
                        pts[key] = (s, j)
        s_pts = np.array([p[0] for p in pts.values()])
        j_pts = np.array([p[1] for p in pts.values()])
        # The last level needs only the best pair, so only it bounds the others.
        k = 1 if fine <= res else keep
        sc = problem.points_best(s_pts, j_pts, k, [item[0] for item in best])
        new = [(float(e), float(s), float(j)) for e, s, j in zip(sc, s_pts, j_pts)]
        # The keep best of old and new are exact: every abandoned pair is worse.
        best = sorted(best + new, key=lambda x: (x[0], x[1] + x[2]))[:keep]
        step = fine
        if progress is not None:
            progress(level, problem.evaluations)
    return best[0]


BOX_POINTS = 100


def confidence_box(problem, S, J, mse_min, resolution=0.01, half_width=0.25, grow=4):
    """
    Return ((S_lo, S_hi), (J_lo, J_hi)): the 95 % joint region projected on each axis.

    The region is every grid pair with ``N ln(MSE / MSE_min)`` under the
    two-degree-of-freedom chi-square quantile; the window around the optimum
    doubles while the region touches its edge (at most ``grow`` times), its
    grid never finer than ``resolution`` nor more than ``BOX_POINTS`` a side.
    Where J's range stays clear of 0, the best play (:func:`best_play`) is
    scored too, and J's range reaches 0 (S's, play's S) where it lies inside.
    """
    # In MV's own units squared, so that MV given in other units reads the same.
    exact = EXACT_MSE * (float(np.ptp(problem.mv)) or 1.0) ** 2
    if mse_min <= exact:
        # An exact fit has no noise to scale a likelihood region by: the region
        # is every pair that fits exactly too (noise-free MV is a noise-free
        # path, and on a 0.01 % grid several S and J often trace the same one).
        sse_bound = exact * problem.n
    else:
        sse_bound = mse_min * problem.n * math.exp(CHI2_95_2DOF / problem.n) * (1 + 1e-12)
    w = half_width
    # Where no grid point is inside, the optimum itself is, within a step.
    found = (np.array([S]), np.array([J]), np.array([0]), np.array([0]), resolution)
    cut = None
    for _ in range(grow + 1):
        # At most BOX_POINTS per axis: a region several % wide needs no 0.01 % edges,
        # and at full resolution a poor fit's widest window cost 640 000 runs (36 s).
        step = max(resolution, 2.0 * w / BOX_POINTS)
        s_ax = _axis(S - w, S + w, step, resolution)
        j_ax = _axis(J - w, J + w, step, resolution)
        inside = problem.grid(s_ax, j_ax, sse_bound) <= sse_bound
        ii, jj = np.nonzero(inside)
        if ii.size == 0:
            # A thin ridge of S-J pairs (a poor fit, its optimum off the coarse lattice)
            # can slip between the points of a coarsened grid; the finer window's region
            # went on past its edge, so it reaches this window's edge there.
            cut = w
            break
        found = (s_ax, j_ax, ii, jj, step)
        if not _at_edge(s_ax, j_ax, ii, jj).any():
            break
        w *= 2
    s_ax, j_ax, ii, jj, step = found
    # On a coarsened grid the edge lies within a step outside the last point inside.
    pad = step if step > resolution else 0.0
    box = np.array([max(float(s_ax[ii.min()]) - pad, 0.0), float(s_ax[ii.max()]) + pad,
                    max(float(j_ax[jj.min()]) - pad, 0.0), float(j_ax[jj.max()]) + pad])
    if cut is not None:
        # Wider, not cut short: a range that looks clear of a floor must be so.
        reach = np.array([max(S - cut, 0.0), S + cut, max(J - cut, 0.0), J + cut])
        box = np.where(_at_edge(s_ax, j_ax, ii, jj), reach, box)
    if box[2] > 0.0:
        # The region need not be one piece: play (J = 0) at an S outside this window can
        # fit within it, where a dead time or noise lets a smooth move stand in for a slip.
        play = best_play(problem, sse_bound)
        if play is not None and play[0] <= sse_bound:
            box = np.array([min(box[0], play[1]), max(box[1], play[1]), 0.0, box[3]])
    lo_s, hi_s, lo_j, hi_j = (round(float(v), 10) for v in box)
    return (lo_s, hi_s), (lo_j, hi_j)


# Play's S is searched on this grid (% of span), then at the fit's resolution about its best.
PLAY_STEP = 0.1


def best_play(problem, limit: float, resolution: float = 0.01) -> tuple[float, float] | None:
    """
    Return (SSE, S) of the best play without a slip jump (J = 0), or None where none comes near.

    S runs over OP's travel in the scored samples (at most 100 %).  Pairs are
    abandoned past twice ``limit``; the fine search runs about the three best
    coarse ones that came under it.
    """
    runs = list(zip(problem.starts, problem.stops))
    s_max, _ = plausible_box(np.concatenate([problem.u[a:b] for a, b in runs]),
                             np.concatenate([problem.y[a:b] for a, b in runs]))
    coarse = _axis(0.0, s_max, PLAY_STEP, resolution)
    scores = problem.grid(coarse, [0.0], 2.0 * limit)[:, 0]
    near = [float(coarse[i]) for i in np.argsort(scores, kind='stable')[:3]
            if scores[i] < 2.0 * limit]
    if not near:
        return None
    fine = np.unique(np.concatenate([_axis(s - PLAY_STEP, s + PLAY_STEP, resolution, resolution)
                                     for s in near]))
    sse = problem.grid(fine, [0.0], 2.0 * limit)[:, 0]
    i = int(np.argmin(sse))
    return float(sse[i]), float(fine[i])


def _at_edge(s_ax, j_ax, ii, jj) -> np.ndarray:
    """Return whether the region touches its window's low S, high S, low J, high J edge."""
    return np.array([ii.min() == 0 and s_ax[0] > 0, ii.max() == len(s_ax) - 1,
                     jj.min() == 0 and j_ax[0] > 0, jj.max() == len(j_ax) - 1])


# Where the search's best S comes within this share of the box's S side, the box may
# have cut the valve's S off: a valve that starts at rest breaks away once OP has
# travelled (S + J) / 2, so OP's travel bounds S only after a reversal the valve
# followed, and 2 x the travel from rest (models.breakaway).
AT_CAP = 0.95


def wider_s(s: float, s_max: float) -> float | None:
    """Return the S side to search again where ``s`` came within ``AT_CAP`` of it, else None."""
    return min(2.0 * s_max, 100.0) if s >= AT_CAP * s_max and s_max < 100.0 else None


def plausible_box(op, mv):
    """Return (s_max, j_max): S within OP's travel, J within MV's (see ``AT_CAP``)."""
    s_max = float(np.ptp(op))
    j_max = float(np.ptp(mv))
    if s_max <= 0.0:
        raise IdentifyError('OP never moves, so S and J cannot be identified')
    return min(s_max, 100.0), max(min(j_max, 100.0), 0.5)


@dataclass(frozen=True)
class SearchProgress:
    """Where one identification stands: ``model``'s search ``search`` of ``searches``."""

    model: str
    search: int
    searches: int
    level: int
    evaluations: int


def _report(progress, model, search, searches, level, evaluations):
    progress(SearchProgress(model, search, searches, level, evaluations))


def identify(op, mv, model='kano', segments=None, sample_time=1.0, resolution=0.01,
             filter_values=None, interval=True, progress=None):
    """
    Identify (S, J) of ``model`` on measured OP and MV; return a :class:`Fit`.

    ``filter_values``: if given, a sequence of air-chamber time constants
    (Kano, seconds) or EWMA weights (Choudhury) to try; the best is kept, one
    search each.  ``progress`` gets a :class:`SearchProgress` at every level
    of every search.
    """
    t0 = time.perf_counter()
    op = np.asarray(op, dtype=np.float64)
    mv = np.asarray(mv, dtype=np.float64)
    starts, stops = segment_bounds(len(op), segments)
    used = np.concatenate([np.arange(a, b) for a, b in zip(starts, stops)])
    s_max, j_max = plausible_box(op[used], mv[used])
    candidates = [None] if filter_values is None else list(filter_values)
    best = None
    problems = []
    for i, fv in enumerate(candidates):
        problem = ValveProblem(model, op, mv, segments, fv, sample_time)
        problems.append(problem)
        step = None if progress is None else functools.partial(
            _report, progress, model, i + 1, len(candidates))
        sse, S, J = search(problem, s_max, j_max, resolution, progress=step)
        s_wide = wider_s(S, s_max)
        if s_wide is not None:
            # Searched again on the whole box a first move from rest allows; kept
            # only where it fits better, so that a valve inside the box is unchanged.
            wide = search(problem, s_wide, j_max, resolution, progress=step)
            if wide[0] < sse:
                sse, S, J = wide
        if best is None or sse < best[0]:
            best = (sse, S, J, fv, problem)
    sse, S, J, fv, problem = best
    mse = sse / problem.n
    fit = Fit(model, round(S, 10), round(J, 10), mse, 'identified', problem.n,
              problem.filter_name if filter_values is not None else None, fv)
    if interval:
        fit.S_interval, fit.J_interval = confidence_box(problem, S, J, mse, resolution)
    fit.evaluations = sum(p.evaluations for p in problems)
    fit.seconds = time.perf_counter() - t0
    return fit


def given_fit(op, mv, model, S, J, segments=None, sample_time=1.0, filter_value=None):
    """Return the :class:`Fit` (MSE of eq. 2.8) of ``model`` with the given S and J."""
    problem = ValveProblem(model, op, mv, segments, filter_value, sample_time)
    return Fit(model, float(S), float(J), problem.mse(S, J), 'given', problem.n,
               problem.filter_name if filter_value is not None else None, filter_value)


def mse_landscape(op, mv, fit, segments=None, sample_time=1.0, half_width=0.5, points=51):
    """
    Return the MSE on a grid around ``fit``, the 95 % bound and the ceiling, for the report.

    Points past ``ceiling`` (an MSE) are abandoned and hold the ceiling.
    """
    problem = ValveProblem(fit.model, op, mv, segments, fit.filter_value, sample_time)
    s_ax = np.linspace(max(0.0, fit.S - half_width), fit.S + half_width, points)
    j_ax = np.linspace(max(0.0, fit.J - half_width), fit.J + half_width, points)
    # Abandon far-off points: 1e4 times the best MSE, but never below ten times MV's
    # variance (that of a valve frozen at its mean), so a fit near MSE 0 still gets a
    # landscape rather than one flat ceiling.
    y = np.concatenate([problem.mv[a:b] for a, b in zip(problem.starts, problem.stops)])
    ceiling = max(fit.mse * 1e4, 10.0 * float(np.var(y)) if len(y) else 0.0, 1e-12)
    cap = ceiling * problem.n
    mse = np.minimum(problem.grid(s_ax, j_ax, cap), cap) / problem.n
    bound = fit.mse * math.exp(CHI2_95_2DOF / problem.n)
    return {'model': fit.model, 'S': s_ax, 'J': j_ax, 'mse': np.maximum(mse, 1e-12),
            'bound': bound, 'best': (fit.S, fit.J), 'ceiling': ceiling}
