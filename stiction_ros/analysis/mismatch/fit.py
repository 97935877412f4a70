"""
Fitting one candidate effect: its parameters together with S and J.

The landscape in (S, J) is piecewise constant and rugged, and an effect moves
the best (S, J) (a dwell term takes static friction out of S, an actuator lag
delays every breakaway).  So for each grid value of the effect's parameters
the fit searches S in a window around the plain fit and J over its whole
range (one coarse grid and one refinement), keeps the best few effect
values, refines (S, J) there to the 0.001 % grid and then bisects the effect
parameter between its neighbours.  A fit that stops in the wrong basin would
look like missing physics, so every stage keeps several candidates, and the
plain model (effect at zero) is always among them: an extended fit is never
worse than the plain one.
"""

from dataclasses import dataclass, field
import math

import numpy as np

from stiction_ros.analysis import fit_core
from stiction_ros.analysis.mismatch.stats import curvature_errors
from stiction_ros.kernels import kano_effects as kk

# Finer than identify's default 0.01 %: on a noisy record a plain fit rounded to
# 0.01 % moved enough breakaways by a sample to triple its MSE (0.010 -> 0.033),
# which left a structured residual that looked like missing physics.
RESOLUTION = 0.001
# Points across the S window of the coarse (S, J) grid tried with each effect value;
# the J axis covers all of [0, S0 + half the S window] at the same step.  An effect can
# move the best J far from the plain fit's (0.07 -> 1.88 for one Stribeck valve, 0.44
# -> 2.35 for a drifting one), out of any window around it, and its basin is a few
# hundredths wide.  On the 65 cases of make bench-explain: J window +-0.35 S with 13
# points named 49 of 55 effects; all of J with 13 points 52, with 17 points 53.
COARSE_POINTS = 17


@dataclass
class CandidateFit:
    """The best parameters of one effect on the fitted part."""

    effect: str
    params: dict
    S: float
    J: float
    sse: float
    n: int
    vector: np.ndarray = field(repr=False)
    evaluations: int = 0

    @property
    def mse(self):
        """Mean squared error on the fitted part."""
        return self.sse / self.n


START_SAMPLES = 10


def start_positions(y, starts, stops):
    """
    Return the resting position each segment starts from.

    A valve at rest holds still, so the median of the first few measured
    samples is a better start than the first one alone, whose noise the
    model would otherwise carry until the first breakaway.
    """
    return np.array([float(np.median(y[a:min(b, a + START_SAMPLES)]))
                     for a, b in zip(starts, stops)])


class EffectsProblem(fit_core.Problem):
    """OP (``u``) and measured MV (``y``) over the fitted segments, for the effects kernel."""

    def __init__(self, op, mv, starts, stops):
        super().__init__(op, mv, starts, stops)
        self.y0s = start_positions(self.y, self.starts, self.stops)

    def grid(self, s_values, j_values, p, limit=math.inf, keep=1):
        """Return the SSE grid over (S, J) with effect ``p``, exact for the ``keep`` best."""
        self.evaluations += len(s_values) * len(j_values)
        return kk.kano_effects_grid(self.u, self.y, self.starts, self.stops, self.y0s,
                                    np.asarray(s_values, dtype=np.float64),
                                    np.asarray(j_values, dtype=np.float64), p, limit, keep)

    def sse(self, S, J, p):
        """Return the SSE of one parameter set."""
        self.evaluations += 1
        return float(kk.kano_effects_sse(self.u, self.y, self.starts, self.stops, self.y0s,
                                         S, J, p, math.inf))


def _axis(centre, half, step):
    # Symmetric about the centre (itself on the grid), so the starting point is always
    # scored: with an effect on, the best S and J are often the plain fit's own.
    c = round(centre / RESOLUTION) * RESOLUTION
    k = max(1, int(round(half / step)))
    vals = np.unique(np.round((c + step * np.arange(-k, k + 1)) / RESOLUTION) * RESOLUTION)
    return vals[vals >= 0.0]


