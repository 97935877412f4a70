"""
Quantify valve stiction (S, J) from OP and PV alone, with a Hammerstein model.

An industrial record seldom has the valve position, so the valve is modelled
inside the loop (Srinivasan et al. 2005; Jelali 2008)::

    OP --> Kano model (S, J) --> MV_hat --> linear plant G(q) --> PV

For fixed (S, J) the model is linear in the parameters of G, so the fit is a
separable least-squares problem (Jelali 2008): a global search over (S, J)
outside, linear least squares inside.  G is an ARX model,

    A(q) y[k] = B(q) v[k - d] + c_seg + e[k],

with ``na`` PV lags, ``nb`` lags of ``v = MV_hat`` from dead time ``d``
samples and one constant per valid segment.  The constant and B absorb the
unknown offset and gain of MV_hat (the valve position is never measured).
For an integrating plant (level loops) the integrator is moved to the input:
``v`` is replaced by its running sum within the segment and a time trend per
segment absorbs the unknown MV_hat offset, which a sum turns into a ramp.
Differencing PV instead would leave a one-step-ahead fit that is mostly
differenced noise, and its PV-lag coefficients would be badly biased.

For each (S, J), MV_hat is Kano's output (Kano et al. 2004) driven by OP;
every dead time from ``min_delay`` to ``max_delay`` samples is fitted and
the smallest residual sum of squares (SSE) kept.  The PV lags do not depend
on (S, J), so they are projected out once and each candidate costs one pass
of compiled code.

The search
----------
The SSE is a jumpy function of (S, J): a breakaway moves by whole samples.
S also trades off against the dead time (a valve that breaks away later looks
like a longer delay), so every dead time has its own narrow valley, the
narrower the less noise there is on OP and the more cycles the record holds.
And nobody recorded where the valve stuck before a segment begins: Kano's
valve stops at every reversal of a noisy OP's increment, so a wrong start
state is never forgotten (model and valve go on slipping on different
samples), which biases J and can move S.  Hence:

1. a coarse grid over the whole box (S and J up to the OP travel, every dead
   time), the valve at rest with no direction at each segment start;
2. its ``KEEP`` best candidates, at most ``PER_DELAY`` per dead time so that
   no valley is lost, each get their best start state (direction of the
   last move and where within the band of stick points OP stood), segment
   by segment;
3. they are refined five-fold per level around their own dead time, as in
   ``identify``;
4. J and the start states are gridded together at the best S (both are set
   by the first slips), then the best few are refined again.

Evidence and uncertainty
------------------------
``fit_improvement`` is the residual variance of the best Hammerstein model
over that of the best linear model (S = J = 0, same ARX orders and dead-time
search): below 1 the sticky valve explains PV better.  The search picks the
best of thousands of (S, J) pairs, and a small S filters the noise that the
controller feeds back into OP, so a linear valve still gets a ratio a little
below 1 (0.91 to 1 in our simulations, 0.90 to 1 on the plant records
labelled without stiction); ``MAX_IMPROVEMENT_RATIO`` sets the bar at 0.9.  The ratio
is of one-step-ahead prediction errors, which PV noise dominates: with PV
noise of about a tenth of the oscillation amplitude, a real stiction may no
longer clear the bar although S is still estimated well.

Each interval is the union of two:

* the 95 % likelihood-ratio region, the grid pairs with
  ``n_eff ln(SSE / SSE_min)`` under the chi-square quantile with two degrees
  of freedom (``n_eff``: the sample count over the integrated autocorrelation
  of the residuals), projected on the axis and padded by one grid step;
* the estimate plus or minus two delete-a-block jackknife standard errors
  (``JACKKNIFE_BLOCKS`` consecutive blocks).  The likelihood region assumes
  the model is right; the jackknife shows how far the optimum moves between
  parts of a record, which is what a real valve, plant and sampling that the
  model only approximates do.

Neither accounts for the bias of an ARX fit in closed loop, so the true pair
can still lie outside, mostly by a few per cent of S.

Identifiability
---------------
* S (deadband plus stickband, % of OP) is set by when the valve breaks away,
  i.e. how far OP travels while PV does not respond; it is well determined
  when the valve sticks and slips several times.
* J (slip jump) is in % of OP as well, but only under the assumption of unity
  valve gain: the gain of B absorbs any scaling of MV_hat.  In a limit cycle
  the valve jumps by J at each reversal and then follows OP until the next
  reversal; J is identified only through the ratio of the jump to that
  follow-through.  When OP reverses soon after each slip (large J, J near S,
  or a fast loop sampled slowly) MV_hat is nearly a square wave whose height
  the plant gain absorbs, and J is weakly determined: read its interval, not
  its value, and an interval of None means the data do not bound it.
* J also depends on the valve's unrecorded state at each segment start; the
  search fits it (step 4), but on short segments after a gap J can still be
  off by a quarter while S is right.
* Only the dead time of the Kano model is resolved to a sample; breakaways
  between samples, an air-chamber lag or a different friction law shift S.
* A regular oscillation is needed; a record without one, too short, where
  stiction does not explain PV better than a linear valve, whose optimum or
  S interval reaches the upper edge of the search box, or whose dead time is
  the longest searched is marked ``reliable = False`` with the reason.

References
----------
Jelali, M. (2008), Estimation of valve stiction in control loops using
separable least-squares and global search algorithms, Journal of Process
Control 18(7-8), 632-642.
Srinivasan, R., Rengaswamy, R., Narasimhan, S., Miller, R. (2005), Control
loop performance assessment. 2. Hammerstein model approach for stiction
diagnosis, Industrial & Engineering Chemistry Research 44(17), 6719-6728.
Kano, M., Maruta, H., Kugemoto, H., Shimizu, K. (2004), Practical model and
detection algorithm for valve stiction, IFAC DYCOPS 2004, Cambridge MA.

"""

