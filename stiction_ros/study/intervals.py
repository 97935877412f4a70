"""
How far a balanced accuracy could move on another draw of the same kind of data.

Two bootstraps, each for the data it reads:

* simulated records are independent draws, so each class is resampled on its
  own (:func:`class_interval`); from the confusion counts alone, since a
  class resampled with replacement is a binomial draw of its hit rate;
* plant records of one valve share a valve, a loop and an operator, so whole
  valve tags are resampled (:func:`tag_interval`); twelve records of one
  valve weigh as one valve, which is what the figure can claim about valves
  it has not seen.

Both use a fixed seed, so a rerun prints the same interval.  A bootstrap
cannot see beyond the data: a class scored perfectly shows no spread at all,
and three sticky valves give a handful of possible values.  For a share
with no miss, :func:`exact_interval` (Clopper-Pearson) says what it can.
"""

from typing import Sequence

import numpy as np
from scipy.stats import beta

DRAWS = 2000
SEED = 0
LEVEL = 0.95


def class_interval(c: dict, draws: int = DRAWS, seed: int = SEED,
                   level: float = LEVEL) -> tuple[float, float]:
    """
    Return the ``level`` percentile interval of the balanced accuracy of confusion ``c``.

    Parameters
    ----------
    c : dict
        ``tp``, ``fn``, ``fp``, ``tn`` as :func:`stiction_ros.study.accuracy.confusion`
        gives them (a refusal already counted where the row counts it).
    draws, seed, level
        Bootstrap draws, the generator's seed, and the interval's coverage.

    Returns
    -------
    (low, high) : tuple of float
        NaN when a class has no record; (1, 1) for a perfect score, which
        resampling cannot put in doubt (see :func:`exact_interval`).

    """
    n_pos, n_neg = c['tp'] + c['fn'], c['tn'] + c['fp']
    if n_pos == 0 or n_neg == 0:
        return float('nan'), float('nan')
    rng = np.random.default_rng(seed)
    sens = rng.binomial(n_pos, c['tp'] / n_pos, draws) / n_pos
    spec = rng.binomial(n_neg, c['tn'] / n_neg, draws) / n_neg
    return percentile_interval(0.5 * (sens + spec), level)


def tag_interval(labels: Sequence[bool], called: Sequence[bool], groups: Sequence[str],
                 draws: int = DRAWS, seed: int = SEED,
                 level: float = LEVEL) -> tuple[float, float]:
    """
    Return the ``level`` percentile interval of the balanced accuracy, resampling tags.

    Parameters
    ----------
    labels, called : sequences of bool
        Per record: sticky or not, and called stiction or not (a refusal is
        not a call).
    groups : sequence of str
        Per record: its valve tag.
    draws, seed, level
        As in :func:`class_interval`.

    Returns
    -------
    (low, high) : tuple of float
        NaN when the records hold only one class.

    """
    values = tag_draws(labels, called, groups, draws, seed)
    if values.size == 0:
        return float('nan'), float('nan')
    return percentile_interval(values, level)


def tag_draws(labels: Sequence[bool], called: Sequence[bool], groups: Sequence[str],
              draws: int = DRAWS, seed: int = SEED) -> np.ndarray:
    """
    Return the balanced accuracy of ``draws`` resamplings of whole tags.

    Tags are drawn with replacement, each bringing all its records; a draw
    without a record of either class has no balanced accuracy and is drawn
    again.  Empty when the records hold only one class.
    """
    y = np.asarray(labels, dtype=bool)
    hit = np.asarray(called, dtype=bool) == y
    tags, index = np.unique(np.asarray(groups), return_inverse=True)
    if len(y) != len(hit) or len(y) != len(index):
        raise ValueError('labels, called and groups must have one entry per record')
    if draws < 1:
        raise ValueError('draws must be at least 1')
    if not (y.any() and (~y).any()):
        return np.empty(0)
    # Per tag: sticky records, sticky hits, healthy records, healthy hits.
    per = np.zeros((len(tags), 4))
    np.add.at(per, index, np.column_stack([y, y & hit, ~y, ~y & hit]).astype(float))
    rng = np.random.default_rng(seed)
    out = np.empty(draws)
    k = 0
    # Ends: both classes are present, so every draw holding all tags is valid.
    while k < draws:
        tot = rng.multinomial(len(tags), np.full(len(tags), 1.0 / len(tags))) @ per
        if tot[0] > 0 and tot[2] > 0:
            out[k] = 0.5 * (tot[1] / tot[0] + tot[3] / tot[2])
            k += 1
    return out


def exact_interval(k: int, n: int, level: float = LEVEL) -> tuple[float, float]:
    """Return the Clopper-Pearson ``level`` interval of a share of ``k`` in ``n``."""
    if n < 1 or not 0 <= k <= n:
        raise ValueError(f'need 0 <= k <= n and n >= 1, got k={k}, n={n}')
    tail = (1.0 - level) / 2.0
    lo = 0.0 if k == 0 else float(beta.ppf(tail, k, n - k + 1))
    hi = 1.0 if k == n else float(beta.ppf(1.0 - tail, k + 1, n - k))
    return lo, hi


def percentile_interval(values: np.ndarray, level: float = LEVEL) -> tuple[float, float]:
    """Return the central ``level`` percentile interval of bootstrap ``values``."""
    tail = 100.0 * (1.0 - level) / 2.0
    lo, hi = np.percentile(values, [tail, 100.0 - tail])
    return float(lo), float(hi)