def local_sj(problem, p, S0, J0, half_s, half_j, points=9, keep=3, levels=math.inf,
             limit=math.inf, j_max=None):
    """
    Return (sse, S, J): a coarse-to-fine search of (S, J) in a window around (S0, J0).

    ``levels`` caps the refinements after the coarse grid (each a quarter of the
    step, down to RESOLUTION).  Evaluations stop once past ``limit`` (nothing worse
    than it matters; if nothing on the coarse grid beats it, no refinement is
    tried).  With ``j_max`` the J axis runs over all of [0, j_max] at the S axis's
    step.
    """
    step = max(2 * max(half_s, half_j) / (points - 1), RESOLUTION)
    s_ax = _axis(S0, half_s, step)
    if j_max is None:
        j_ax = _axis(J0, half_j, step)
    else:
        j_ax = _axis(J0, max(J0, j_max - J0), step)
        j_ax = j_ax[j_ax <= j_max + 0.5 * step]
    best = _best(problem.grid(s_ax, j_ax, p, limit, keep), s_ax, j_ax, keep)
    if best[0][0] > limit:
        return best[0]
    while step > RESOLUTION and levels > 0:
        levels -= 1
        fine = max(step / 4.0, RESOLUTION)
        found = {(round(s / RESOLUTION), round(j / RESOLUTION)): (e, s, j) for e, s, j in best}
        limit = best[-1][0]
        for _, s0, j0 in list(best):
            # Half a coarse step each way covers the cell; the kept neighbours cover the rest.
            s_ax, j_ax = _axis(s0, 0.5 * step, fine), _axis(j0, 0.5 * step, fine)
            for e, s, j in _best(problem.grid(s_ax, j_ax, p, limit, keep), s_ax, j_ax, keep):
                found.setdefault((round(s / RESOLUTION), round(j / RESOLUTION)), (e, s, j))
        best = sorted(found.values())[:keep]
        step = fine
    return best[0]


def _best(scores, s_ax, j_ax, keep):
    flat = np.argsort(scores, axis=None)[:keep]
    ii, jj = np.unravel_index(flat, scores.shape)
    return [(float(scores[i, j]), float(s_ax[i]), float(j_ax[j])) for i, j in zip(ii, jj)]


def fit_effect(problem, effect, ctx, S0, J0, plain_sse, keep=3):
    """Return the :class:`CandidateFit` of ``effect`` (never worse than the plain fit)."""
    half_s = half_j = _half_window(S0)
    thetas = effect.grid(ctx)
    coarse = []
    for theta in thetas:
        p = effect.vector(theta, ctx)
        # Only the best few effect values go on, and only if they beat the plain fit,
        # so nothing is summed past the worse of the two.  One refinement level ranks
        # the values by their basins rather than by where the coarse grid happens to fall.
        bound = min(plain_sse, sorted(c[0] for c in coarse)[keep - 1]
                    if len(coarse) >= keep else math.inf)
        sse, s, j = local_sj(problem, p, S0, J0, half_s, half_j, points=COARSE_POINTS,
                             levels=1, limit=bound, j_max=S0 + half_s)
        coarse.append((sse, theta, s, j))
    coarse.sort(key=lambda x: x[0])
    results = []
    for sse, theta, s, j in coarse[:keep]:
        p = effect.vector(theta, ctx)
        results.append((*local_sj(problem, p, s, j, half_s / 4, half_j / 4,
                                  limit=plain_sse), theta))
    best = min(results, key=lambda x: x[0])
    for dim in range(len(effect.names)):
        best = _bisect(problem, effect, ctx, best, dim, sorted({t[dim] for t in thetas}))
    sse, S, J, theta = best
    if sse >= plain_sse:
        theta = tuple(0.0 for _ in effect.names)
        sse, S, J = plain_sse, S0, J0
        vector = kk.plain_params()
    else:
        vector = effect.vector(theta, ctx)
    return CandidateFit(effect.eid, dict(zip(effect.names, (float(v) for v in theta))),
                        float(S), float(J), float(sse), problem.n, vector,
                        problem.evaluations)


