"""
The learned detector's file: gradient-boosted trees and their calibration, without pickle.

The classifier is trained with scikit-learn (``stiction_ros.analysis.detection.train``)
but shipped as plain arrays in a NumPy ``.npz``: each tree's split feature,
threshold, children, leaf value, where a missing value goes and how many
training records reached each node (for :meth:`TreeModel.contributions`), plus
the isotonic calibration map from raw score to probability.  Loading never
unpickles anything (the security test bans it) and needs no scikit-learn;
:func:`load` checks every array's type, shape and cross-reference and a
SHA-256 of the content, so a missing, truncated or edited file is a
:class:`DetectorFileError` naming what is wrong, never a wrong answer.
"""

from dataclasses import dataclass
from functools import cached_property
import hashlib
import json
from pathlib import Path
import zipfile
import zlib

import numpy as np

from stiction_ros.errors import DetectorFileError

FORMAT = 'stiction_ros.detector'
# Version 2 (2026-11-27) added each node's training count.
VERSION = 2
ARRAYS = {'feature': np.int32, 'threshold': np.float64, 'left': np.int32, 'right': np.int32,
          'value': np.float64, 'missing_left': np.uint8, 'is_leaf': np.uint8,
          'count': np.int64, 'tree_start': np.int32, 'calib_x': np.float64, 'calib_y': np.float64}
DEFAULT_PATH = Path(__file__).resolve().parents[2] / 'resources' / 'stiction_detector.npz'


@dataclass(frozen=True)
class TreeModel:
    """A boosted-tree classifier as arrays: raw score = baseline + sum of leaf values."""

    feature_names: tuple
    baseline: float
    feature: np.ndarray
    threshold: np.ndarray
    left: np.ndarray
    right: np.ndarray
    value: np.ndarray
    missing_left: np.ndarray
    is_leaf: np.ndarray
    count: np.ndarray
    tree_start: np.ndarray
    calib_x: np.ndarray
    calib_y: np.ndarray
    meta: dict

    def raw_score(self, x: np.ndarray) -> np.ndarray:
        """Return the raw (log-odds) score of each row of ``x``."""
        x = np.atleast_2d(np.asarray(x, dtype=np.float64))
        if x.shape[1] != len(self.feature_names):
            raise ValueError(f'{x.shape[1]} features given, the model takes '
                             f'{len(self.feature_names)}')
        rows = np.arange(x.shape[0])
        total = np.full(x.shape[0], self.baseline)
        for root in self.tree_start:
            node = np.full(x.shape[0], root, dtype=np.int64)
            while True:
                inner = self.is_leaf[node] == 0
                if not inner.any():
                    break
                nd = node[inner]
                xv = x[rows[inner], self.feature[nd]]
                go_left = np.where(np.isnan(xv), self.missing_left[nd] == 1,
                                   xv <= self.threshold[nd])
                node[inner] = np.where(go_left, self.left[nd], self.right[nd])
            total += self.value[node]
        return total

    @cached_property
    def expected(self) -> np.ndarray:
        """Return each node's mean leaf value over the training records that reached it."""
        e = np.where(self.is_leaf == 1, self.value, 0.0)
        # Children lie after their parent (checked on load): fill from the end.
        for i in np.flatnonzero(self.is_leaf == 0)[::-1]:
            cl, cr = self.count[self.left[i]], self.count[self.right[i]]
            e[i] = (cl * e[self.left[i]] + cr * e[self.right[i]]) / (cl + cr)
        return e

    def contributions(self, x: np.ndarray) -> tuple[float, np.ndarray]:
        """
        Return ``(bias, per_feature)`` of one row: how the raw score was reached.

        Each split on a row's path moves the expected score from the node's
        mean to the child's; the move is credited to the split's feature
        (Saabas 2014).  ``bias + per_feature.sum()`` is :meth:`raw_score` of
        the row, to rounding.
        """
        x = np.asarray(x, dtype=np.float64).ravel()
        if x.size != len(self.feature_names):
            raise ValueError(f'{x.size} features given, the model takes '
                             f'{len(self.feature_names)}')
        e, out = self.expected, np.zeros(x.size)
        node = self.tree_start.astype(np.int64)
        bias = self.baseline + float(e[node].sum())
        while True:
            inner = self.is_leaf[node] == 0
            if not inner.any():
                break
            nd = node[inner]
            xv = x[self.feature[nd]]
            go_left = np.where(np.isnan(xv), self.missing_left[nd] == 1,
                               xv <= self.threshold[nd])
            child = np.where(go_left, self.left[nd], self.right[nd])
            np.add.at(out, self.feature[nd], e[child] - e[nd])
            node[inner] = child
        return bias, out

    @property
    def stack(self) -> list | None:
        """Return ``[intercept, trees weight, large network weight]``, or None for trees alone."""
        stack = self.meta.get('stack')
        return None if stack is None else [float(c) for c in stack['coef']]

    def score(self, x: np.ndarray, large_logit: np.ndarray | None = None) -> np.ndarray:
        """
        Return the score the calibration map reads, for each row of ``x``.

        The trees' raw score, or with a stack (``stiction_ros.analysis.detection.stack``)
        its weighed sum with the large network's logit of each row.
        """
        raw, w = self.raw_score(x), self.stack
        if w is None:
            return raw
        if large_logit is None:
            raise ValueError('this detector weighs the large network in: give its logit')
        return w[0] + w[1] * raw + w[2] * np.asarray(large_logit, dtype=np.float64)

    def probability(self, x: np.ndarray, large_logit: np.ndarray | None = None) -> np.ndarray:
        """Return the calibrated probability of stiction of each row of ``x``."""
        return np.interp(self.score(x, large_logit), self.calib_x, self.calib_y)


