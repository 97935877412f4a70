"""
The evidence and uncertainty of a Hammerstein fit: residual statistics and intervals.

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
"""

import math

import numpy as np

from stiction_ros.analysis.hammerstein.problem import HammersteinProblem, MIN_ROWS
from stiction_ros.analysis.hammerstein.search import FINAL_KEEP, Search

JACKKNIFE_BLOCKS = 4


def effective_samples(e: np.ndarray, max_lag: int | None = None) -> float:
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


def jackknife(problem: HammersteinProblem, s_max: float, resolution: float,
              finalists: list) -> tuple[float, float] | None:
    """
    Return the delete-a-block jackknife standard errors (se_S, se_J), or None.

    The regression rows are cut into ``JACKKNIFE_BLOCKS`` consecutive blocks;
    without the rows of each (the valve is still simulated through them, so
    its state stays right), the search is refined again from the full
    record's finalists, as most of the data put the valleys in the same
    places.  The spread of the estimates shows what the likelihood-ratio
    region cannot: a model that is only approximately right (valve, plant,
    sampling), whose optimum moves from one part of the record to another.
    """
    cuts = problem.rows[np.linspace(0, problem.n - 1, JACKKNIFE_BLOCKS + 1).astype(int)]
    cuts[-1] += 1
    est = []
    for lo, hi in zip(cuts[:-1], cuts[1:]):
        sub = HammersteinProblem(problem.op, problem.pv, problem.segments,
                                 problem.integrating, (problem.na, problem.nb), problem.dlo,
                                 problem.dhi, problem.exclude + [(lo, hi)])
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


def linear_model_json(coefs: dict, delay: int, problem: HammersteinProblem,
                      sample_time: float) -> dict:
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