def _half_window(S0):
    # The (S, J) window every fit searches around the plain fit: S and J within a third
    # of S (0.3 % at least); the coarse grid's J runs from 0 to the window's top.
    return max(0.35 * S0, 0.3)


def plain_in_window(problem, S0, J0, plain_sse):
    """
    Return (sse, S, J): the plain model's best over the window the effects search.

    The plain fit is a global grid search, and on a slowly moving OP its
    coarse grid can miss a basin a few hundredths wide (S 2.81, J 0.84 with
    10 times the SSE of S 3, J 1).  An effect searched over this window would
    then find that basin with itself at almost nothing and be named for the
    plain fit's miss, so the plain model gets the same search first.
    """
    half_s = half_j = _half_window(S0)
    p = kk.plain_params()
    sse, s, j = local_sj(problem, p, S0, J0, half_s, half_j, points=COARSE_POINTS, levels=1,
                         limit=plain_sse, j_max=S0 + half_s)
    if sse < plain_sse:
        sse, s, j = local_sj(problem, p, s, j, half_s / 4, half_j / 4, limit=sse)
    return (sse, s, j) if sse < plain_sse else (plain_sse, S0, J0)


def plain_at_fits(problem, fits, S0, J0, plain_sse):
    """
    Return (sse, S, J): the plain model's best near any candidate's (S, J), or the plain fit.

    An effect whose fit lands where the plain model fits as well or better
    explains nothing the plain model could not: its likelihood ratio must
    be taken against the plain model at its best.
    """
    best = (plain_sse, S0, J0)
    p = kk.plain_params()
    for f in fits:
        if (f.S, f.J) == (S0, J0):
            continue
        found = local_sj(problem, p, f.S, f.J, 0.1, 0.1, points=5, keep=2, limit=best[0])
        if found[0] < best[0]:
            best = found
    return best


def as_plain(fit, S, J, sse):
    """Return ``fit`` set back to the plain model at (S, J) when it is no better than that."""
    if fit.sse < sse:
        return fit
    return CandidateFit(fit.effect, dict.fromkeys(fit.params, 0.0), float(S), float(J),
                        float(sse), fit.n, kk.plain_params(), fit.evaluations)


def effect_errors(problem, effect, ctx, fit, rho=0.0) -> dict:
    """
    Return the standard error of each fitted effect parameter from the SSE's curvature.

    The effect's parameters are varied together (``stats.curvature_errors``);
    S and J are held.  The noise variance is inflated by (1 + rho) / (1 - rho)
    for a residual of lag-1 autocorrelation ``rho``.
    """
    sigma2 = fit.sse / fit.n * (1.0 + rho) / max(1.0 - rho, 0.05)
    theta = [fit.params[k] for k in effect.names]

    def sse(t):
        return problem.sse(fit.S, fit.J, effect.vector(tuple(float(x) for x in t), ctx))

    steps = [max(1e-3, 0.05 * abs(v)) for v in theta]
    return dict(zip(effect.names, curvature_errors(sse, theta, steps, sigma2)))


def _bisect(problem, effect, ctx, best, dim, axis, rounds=3):
    # Halve the distance to the better grid neighbour of parameter ``dim`` a few times.
    sse, S, J, theta = best
    v = theta[dim]
    i = int(np.argmin(np.abs(np.asarray(axis) - v)))
    lo = axis[i - 1] if i > 0 else v
    hi = axis[i + 1] if i + 1 < len(axis) else v
    for _ in range(rounds):
        tries = []
        for cand in (0.5 * (lo + v), 0.5 * (v + hi)):
            if cand == v:
                continue
            t = theta[:dim] + (cand,) + theta[dim + 1:]
            e, s, j = local_sj(problem, effect.vector(t, ctx), S, J, 0.1, 0.1, points=5,
                               keep=2, limit=sse)
            tries.append((e, s, j, t))
        for e, s, j, t in tries:
            if e < sse:
                sse, S, J, theta = e, s, j, t
        v = theta[dim]
        lo, hi = 0.5 * (lo + v), 0.5 * (v + hi)
    return sse, S, J, theta