def digest(arrays: dict, header: str) -> str:
    """Return the SHA-256 of ``arrays`` (by name) and the JSON ``header``."""
    h = hashlib.sha256(header.encode())
    for name in sorted(arrays):
        h.update(name.encode())
        h.update(np.ascontiguousarray(arrays[name]).tobytes())
    return h.hexdigest()


def save(path: str | Path, model: TreeModel) -> None:
    """Write ``model`` to ``path`` (an ``.npz`` of plain arrays and a JSON header)."""
    arrays = {k: np.asarray(getattr(model, k), dtype=t) for k, t in ARRAYS.items()}
    header = json.dumps({'format': FORMAT, 'version': VERSION,
                         'feature_names': list(model.feature_names),
                         'baseline': model.baseline, 'meta': model.meta}, sort_keys=True)
    arrays['header'] = np.array(header)
    arrays['sha256'] = np.array(digest({k: arrays[k] for k in ARRAYS}, header))
    with open(path, 'wb') as fh:
        np.savez_compressed(fh, **arrays)


def _check(a: dict, header: dict, path: Path) -> None:
    n = a['feature'].shape[0]
    for k in ('threshold', 'left', 'right', 'value', 'missing_left', 'is_leaf', 'count'):
        if a[k].shape != (n,):
            raise DetectorFileError(f'{path}: array {k} has shape {a[k].shape}, expected ({n},)')
    inner = a['is_leaf'] == 0
    nf = len(header['feature_names'])
    starts = a['tree_start']
    if (starts.size == 0 or starts[0] != 0 or np.any(np.diff(starts) <= 0)
            or starts[-1] >= n or np.any(a['feature'][inner] < 0)
            or np.any(a['feature'][inner] >= nf)):
        raise DetectorFileError(f'{path}: tree arrays point outside the model')
    # Every child lies after its parent and inside its own tree, so a walk
    # from a root always ends at a leaf (no cycle, no jump into another tree).
    idx = np.arange(n)
    end = np.append(starts[1:], n)[np.searchsorted(starts, idx, side='right') - 1]
    for child in (a['left'], a['right']):
        if np.any((child[inner] <= idx[inner]) | (child[inner] >= end[inner])):
            raise DetectorFileError(f'{path}: a tree node points back or outside its tree')
    if np.any(a['count'] < 1):
        raise DetectorFileError(f'{path}: a tree node reached by no training record')
    if not all(np.all(np.isfinite(a[k])) for k in ('value', 'calib_x', 'calib_y')):
        raise DetectorFileError(f'{path}: NaN or infinity in leaf values or calibration')
    cx, cy = a['calib_x'], a['calib_y']
    if (cx.ndim != 1 or cx.shape != cy.shape or cx.size < 2 or np.any(np.diff(cx) < 0)
            or np.any((cy < 0) | (cy > 1))):
        raise DetectorFileError(f'{path}: the calibration map is not a monotone [0, 1] map')