from dataclasses import dataclass, field
import math
import time

import numpy as np

from stiction_ros.analysis.oscillation import detect_oscillation
from stiction_ros.analysis.sse_kernels import kano_output, njit

CHI2_95_2DOF = 5.991464547107979
# A linear valve scores 0.9 to 1 (see the module docstring); stiction with
# moderate noise 0.05 to 0.85.
MAX_IMPROVEMENT_RATIO = 0.9
MIN_ROWS = 200
COARSE_POINTS = 24
KEEP = 16
REFINE = 5
PER_DELAY = 2
JACKKNIFE_BLOCKS = 4
FINAL_KEEP = 4
# Valve start states (direction, fraction of the band of stick points): a
# few to polish each candidate, then a fine grid together with J.
START_J_POINTS = 21
START_FINE_POINTS = 41
START_SEGMENTS = 4
START_STATES = ((0, 0.5),) + tuple((d, f) for d in (1, -1) for f in np.linspace(0, 1, 13))
MIN_CYCLES = 3
DEFAULT_MAX_DELAY = 30
REFERENCE = ('Jelali (2008) J. Process Control 18, 632-642; Srinivasan et al. (2005) '
             'Ind. Eng. Chem. Res. 44, 6719-6728')


@dataclass
class HammersteinResult:
    """
    The Hammerstein quantification of one record.

    ``S`` and ``J`` are in % of OP (J assuming unity valve gain); None when
    the data could not be fitted at all.  An interval is None where the data
    do not bound it (the 95 % region reaches the edge of the search box).
    ``fit_improvement`` is residual variance with stiction over that with a
    linear valve.  ``linear_model`` describes G; ``details`` holds the search
    box, sample counts, the fitted valve start states, the jackknife
    standard errors and timings; ``curves`` holds MV_hat for figures and is
    never written to JSON.
    """

    S: float | None
    J: float | None
    S_interval: tuple | None
    J_interval: tuple | None
    fit_improvement: float | None
    reliable: bool
    reason: str
    linear_model: dict = field(default_factory=dict)
    details: dict = field(default_factory=dict)
    curves: dict = field(default_factory=dict)

    def to_json(self):
        """Return the JSON-able part (everything but ``curves``)."""
        def interval(iv):
            return None if iv is None else [float(iv[0]), float(iv[1])]
        return {'S': self.S, 'J': self.J, 'S_interval': interval(self.S_interval),
                'J_interval': interval(self.J_interval),
                'fit_improvement': self.fit_improvement, 'reliable': self.reliable,
                'reason': self.reason, 'linear_model': self.linear_model,
                'details': self.details, 'reference': REFERENCE}


@njit(cache=True)
def _reduction(h, g):
    # g' H^-1 g by Cholesky; a pivot lost to round-off marks a column that
    # repeats the others (a valve that never moves), which explains nothing.
    m = g.shape[0]
    low = np.zeros((m, m))
    z = np.zeros(m)
    for i in range(m):
        for j in range(i + 1):
            s = h[i, j]
            for k in range(j):
                s -= low[i, k] * low[j, k]
            if i == j:
                if s <= 1e-10 * max(h[i, i], 1e-300):
                    low[i, i] = 0.0
                else:
                    low[i, i] = math.sqrt(s)
            elif low[j, j] > 0.0:
                low[i, j] = s / low[j, j]
        if low[i, i] > 0.0:
            s = g[i]
            for k in range(i):
                s -= low[i, k] * z[k]
            z[i] = s / low[i, i]
    return np.sum(z * z)


