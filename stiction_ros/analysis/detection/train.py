"""
Train the learned detector on simulated loops and export it as plain arrays.

Only ``make detector`` and the tests import this module: it needs
scikit-learn, which the analyzer itself does not.  The classifier is a
histogram gradient-boosting model (shallow trees on the engineered features
of :mod:`features`, missing values native); its raw score is calibrated to a
probability by isotonic regression on simulated records it was not trained
on.  Real plant loops never enter training or calibration.
"""

import numpy as np

from stiction_ros.analysis.detection.model_file import TreeModel

# Classes weighted equally: the probability is stated for even odds, and 0.5
# is then the threshold of the best balanced accuracy whatever the share of
# sticky records a set happens to hold.
PARAMS = {'max_iter': 300, 'learning_rate': 0.05, 'max_leaf_nodes': 15, 'min_samples_leaf': 40,
          'l2_regularization': 1.0, 'class_weight': 'balanced', 'random_state': 0}


def fit_classifier(x: np.ndarray, y: np.ndarray, **params):
    """Return a fitted ``HistGradientBoostingClassifier`` (``PARAMS`` unless overridden)."""
    from sklearn.ensemble import HistGradientBoostingClassifier
    return HistGradientBoostingClassifier(**{**PARAMS, **params}).fit(x, y)


def fit_calibration(raw: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """
    Return the isotonic map (score knots, probabilities) fitted on held-out scores.

    Each class carries half the weight, so the probability is that of
    stiction at even prior odds.  Each step of the map is then the Jeffreys
    estimate of its records (half a record of each class added), so that no
    step reads 0 or 1: a step of 350 healthy records and no sticky one says
    about 0.002, not certainty, since a thousand records cannot support more.
    """
    from sklearn.isotonic import IsotonicRegression
    y = np.asarray(y, dtype=bool)
    w_pos, w_neg = 0.5 / max(y.sum(), 1), 0.5 / max((~y).sum(), 1)
    w = np.where(y, w_pos, w_neg)
    iso = IsotonicRegression(out_of_bounds='clip', y_min=0.0, y_max=1.0)
    iso.fit(raw, y, sample_weight=w)
    cx, cy = np.asarray(iso.X_thresholds_, float), np.asarray(iso.y_thresholds_, float)
    cy = _jeffreys_steps(iso.predict(raw), y, cy, w_pos, w_neg)
    if cx.size < 2:
        cx, cy = np.array([cx[0] - 1.0, cx[0] + 1.0]), np.array([cy[0], cy[0]])
    return cx, cy


def _jeffreys_steps(fitted: np.ndarray, y: np.ndarray, knots_y: np.ndarray,
                    w_pos: float, w_neg: float) -> np.ndarray:
    """Return ``knots_y`` with each step's value replaced by its records' Jeffreys estimate."""
    from sklearn.isotonic import IsotonicRegression
    steps = np.unique(knots_y)
    pos = np.array([np.sum(y & (fitted == v)) for v in steps], dtype=float)
    neg = np.array([np.sum(~y & (fitted == v)) for v in steps], dtype=float)
    a, b = w_pos * (pos + 0.5), w_neg * (neg + 0.5)
    # Shrinking a small step more than a large one may break the order: pool again.
    smooth = IsotonicRegression().fit(np.arange(steps.size), a / (a + b), sample_weight=a + b)
    return np.interp(knots_y, steps, smooth.predict(np.arange(steps.size)))


def export(clf, feature_names, calib: tuple, meta: dict) -> TreeModel:
    """Return the :class:`TreeModel` of a fitted binary ``HistGradientBoostingClassifier``."""
    cols = {k: [] for k in ('feature', 'threshold', 'left', 'right', 'value',
                            'missing_left', 'is_leaf', 'count')}
    starts, offset = [], 0
    for per_iter in clf._predictors:
        nodes = per_iter[0].nodes
        if np.any(nodes['is_categorical']):
            raise ValueError('categorical splits are not supported by the exported model')
        starts.append(offset)
        cols['feature'].append(nodes['feature_idx'])
        cols['threshold'].append(nodes['num_threshold'])
        cols['left'].append(nodes['left'].astype(np.int64) + offset)
        cols['right'].append(nodes['right'].astype(np.int64) + offset)
        cols['value'].append(nodes['value'])
        cols['missing_left'].append(nodes['missing_go_to_left'])
        cols['is_leaf'].append(nodes['is_leaf'])
        cols['count'].append(nodes['count'])
        offset += len(nodes)
    arr = {k: np.concatenate(v) for k, v in cols.items()}
    leaf = arr['is_leaf'] == 1
    arr['left'][leaf] = 0
    arr['right'][leaf] = 0
    baseline = float(np.ravel(clf._baseline_prediction)[0])
    return TreeModel(tuple(feature_names), baseline, arr['feature'].astype(np.int32),
                     arr['threshold'].astype(np.float64), arr['left'].astype(np.int32),
                     arr['right'].astype(np.int32), arr['value'].astype(np.float64),
                     arr['missing_left'].astype(np.uint8), arr['is_leaf'].astype(np.uint8),
                     arr['count'].astype(np.int64), np.array(starts, dtype=np.int32),
                     calib[0], calib[1], meta)


def train(x_train: np.ndarray, y_train: np.ndarray, x_cal: np.ndarray, y_cal: np.ndarray,
          feature_names, meta: dict, **params) -> tuple:
    """Return ``(TreeModel, classifier)`` trained on one set and calibrated on the other."""
    clf = fit_classifier(x_train, y_train, **params)
    calib = fit_calibration(clf.decision_function(x_cal), y_cal)
    return export(clf, feature_names, calib, meta), clf


# The stack (stack.py): the trees' score out of fold, weighed with the large network.
FOLDS = 5


def out_of_fold_scores(x: np.ndarray, y: np.ndarray, params: dict) -> np.ndarray:
    """Return each training record's trees score from trees that did not see it."""
    from sklearn.model_selection import StratifiedKFold
    out = np.zeros(len(y))
    for a, b in StratifiedKFold(FOLDS, shuffle=True, random_state=0).split(x, y):
        out[b] = fit_classifier(x[a], y[a], **params).decision_function(x[b])
    return out


def fit_stack(tree_scores: np.ndarray, logits: np.ndarray, y: np.ndarray) -> list:
    """Return ``[intercept, trees weight, network weight]`` of the class-balanced logistic fit."""
    from sklearn.linear_model import LogisticRegression
    fit = LogisticRegression(class_weight='balanced').fit(np.c_[tree_scores, logits], y)
    return [float(fit.intercept_[0]), *map(float, fit.coef_[0])]
