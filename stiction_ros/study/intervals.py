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

Both use a fixed seed, so a rerun prints the same interval.
"""

import numpy as np

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
        NaN when a class has no record.

    """
    n_pos, n_neg = c['tp'] + c['fn'], c['tn'] + c['fp']
    if n_pos == 0 or n_neg == 0:
        return float('nan'), float('nan')
    rng = np.random.default_rng(seed)
    sens = rng.binomial(n_pos, c['tp'] / n_pos, draws) / n_pos
    spec = rng.binomial(n_neg, c['tn'] / n_neg, draws) / n_neg
    return _percentiles(0.5 * (sens + spec), level)


def tag_interval(labels, called, groups, draws: int = DRAWS, seed: int = SEED,
                 level: float = LEVEL) -> tuple[float, float]:
    """
    Return the ``level`` percentile interval of the balanced accuracy, resampling tags.

    Parameters
    ----------
    labels, called : sequences of bool
        Per record: sticky or not, and called stiction or not (a refusal is
        not a call).
    groups : sequence of str
        Per record: its valve tag.  Tags are drawn with replacement, each
        bringing all its records; a draw without a record of either class
        is drawn again (it has no balanced accuracy).
    draws, seed, level
        As in :func:`class_interval`.

    Returns
    -------
    (low, high) : tuple of float
        NaN when the records hold only one class.

    """
    y = np.asarray(labels, dtype=bool)
    hit = np.asarray(called, dtype=bool) == y
    tags, index = np.unique(np.asarray(groups), return_inverse=True)
    if not (y.any() and (~y).any()):
        return float('nan'), float('nan')
    # Per tag: sticky records, sticky hits, healthy records, healthy hits.
    per = np.zeros((len(tags), 4))
    np.add.at(per, index, np.column_stack([y, y & hit, ~y, ~y & hit]).astype(float))
    rng = np.random.default_rng(seed)
    out = np.empty(draws)
    k = 0
    while k < draws:
        tot = rng.multinomial(len(tags), np.full(len(tags), 1.0 / len(tags))) @ per
        if tot[0] > 0 and tot[2] > 0:
            out[k] = 0.5 * (tot[1] / tot[0] + tot[3] / tot[2])
            k += 1
    return _percentiles(out, level)


def _percentiles(values: np.ndarray, level: float) -> tuple[float, float]:
    tail = 100.0 * (1.0 - level) / 2.0
    lo, hi = np.percentile(values, [tail, 100.0 - tail])
    return float(lo), float(hi)