@njit(cache=True)
def segment_path(u, S, J, direction, fraction):
    """
    Return Kano's output for ``u`` from the start state (``direction``, ``fraction``).

    ``direction`` 0: at rest at ``u[0]`` with no direction, so breakaway
    needs (S + J) / 2 either way.  +1 or -1: at rest after moving that way,
    so it breaks away J onwards or S back from the OP where it stuck; that
    OP lies ``fraction`` (0 to 1) of the way across the band of stick points
    from which ``u[0]`` does not break it away.  Two samples of history in
    front of ``u`` put the model in that state.
    """
    if direction == 0:
        return kano_output(u, u[0], S, J, 0.0)
    stuck_at = u[0] - (J if direction > 0 else S) + fraction * (S + J)
    w = np.empty(u.shape[0] + 2)
    w[0] = stuck_at - direction * (S + J + 1.0)
    w[1] = stuck_at
    w[2:] = u
    return kano_output(w, w[0], S, J, 0.0)[2:]


@njit(cache=True)
def _valve_path(u, starts, stops, S, J, ubar, integrate, start_dir, start_frac, v):
    # Centred so that the cross products below do not cancel catastrophically.
    for s in range(starts.shape[0]):
        a = starts[s]
        b = stops[s]
        v[a:b] = segment_path(u[a:b], S, J, start_dir[s], start_frac[s]) - ubar
        if integrate:
            v[a:b] = np.cumsum(v[a:b])


@njit(cache=True)
def _best_delay(v, rows, row_seg, seg_rows, qy, tres, tt, dlo, dhi, nb):
    # Cross products of every lag of v with the projected regressors, then
    # the SSE of each dead time from a small (nb x nb) system.
    nl = dhi - dlo + nb
    p = qy.shape[1]
    nseg = seg_rows.shape[0]
    qv = np.zeros((nl, p))
    tv = np.zeros(nl)
    vv = np.zeros((nl, nb))
    sv = np.zeros((nseg, nl))
    for r in range(rows.shape[0]):
        k = rows[r] - dlo
        s = row_seg[r]
        for i in range(nl):
            x = v[k - i]
            sv[s, i] += x
            tv[i] += x * tres[r]
            for c in range(p):
                qv[i, c] += x * qy[r, c]
            for m in range(min(nb, nl - i)):
                vv[i, m] += x * v[k - i - m]
    best = np.inf
    best_d = dlo
    h = np.empty((nb, nb))
    g = np.empty(nb)
    for d in range(dhi - dlo + 1):
        for a in range(nb):
            g[a] = tv[d + a]
            for b in range(a, nb):
                x = vv[d + a, b - a]
                for s in range(nseg):
                    if seg_rows[s] > 0.0:
                        x -= sv[s, d + a] * sv[s, d + b] / seg_rows[s]
                for c in range(p):
                    x -= qv[d + a, c] * qv[d + b, c]
                h[a, b] = x
                h[b, a] = x
        sse = tt - _reduction(h, g)
        if sse < best:
            best = sse
            best_d = d + dlo
    return max(best, 0.0), best_d


@njit(cache=True)
def _grid_sse(u, ubar, integrate, start_dir, start_frac, starts, stops, rows, row_seg,
              seg_rows, qy, tres, tt, s_values, j_values, dlo, dhi, nb):
    v = np.zeros(u.shape[0])
    sse = np.empty((s_values.shape[0], j_values.shape[0]))
    delay = np.empty((s_values.shape[0], j_values.shape[0]), dtype=np.int64)
    for i in range(s_values.shape[0]):
        for j in range(j_values.shape[0]):
            _valve_path(u, starts, stops, s_values[i], j_values[j], ubar, integrate, start_dir,
                        start_frac, v)
            sse[i, j], delay[i, j] = _best_delay(v, rows, row_seg, seg_rows, qy, tres, tt,
                                                 dlo, dhi, nb)
    return sse, delay


def valid_segments(op, pv, segments=None, min_samples=2):
    """Return the (start, stop) ranges of ``segments`` split wherever OP or PV is not finite."""
    n = len(op)
    ok = np.isfinite(op) & np.isfinite(pv)
    out = []
    for a, b in segments if segments is not None else [(0, n)]:
        a, b = max(int(a), 0), min(int(b), n)
        edges = np.flatnonzero(np.diff(np.concatenate(([False], ok[a:b], [False])).astype(int)))
        out += [(a + s, a + e) for s, e in zip(edges[::2], edges[1::2]) if e - s >= min_samples]
    return out


