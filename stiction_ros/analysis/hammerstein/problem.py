"""
The data of one Hammerstein fit and its separable regression.

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
of compiled code (``stiction_ros.kernels.hammerstein``).
"""

import numpy as np

from stiction_ros.analysis import fit_core
from stiction_ros.kernels.hammerstein import _grid_sse, segment_path

# Fewer regression rows leave the ARX fit and the residual statistics unreliable.
MIN_ROWS = 200
# The share of the target's sum of squares by which a grid cell's SSE may be wrong
# before it is scored again by least squares (the kernel's own bound on its rounding).
DOUBT = 1e-6


def valid_segments(op, pv, segments=None, min_samples=2) -> list:
    """Return the (start, stop) ranges of ``segments`` split wherever OP or PV is not finite."""
    n = len(op)
    ok = np.isfinite(op) & np.isfinite(pv)
    out = []
    for a, b in segments if segments is not None else [(0, n)]:
        a, b = max(int(a), 0), min(int(b), n)
        edges = np.flatnonzero(np.diff(np.concatenate(([False], ok[a:b], [False])).astype(int)))
        out += [(a + s, a + e) for s, e in zip(edges[::2], edges[1::2]) if e - s >= min_samples]
    return out


class HammersteinProblem(fit_core.Problem):
    """
    The data of one quantification (OP -> PV), ready for the compiled kernel.

    ``op`` and ``pv`` are the base class's ``u`` and ``y``.  Only segments
    longer than the lags (plus ten samples) are kept, in ``segments``,
    ``starts`` and ``stops``.  The regression rows are taken within each
    segment only, from the first sample where every lag up to
    ``max_delay + nb - 1`` of the valve input exists, so every dead time is
    scored on the same rows and no regressor reaches across a gap; ``n``
    counts these rows, not the segments' samples.  ``exclude``, a list of
    (start, stop) ranges, drops rows from the fit but not from the valve
    simulation, whose state must run through them (the jackknife's blocks).
    Per-segment means and the PV lags are projected out here once.
    """

    def __init__(self, op, pv, segments, integrating, orders, min_delay, max_delay,
                 exclude=()):
        na, nb = int(orders[0]), int(orders[1])
        lead = max(na, int(max_delay) + nb - 1)
        kept = [(a, b) for a, b in segments if b - a > lead + 10]
        super().__init__(op, pv, np.array([a for a, _ in kept], dtype=np.int64),
                         np.array([b for _, b in kept], dtype=np.int64))
        self.op, self.pv = self.u, self.y
        self.integrating = bool(integrating)
        self.na, self.nb = na, nb
        self.dlo, self.dhi = int(min_delay), int(max_delay)
        self.segments = kept
        self.rescored = 0           # grid cells scored again by least squares (grid)
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
        if self.n:
            self._project()

    def target_and_lags(self) -> tuple:
        """Return PV and the regressors that do not depend on (S, J), on the regression rows."""
        cols = [self.pv[self.rows - i] for i in range(1, self.na + 1)]
        if self.integrating:
            # The running sum of an MV_hat offset is a ramp in each segment.
            cols += [np.where(self.row_seg == s, self.rows.astype(np.float64), 0.0)
                     for s in range(len(self.segments))]
        return self.pv[self.rows], np.column_stack(cols)

    def demean(self, x) -> np.ndarray:
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

    def grid(self, s_values, j_values, start, dlo=None, dhi=None) -> tuple:
        """
        Return (SSE, best dead time) arrays over the grid ``s_values`` x ``j_values``.

        ``start`` holds the valve's start state, (direction, fraction) per
        segment (see :func:`segment_path`); dead times ``dlo`` to ``dhi``.
        A cell whose SSE the kernel may have wrong by more than ``DOUBT`` of
        the target's sum of squares (a valve path that the plant's own lags
        nearly repeat, so that the projection cancels most of its digits) is
        scored again by plain least squares, at every dead time.
        """
        dlo = self.dlo if dlo is None else max(self.dlo, dlo)
        dhi = self.dhi if dhi is None else min(self.dhi, dhi)
        s = np.ascontiguousarray(s_values, dtype=np.float64)
        j = np.ascontiguousarray(j_values, dtype=np.float64)
        self.evaluations += s.size * j.size
        sse, delay, doubt = _grid_sse(
            self.op, self.ubar, self.integrating, np.array([d for d, _ in start], dtype=np.int64),
            np.array([f for _, f in start], dtype=np.float64), self.starts, self.stops,
            self.rows, self.row_seg, self.seg_rows, self.qy, self.tres, self.tt, s, j, dlo, dhi,
            self.nb)
        for a, b in zip(*np.nonzero(doubt > DOUBT * self.tt)):
            self.rescored += 1
            fits = self.fits(s[a], j[b], range(dlo, dhi + 1), start)
            sse[a, b], delay[a, b] = min((float(r @ r), d) for d, (_, r) in
                                         zip(range(dlo, dhi + 1), fits))
        return sse, delay

    def at_rest(self) -> tuple:
        """Return the default start state: every segment at rest with no direction."""
        return ((0, 0.5),) * len(self.segments)

    def mv_hat(self, S, J, start) -> np.ndarray:
        """Return Kano's MV_hat over the record, NaN outside the segments."""
        v = np.full(len(self.op), np.nan)
        for (a, b), (d, f) in zip(self.segments, start):
            v[a:b] = segment_path(self.op[a:b], float(S), float(J), int(d), float(f))
        return v

    def fit(self, S, J, delay, start) -> tuple:
        """Return (coefficients dict, residuals) of the ARX model at (S, J, dead time)."""
        return self.fits(S, J, [delay], start)[0]

    def fits(self, S, J, delays, start) -> list:
        """Return :meth:`fit` for each dead time of ``delays``, the valve's path made once."""
        v = self.mv_hat(S, J, start) - self.ubar
        if self.integrating:
            for a, b in self.segments:
                v[a:b] = np.cumsum(v[a:b])
        t, fixed = self.target_and_lags()
        ind = (self.row_seg[:, None] == np.arange(len(self.segments))).astype(np.float64)
        nf = fixed.shape[1]
        out = []
        for delay in delays:
            vlags = np.column_stack([v[self.rows - delay - i] for i in range(self.nb)])
            x = np.hstack([fixed, vlags, ind])
            coef, *_ = np.linalg.lstsq(x, t, rcond=None)
            out.append(({'a': coef[:self.na], 'b': coef[nf:nf + self.nb]}, t - x @ coef))
        return out