def read_arrays(path: Path, names: tuple, what: str, rebuild: str) -> tuple[dict, dict]:
    """
    Return the arrays of the ``.npz`` at ``path`` and its parsed JSON ``header``.

    Refuses pickles, missing ``names`` and a header that is not a JSON
    object.  ``what`` names the file in the error; ``rebuild`` says how to
    make it again.
    """
    if not path.is_file():
        raise DetectorFileError(f'{path}: no {what} model file; rebuild it with {rebuild}')
    try:
        with np.load(path, allow_pickle=False) as z:
            a = {k: z[k] for k in z.files}
    except (OSError, ValueError, EOFError, TypeError, AttributeError, zipfile.BadZipFile,
            zlib.error) as exc:
        # TypeError/AttributeError: a plain .npy, which np.load returns as one array.
        raise DetectorFileError(f'{path}: not a readable {what} file ({exc}); rebuild it '
                                f'with {rebuild}') from None
    missing = [k for k in (*names, 'header') if k not in a]
    if missing:
        raise DetectorFileError(f'{path}: missing arrays {missing}')
    try:
        header = json.loads(str(a['header']))
    except (ValueError, RecursionError):
        header = None
    if not isinstance(header, dict):
        raise DetectorFileError(f'{path}: damaged header')
    return a, header


def load(path: str | Path | None = None, feature_names: tuple | None = None) -> TreeModel:
    """
    Return the :class:`TreeModel` stored at ``path`` (default: the shipped detector).

    ``feature_names``: the features the caller will give; a file trained on
    other features is refused.  Raises :class:`DetectorFileError`.
    """
    path = Path(path) if path is not None else DEFAULT_PATH
    a, header = read_arrays(path, (*ARRAYS, 'sha256'), 'detector', '`make detector`')
    if (not isinstance(header.get('feature_names'), list)
            or not isinstance(header.get('meta'), dict)
            or not isinstance(header.get('baseline'), (int, float))
            or not np.isfinite(header['baseline'])):
        raise DetectorFileError(f'{path}: the header lacks feature_names, baseline or meta')
    if header.get('format') != FORMAT or header.get('version') != VERSION:
        raise DetectorFileError(f'{path}: format {header.get("format")!r} version '
                                f'{header.get("version")!r}; this code reads {FORMAT} '
                                f'version {VERSION}')
    for k, t in ARRAYS.items():
        if a[k].dtype != t or a[k].ndim != 1:
            raise DetectorFileError(f'{path}: array {k} is {a[k].dtype}[{a[k].ndim}-D], '
                                    f'expected 1-D {np.dtype(t)}')
    if digest({k: a[k] for k in ARRAYS}, str(a['header'])) != str(a['sha256']):
        raise DetectorFileError(f'{path}: checksum mismatch (the file was changed or damaged)')
    _check(a, header, path)
    stack = header['meta'].get('stack')
    if stack is not None and not (
            isinstance(stack, dict) and isinstance(stack.get('coef'), list)
            and len(stack['coef']) == 3
            and all(isinstance(c, (int, float)) and np.isfinite(c) for c in stack['coef'])
            and isinstance(stack.get('network_sha256'), str)):
        raise DetectorFileError(f'{path}: the stack needs three finite weights and the '
                                f'SHA-256 of its network')
    names = tuple(header['feature_names'])
    if feature_names is not None and names != tuple(feature_names):
        raise DetectorFileError(f'{path}: trained on features {list(names)}, this code '
                                f'computes {list(feature_names)}; rebuild with `make detector`')
    return TreeModel(names, float(header['baseline']), *(a[k] for k in ARRAYS), header['meta'])