class Problem:
    """
    The data of one quantification, ready for the compiled kernel.

    The regression rows are taken within each segment only, from the first
    sample where every lag up to ``max_delay + nb - 1`` of the valve input
    exists, so every dead time is scored on the same rows and no regressor
    reaches across a gap.  ``exclude``, a list of (start, stop) ranges, drops
    rows from the fit but not from the valve simulation, whose state must
    run through them (the jackknife's blocks).
    Per-segment means and the PV lags are projected out here once.
    """

    def __init__(self, op, pv, segments, integrating, orders, min_delay, max_delay,
                 exclude=()):
        self.op = np.ascontiguousarray(op, dtype=np.float64)
        self.pv = np.asarray(pv, dtype=np.float64)
        self.integrating = bool(integrating)
        self.na, self.nb = int(orders[0]), int(orders[1])
        self.dlo, self.dhi = int(min_delay), int(max_delay)
        lead = max(self.na, self.dhi + self.nb - 1)
        self.segments = [(a, b) for a, b in segments if b - a > lead + 10]
        self.starts = np.array([a for a, _ in self.segments], dtype=np.int64)
        self.stops = np.array([b for _, b in self.segments], dtype=np.int64)
        rows = [np.arange(a + lead, b, dtype=np.int64) for a, b in self.segments]
        self.exclude = list(exclude)
        for lo, hi in self.exclude:
            rows = [r[(r < lo) | (r >= hi)] for r in rows]
        self.rows = np.concatenate(rows or [np.zeros(0, dtype=np.int64)])
        self.row_seg = np.concatenate([np.full(len(r), s, dtype=np.int64)
                                       for s, r in enumerate(rows)] or [self.rows[:0]])
        self.seg_rows = np.array([len(r) for r in rows], dtype=np.float64)
        self.n = len(self.rows)
        self.ubar = float(np.mean(self.op[self.rows])) if self.n else 0.0
        self.evaluations = 0
        if self.n:
            self._project()

    def target_and_lags(self):
        """Return PV and the regressors that do not depend on (S, J), on the regression rows."""
        cols = [self.pv[self.rows - i] for i in range(1, self.na + 1)]
        if self.integrating:
            # The running sum of an MV_hat offset is a ramp in each segment.
            cols += [np.where(self.row_seg == s, self.rows.astype(np.float64), 0.0)
                     for s in range(len(self.segments))]
        return self.pv[self.rows], np.column_stack(cols)

    def demean(self, x):
        """Return ``x`` (rows first) minus its mean over each segment's rows."""
        x = np.array(x, dtype=np.float64)
        for s in range(len(self.segments)):
            m = self.row_seg == s
            if m.any():
                x[m] -= x[m].mean(axis=0)
        return x

    def _project(self):
        t, lags = self.target_and_lags()
        t, lags = self.demean(t), self.demean(lags)
        u, sv, _ = np.linalg.svd(lags, full_matrices=False)
        keep = sv > 1e-10 * max(sv.max(initial=0.0), 1e-300)
        self.qy = np.ascontiguousarray(u[:, keep])
        self.tres = t - self.qy @ (self.qy.T @ t)
        self.tt = float(self.tres @ self.tres)

    def grid(self, s_values, j_values, start, dlo=None, dhi=None):
        """
        Return (SSE, best dead time) arrays over the grid ``s_values`` x ``j_values``.

        ``start`` holds the valve's start state, (direction, fraction) per
        segment (see :func:`segment_path`); dead times ``dlo`` to ``dhi``.
        """
        dlo = self.dlo if dlo is None else max(self.dlo, dlo)
        dhi = self.dhi if dhi is None else min(self.dhi, dhi)
        s = np.ascontiguousarray(s_values, dtype=np.float64)
        j = np.ascontiguousarray(j_values, dtype=np.float64)
        self.evaluations += s.size * j.size
        return _grid_sse(self.op, self.ubar, self.integrating,
                         np.array([d for d, _ in start], dtype=np.int64),
                         np.array([f for _, f in start], dtype=np.float64), self.starts,
                         self.stops, self.rows, self.row_seg, self.seg_rows, self.qy, self.tres,
                         self.tt, s, j, dlo, dhi, self.nb)

    def at_rest(self):
        """Return the default start state: every segment at rest with no direction."""
        return ((0, 0.5),) * len(self.segments)

    def mv_hat(self, S, J, start):
        """Return Kano's MV_hat over the record, NaN outside the segments."""
        v = np.full(len(self.op), np.nan)
        for (a, b), (d, f) in zip(self.segments, start):
            v[a:b] = segment_path(self.op[a:b], float(S), float(J), int(d), float(f))
        return v

    def fit(self, S, J, delay, start):
        """Return (coefficients dict, residuals) of the ARX model at (S, J, dead time)."""
        v = self.mv_hat(S, J, start) - self.ubar
        if self.integrating:
            for a, b in self.segments:
                v[a:b] = np.cumsum(v[a:b])
        t, fixed = self.target_and_lags()
        vlags = np.column_stack([v[self.rows - delay - i] for i in range(self.nb)])
        ind = (self.row_seg[:, None] == np.arange(len(self.segments))).astype(np.float64)
        x = np.hstack([fixed, vlags, ind])
        coef, *_ = np.linalg.lstsq(x, t, rcond=None)
        nf = fixed.shape[1]
        return {'a': coef[:self.na], 'b': coef[nf:nf + self.nb]}, t - x @ coef


class Search:
    """
    Coarse-to-fine grid over the (S, J) box; remembers every pair scored.

    A candidate is (sse, S, J, dead time, start), ``start`` the valve's start
    state per segment (see :func:`segment_path`); the steps are those of the
    module docstring.
    """

    def __init__(self, problem, s_max, j_max, resolution):
        self.problem = problem
        self.s_max, self.j_max = s_max, j_max
        self.points = []
        self.levels = max(1, math.ceil(math.log(max(s_max, j_max) / COARSE_POINTS / resolution,
                                                REFINE)))

    def score(self, s_ax, j_ax, start, dlo=None, dhi=None):
        """Return the candidates of a grid from one start state, and remember them."""
        sse, delay = self.problem.grid(s_ax, j_ax, start, dlo, dhi)
        out = [(float(sse[i, j]), float(s_ax[i]), float(j_ax[j]), int(delay[i, j]), start)
               for i in range(len(s_ax)) for j in range(len(j_ax))]
        self.points += out
        return out

    def coarse(self):
        """Return the best candidates of the coarse grid over the whole box, start at rest."""
        found = self.score(np.linspace(0.0, self.s_max, COARSE_POINTS + 1),
                           np.linspace(0.0, self.j_max, COARSE_POINTS + 1),
                           self.problem.at_rest())
        return self.polish(_best(found, KEEP, PER_DELAY))

    def longest_segments(self):
        """Return the indices of the ``START_SEGMENTS`` longest segments (starts fitted)."""
        lengths = [b - a for a, b in self.problem.segments]
        return np.argsort([-n for n in lengths], kind='stable')[:START_SEGMENTS]

    def polish(self, candidates):
        """Return ``candidates`` each with its best start state, segment by segment."""
        out = []
        for sse, S, J, d, start in candidates:
            best = (sse, S, J, d, start)
            for seg in self.longest_segments():
                for state in START_STATES:
                    trial = best[4][:seg] + (state,) + best[4][seg + 1:]
                    p = self.score([S], [J], trial, d - 1, d + 1)[0]
                    best = min(best, p, key=lambda c: c[0])
            out.append(best)
        return _best(out, len(candidates), PER_DELAY)

    def settle_start(self, best):
        """
        Return ``best`` with J and the start states searched together at its S and dead time.

        J and the start state trade off (both set when the valve slips after
        the record begins) and each has narrow valleys, so they are gridded
        jointly, segment by segment for the ``START_SEGMENTS`` longest.
        """
        _, S, J, d, start = best
        j_ax = np.linspace(0.0, min(self.j_max, 2 * J + 0.1 * self.s_max), START_J_POINTS)
        states = ((0, 0.5),) + tuple((k, f) for k in (1, -1)
                                     for f in np.linspace(0.0, 1.0, START_FINE_POINTS))
        for seg in self.longest_segments():
            for state in states:
                trial = best[4][:seg] + (state,) + best[4][seg + 1:]
                best = min([best] + self.score([S], j_ax, trial, d - 1, d + 1),
                           key=lambda c: c[0])
        return best

    def rescore(self, candidates, keep):
        """Return the ``keep`` best of ``candidates`` scored afresh here, all dead times."""
        out = []
        for _, s0, j0, _, start in candidates:
            out += self.score([s0], [j0], start)
        return _best(out, keep, PER_DELAY)

    def refine(self, best, progress=None):
        """Return the best candidates (as many as ``best``) refining ``best`` level by level."""
        keep = len(best)
        s_step = self.s_max / COARSE_POINTS
        j_step = self.j_max / COARSE_POINTS
        for level in range(self.levels):
            found = []
            for _, s0, j0, d0, start in best:
                found += self.score(_window(s0, s_step, self.s_max),
                                    _window(j0, j_step, self.j_max), start, d0 - 1, d0 + 1)
            best = _best(found + best, keep, PER_DELAY)
            s_step, j_step = s_step / REFINE, j_step / REFINE
            if progress is not None:
                progress(level + 2, self.levels + 3)
        return best

    def region(self, best, n_eff):
        """Return the pairs inside the 95 % region and the grid steps of the last window."""
        sse_min, S, J, d, start = best
        bound = sse_min * math.exp(CHI2_95_2DOF / n_eff) * (1 + 1e-12)
        ws, wj = self.s_max / COARSE_POINTS, self.j_max / COARSE_POINTS
        # Grow a window around the optimum while the region touches its edge.
        for _ in range(5):
            steps = (ws / 12, wj / 12)
            s_ax = np.union1d(np.linspace(max(0.0, S - ws), min(self.s_max, S + ws), 25), [S])
            j_ax = np.union1d(np.linspace(max(0.0, J - wj), min(self.j_max, J + wj), 25), [J])
            inside = [p for p in self.score(s_ax, j_ax, start, d - 1, d + 1) if p[0] <= bound]
            lo_s, hi_s = min(p[1] for p in inside), max(p[1] for p in inside)
            lo_j, hi_j = min(p[2] for p in inside), max(p[2] for p in inside)
            if not ((lo_s == s_ax[0] > 0.0) or (hi_s == s_ax[-1] < self.s_max)
                    or (lo_j == j_ax[0] > 0.0) or (hi_j == j_ax[-1] < self.j_max)):
                break
            ws, wj = 2 * ws, 2 * wj
        return [p for p in self.points if p[0] <= bound], steps


def _best(points, keep, per_delay):
    """
    Return the ``keep`` lowest-SSE candidates of distinct (S, J), ties to smaller S + J.

    S trades off against the dead time (a later breakaway looks like a longer
    delay), so each dead time has its own valley; ``per_delay`` caps the
    candidates taken from one of them, to keep the others in the search.
    """
    seen = {}
    count = {}
    for p in sorted(points, key=lambda p: (p[0], p[1] + p[2])):
        key = (round(p[1], 9), round(p[2], 9))
        if key in seen or count.get(p[3], 0) == per_delay:
            continue
        seen[key] = p
        count[p[3]] = count.get(p[3], 0) + 1
        if len(seen) == keep:
            break
    return list(seen.values())


def _window(x0, step, top):
    """Return the points spanning ``x0 +- step`` at ``step / REFINE``, clipped to [0, top]."""
    return np.unique(np.clip(np.linspace(x0 - step, x0 + step, 2 * REFINE + 1), 0.0, top))


def effective_samples(e, max_lag=None):
    """Return the sample count over the integrated autocorrelation of residuals ``e``."""
    n = len(e)
    e = e - e.mean()
    var = float(e @ e)
    if n < 4 or var <= 0.0:
        return float(n)
    k = max_lag or max(1, min(n // 10, int(4 * math.sqrt(n))))
    rho = np.array([float(e[i:] @ e[:-i]) / var for i in range(1, k + 1)])
    # Bartlett weights keep the sum from being dominated by noisy far lags.
    tau = 1.0 + 2.0 * float(np.sum((1.0 - np.arange(1, k + 1) / (k + 1)) * rho))
    return float(min(n, max(n / max(tau, 1e-12), 10.0)))


def jackknife(problem, s_max, resolution, finalists):
    """
    Return the delete-a-block jackknife standard errors (se_S, se_J), or None.

    The regression rows are cut into ``JACKKNIFE_BLOCKS`` consecutive blocks;
    without the rows of each (the valve is still simulated through them, so
    its state stays right), the search is refined again from the full
    record's finalists, as most of the data put the valleys in the same
    places.  The
    spread of the estimates shows what the likelihood-ratio region cannot: a
    model that is only approximately right (valve, plant, sampling), whose
    optimum moves from one part of the record to another.
    """
    cuts = problem.rows[np.linspace(0, problem.n - 1, JACKKNIFE_BLOCKS + 1).astype(int)]
    cuts[-1] += 1
    est = []
    for lo, hi in zip(cuts[:-1], cuts[1:]):
        sub = Problem(problem.op, problem.pv, problem.segments, problem.integrating,
                      (problem.na, problem.nb), problem.dlo, problem.dhi,
                      problem.exclude + [(lo, hi)])
        if sub.n < MIN_ROWS or sub.tt <= 0.0:
            return None
        search = Search(sub, s_max, s_max, resolution)
        _, S, J, _, _ = search.refine(search.rescore(finalists, FINAL_KEEP))[0]
        est.append((S, J))
        problem.evaluations += sub.evaluations
    est = np.array(est)
    k = len(est)
    se = np.sqrt((k - 1) / k * np.sum((est - est.mean(axis=0)) ** 2, axis=0))
    return float(se[0]), float(se[1])


def linear_model_json(coefs, delay, problem, sample_time):
    """Return G as a JSON-able dict: ARX coefficients, gain, poles, time constant."""
    a, b = coefs['a'], coefs['b']
    poles = np.roots(np.concatenate(([1.0], -a))) if len(a) else np.zeros(0)
    real = [p.real for p in poles if abs(p.imag) < 1e-9 and 0.0 < p.real < 1.0]
    dominant = max(real, default=None)
    if dominant is not None and poles.size and abs(dominant) < np.max(np.abs(poles)) - 1e-9:
        dominant = None     # a complex pair dominates: no single time constant
    den = 1.0 - float(np.sum(a))
    gain = float(np.sum(b)) / den if abs(den) > 1e-9 else None
    out = {'structure': ('ARX on the running sum of MV_hat (integrating)' if problem.integrating
                         else 'ARX'),
           'na': problem.na, 'nb': problem.nb, 'delay_samples': int(delay),
           'delay_s': float(delay * sample_time), 'integrating': problem.integrating,
           'a': [float(x) for x in a], 'b': [float(x) for x in b],
           'poles': [[float(p.real), float(p.imag)] for p in poles],
           'time_constant_s': (None if dominant is None
                               else float(-sample_time / math.log(dominant)))}
    if problem.integrating:
        out['integrator_gain_per_s'] = None if gain is None else gain / sample_time
    else:
        out['gain'] = gain
    return out


def _interval(points, steps, axis, value, se, top):
    """
    Return (lo, hi) on ``axis`` (1 = S, 2 = J), or None where the data do not bound it.

    The union of the likelihood-ratio region, padded by one grid step, and
    ``value +- 2 se`` from the jackknife.
    """
    lo = min(p[axis] for p in points) - steps[axis - 1]
    hi = max(p[axis] for p in points) + steps[axis - 1]
    if se is not None:
        lo, hi = min(lo, value - 2 * se), max(hi, value + 2 * se)
    if hi >= top:
        return None
    return (round(max(lo, 0.0), 6), round(hi, 6))


def _failure(reason, details):
    return HammersteinResult(None, None, None, None, None, False, reason, details=details)


def _unusable(problem, op, pv):
    """Return why the data cannot be fitted at all, or ''."""
    if problem.n < MIN_ROWS:
        return (f'too short: {problem.n} usable samples after the lags, at least {MIN_ROWS} '
                'needed')
    if max(np.ptp(op[a:b]) for a, b in problem.segments) <= 0.0:
        return 'OP never moves, so the valve cannot be seen sticking'
    span = max(np.ptp(pv[a:b]) for a, b in problem.segments)
    if span <= 1e-9 * max(1.0, float(np.median(np.abs(pv[problem.rows])))) or problem.tt <= 0:
        return 'PV does not vary (or only as its own past predicts): nothing to fit'
    return ''


def quantify(op, pv, sample_time, segments=None, integrating=False, s_max=None, progress=None,
             orders=(2, 2), min_delay=1, max_delay=None, resolution=None):
    """
    Return the :class:`HammersteinResult` of OP and PV sampled every ``sample_time`` s.

    ``segments``: (start, stop) index ranges of valid samples (default: the
    whole record, split at NaN); regressors never reach across a gap.
    ``integrating``: put an integrator in front of G (level loops).
    ``s_max``: upper edge of the S and J search (default: the OP travel).
    ``orders``: ARX orders (PV lags, valve-input lags); dead times from
    ``min_delay`` to ``max_delay`` samples (default 30) are searched.
    ``resolution``: finest grid step in % (default s_max / 500).
    ``progress(done, total)`` is called after each search stage.
    """
    t0 = time.perf_counter()
    op = np.asarray(op, dtype=np.float64)
    pv = np.asarray(pv, dtype=np.float64)
    if op.shape != pv.shape or op.ndim != 1:
        raise ValueError('op and pv must be 1-D arrays of the same length')
    segs = valid_segments(op, pv, segments)
    longest = max((b - a for a, b in segs), default=0)
    max_delay = int(max_delay if max_delay is not None
                    else min(DEFAULT_MAX_DELAY, max(min_delay, longest // 10)))
    details = {'samples': int(sum(b - a for a, b in segs)), 'sample_time': float(sample_time),
               'min_delay': int(min_delay), 'max_delay': max_delay}
    problem = Problem(op, pv, segs, integrating, orders, min_delay, max_delay)
    details['rows'] = problem.n
    why = _unusable(problem, op, pv)
    if why:
        return _failure(why, details)
    s_max = float(min(s_max if s_max is not None
                      else max(np.ptp(op[a:b]) for a, b in problem.segments), 100.0))
    res = float(resolution if resolution is not None else s_max / 500)
    search = Search(problem, s_max, s_max, res)
    if progress is not None:
        progress(1, search.levels + 3)
    finalists = search.polish(search.refine(search.coarse(), progress))
    sse, S, J, delay, start = finalists[0]
    # Settled from the polished start and from rest: the grid is taken one
    # segment at a time and can stop in a local optimum.
    settled = [search.settle_start((sse, S, J, delay, s)) for s in (start, problem.at_rest())]
    finalists = search.refine(_best(settled + finalists, FINAL_KEEP, PER_DELAY))
    sse, S, J, delay, start = best = finalists[0]
    coefs, resid = problem.fit(S, J, delay, start)
    n_eff = effective_samples(resid)
    inside, steps = search.region(best, n_eff)
    se = jackknife(problem, s_max, res, finalists)
    if progress is not None:
        progress(search.levels + 3, search.levels + 3)
    lin_sse, _, _, lin_delay, _ = search.score([0.0], [0.0], problem.at_rest())[0]
    ratio = sse / lin_sse if lin_sse > 0 else 1.0
    lr = n_eff * math.log(lin_sse / sse) if sse > 0 else 1e300
    details.update({
        'search_box': {'S_max': s_max, 'J_max': s_max, 'resolution': res},
        'residual_variance': sse / problem.n, 'linear_residual_variance': lin_sse / problem.n,
        'linear_delay_samples': int(lin_delay), 'effective_samples': n_eff,
        'likelihood_ratio': lr,
        'jackknife_se': None if se is None else {'S': se[0], 'J': se[1]},
        'valve_start': [{'direction': int(d), 'fraction': float(f)} for d, f in start],
        'evaluations': problem.evaluations, 'seconds': round(time.perf_counter() - t0, 4)})
    result = HammersteinResult(
        round(S, 6), round(J, 6),
        _interval(inside, steps, 1, S, se and se[0], s_max),
        _interval(inside, steps, 2, J, se and se[1], s_max), float(ratio), True, '',
        linear_model_json(coefs, delay, problem, sample_time), details,
        {'mv_hat': problem.mv_hat(S, J, start)})
    _judge(result, problem, sample_time, lr, s_max, steps)
    return result


def _oscillation_reason(problem, sample_time):
    """Return '' if OP or PV oscillates regularly over the longest segment, else why not."""
    a, b = max(problem.segments, key=lambda s: s[1] - s[0])
    found = [detect_oscillation(x[a:b], sample_time) for x in (problem.op, problem.pv)]
    if any(o.oscillating and o.n_cycles >= MIN_CYCLES for o in found):
        return ''
    return (f'no regular oscillation of at least {MIN_CYCLES} cycles in OP or PV (OP: '
            f'{found[0].reason}; PV: {found[1].reason}): the valve did not stick and slip '
            'often enough to quantify')


def _judge(result, problem, sample_time, lr, s_max, steps):
    """Set ``reliable`` and ``reason`` from the checks the data must pass."""
    why = [_oscillation_reason(problem, sample_time)]
    ratio = result.fit_improvement
    if ratio > MAX_IMPROVEMENT_RATIO or lr < CHI2_95_2DOF:
        why.append(f'no improvement over a linear valve: residual variance ratio {ratio:.3g} '
                   f'(needs <= {MAX_IMPROVEMENT_RATIO}), likelihood ratio {lr:.3g}')
    if result.S >= s_max - steps[0] or result.J >= s_max - steps[1]:
        why.append(f'optimum on the edge of the search box (S, J <= {s_max:.4g} %, the OP '
                   'travel): the data do not bound it')
    elif result.S_interval is None:
        why.append('the 95 % interval of S reaches the edge of the search box')
    if result.linear_model['delay_samples'] >= problem.dhi:
        why.append(f'dead time at the end of the searched range ({problem.dhi} samples): the '
                   'plant model is not bounded either')
    why = [w for w in why if w]
    result.reliable = not why
    if why:
        result.reason = '; '.join(why)
        return
    j_iv = result.J_interval
    j_note = ('; J is not bounded by the data (weakly identifiable)' if j_iv is None
              else '; J is weakly determined, read its interval' if j_iv[1] - j_iv[0] > 0.5 *
              max(result.S, 1e-9) else '')
    result.reason = (f'a sticky valve explains PV better than a linear one (residual variance '
                     f'ratio {ratio:.3g}, likelihood ratio {lr:.3g}); S = {result.S:.3g} % '
                     f'in {list(result.S_interval)}{j_note}')
