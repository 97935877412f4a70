"""
A small 1-D convolutional network that reads the record itself: one more detector figure.

The engineered figures say what a stiction test looks for; the network
learns from a large simulated corpus (``make cnn``: 32 000 records of seeds
the detector's own training never uses) what else in the shape of OP and PV
tells a sticking valve.  Its logit is one figure among the others
(``cnn_logit``), so the boosted trees weigh it against the physics.

The network, in NumPy (its convolution a compiled loop, ``kernels/conv.py``) so the
analyzer needs no deep-learning library: five
input channels per sample (PV and SP on PV's scale, OP, and the changes of
PV and OP, each standardised over the record, so units and offsets drop
out), a 7-tap convolution to ``C`` channels, seven residual convolutions of 5
taps dilated 1 to 64 (a receptive field of about 500 samples: an hour's
stuck period at 10 s), the mean and the maximum of each channel over the
record, the loop type, and two dense layers.  Any record length works;
training cut random windows of 500 samples.  The logit given is the mean
over the loop's four sign conventions (:data:`SIGNS`), which the physics
says cannot matter and the network alone does not fully ignore.

The weights are plain arrays in ``resources/stiction_cnn.npz`` with a JSON
header and a SHA-256, loaded without pickle; a missing, damaged or edited
file is a :class:`DetectorFileError`.
"""

from dataclasses import dataclass
from functools import lru_cache
import json
from pathlib import Path
from typing import Callable

import numpy as np

from stiction_ros.analysis.detection.model_file import digest, read_arrays
from stiction_ros.errors import DetectorFileError
from stiction_ros.kernels.conv import conv1d_same

FORMAT = 'stiction_ros.cnn'
VERSION = 1
N_CHANNELS = 5
CLIP = 10.0
# A dilation pads the record by this many samples per tap: bounded so that a
# re-saved file with a huge one is refused rather than exhausting memory.
MAX_DILATION = 4096
# The longest stretch read at once, and how many stretches of a longer record.
WINDOW = 4096
WINDOWS = 4
DEFAULT_PATH = Path(__file__).resolve().parents[2] / 'resources' / 'stiction_cnn.npz'
ARRAYS = ('inp_w', 'inp_b', 'conv_w', 'conv_b', 'dilations', 'fc1_w', 'fc1_b', 'fc2_w', 'fc2_b')


def channels(op: np.ndarray, pv: np.ndarray, sp: np.ndarray | None) -> np.ndarray:
    """
    Return the network's input, shape (5, n): PV, SP, OP, dPV, dOP standardised.

    SP shares PV's offset and scale so a set-point step and the PV that
    follows it line up; each change is scaled by its own spread.  Clipped to
    +-10 so one spike cannot saturate the network.
    """
    op = np.asarray(op, dtype=np.float64)
    pv = np.asarray(pv, dtype=np.float64)
    sp = np.full(pv.shape, pv.mean()) if sp is None else np.broadcast_to(
        np.asarray(sp, dtype=np.float64), pv.shape)
    tiny = 1e-12
    m, s = pv.mean(), pv.std() + tiny
    dpv = np.diff(pv, prepend=pv[0])
    dop = np.diff(op, prepend=op[0])
    out = np.stack([(pv - m) / s, (sp - m) / s, (op - op.mean()) / (op.std() + tiny),
                    dpv / (dpv.std() + tiny), dop / (dop.std() + tiny)])
    return np.clip(out, -CLIP, CLIP).astype(np.float32)


def conv1d(x: np.ndarray, w: np.ndarray, b: np.ndarray, dilation: int) -> np.ndarray:
    """Return the same-length dilated convolution of ``x`` (C_in, n) by ``w`` (C_out, C_in, k)."""
    # A compiled loop, not BLAS: BLAS splits a product differently with each
    # thread count, and a figure must not change with the machine's load (a pool
    # worker runs one BLAS thread, the main process several).  It sums in
    # einsum's order, so the figures computed with einsum before it stand.
    if w.ndim != 3 or w.shape[2] % 2 == 0 or w.shape[1] != x.shape[0] or b.shape != w.shape[:1]:
        # The compiled loop trusts its shapes: an even kernel would read past the padding.
        raise ValueError(f'convolution of {x.shape} by {w.shape} with bias {b.shape}: '
                         'needs (C_in, n), (C_out, C_in, odd k) and (C_out,)')
    f8 = np.float64
    return conv1d_same(np.ascontiguousarray(x, dtype=f8), np.ascontiguousarray(w, dtype=f8),
                       np.ascontiguousarray(b, dtype=f8), int(dilation))


def conv1d_reference(x: np.ndarray, w: np.ndarray, b: np.ndarray, dilation: int) -> np.ndarray:
    """
    Return :func:`conv1d` computed with NumPy's einsum, one tap at a time.

    How the figures were computed before the compiled loop, which gives the
    same bits about 1.7 times as fast; tests and ``make bench-detector`` hold
    :func:`conv1d` to it.
    """
    k = w.shape[2]
    pad = dilation * (k - 1) // 2
    n = x.shape[1]
    xp = np.pad(x, ((0, 0), (pad, pad)))
    out = np.repeat(np.asarray(b, dtype=np.float64)[:, None], n, axis=1)
    for j in range(k):
        out += np.einsum('oi,it->ot', w[:, :, j], xp[:, j * dilation:j * dilation + n],
                         optimize=False)
    return out


Conv = Callable[[np.ndarray, np.ndarray, np.ndarray, int], np.ndarray]


@dataclass(frozen=True)
class CnnModel:
    """The network's weights (stored as float32, held as float64) and its file's metadata."""

    inp_w: np.ndarray
    inp_b: np.ndarray
    conv_w: np.ndarray
    conv_b: np.ndarray
    dilations: np.ndarray
    fc1_w: np.ndarray
    fc1_b: np.ndarray
    fc2_w: np.ndarray
    fc2_b: np.ndarray
    meta: dict
    sha256: str = ''

    def logit(self, x: np.ndarray, integrating: bool, conv: Conv = conv1d) -> float:
        """Return the log-odds of stiction for the input ``x`` from :func:`channels`."""
        x = np.asarray(x, dtype=np.float64)
        h = np.maximum(conv(x, self.inp_w, self.inp_b, 1), 0.0)
        for w, b, d in zip(self.conv_w, self.conv_b, self.dilations):
            h = h + conv(np.maximum(h, 0.0), w, b, int(d))
        pooled = np.concatenate([h.mean(axis=1), h.max(axis=1),
                                 np.array([float(integrating)])])
        z = np.maximum(np.einsum('oi,i->o', self.fc1_w, pooled, optimize=False) + self.fc1_b,
                       0.0)
        return float(np.einsum('oi,i->o', self.fc2_w, z, optimize=False)[0] + self.fc2_b[0])


def save(path: str | Path, arrays: dict, meta: dict) -> None:
    """Write the network ``arrays`` (:data:`ARRAYS`) and ``meta`` to ``path``."""
    a = {k: np.asarray(arrays[k], dtype=np.int32 if k == 'dilations' else np.float32)
         for k in ARRAYS}
    header = json.dumps({'format': FORMAT, 'version': VERSION, 'meta': meta}, sort_keys=True)
    with open(path, 'wb') as fh:
        np.savez_compressed(fh, **a, header=np.array(header), sha256=np.array(digest(a, header)))


def _check(a: dict, path: Path) -> None:
    c, cin, k0 = a['inp_w'].shape if a['inp_w'].ndim == 3 else (0, 0, 0)
    layers = a['dilations'].shape[0] if a['dilations'].ndim == 1 else -1
    hidden = a['fc1_b'].shape[0] if a['fc1_b'].ndim == 1 else -1
    want = {'inp_w': (c, N_CHANNELS, k0), 'inp_b': (c,), 'conv_b': (layers, c),
            'fc1_w': (hidden, 2 * c + 1), 'fc2_w': (1, hidden), 'fc2_b': (1,)}
    for k, shape in want.items():
        if a[k].shape != shape:
            raise DetectorFileError(f'{path}: array {k} has shape {a[k].shape}, expected {shape}')
    if a['conv_w'].ndim != 4 or a['conv_w'].shape[:3] != (layers, c, c) or c == 0:
        raise DetectorFileError(f'{path}: convolution weights of shape {a["conv_w"].shape}')
    if (k0 % 2 == 0 or a['conv_w'].shape[3] % 2 == 0 or np.any(a['dilations'] < 1)
            or np.any(a['dilations'] > MAX_DILATION) or hidden < 1 or layers < 1):
        raise DetectorFileError(f'{path}: kernels must be odd, dilations 1-{MAX_DILATION}, '
                                f'and there must be a layer and a hidden unit')
    if not all(np.all(np.isfinite(a[k])) for k in ARRAYS):
        raise DetectorFileError(f'{path}: NaN or infinity in the weights')


def load(path: str | Path | None = None, rebuild: str = '`make cnn`') -> CnnModel:
    """Return the network at ``path`` (default: the shipped one); bad files raise."""
    path = Path(path) if path is not None else DEFAULT_PATH
    a, header = read_arrays(path, (*ARRAYS, 'sha256'), 'CNN', rebuild)
    if (header.get('format') != FORMAT
            or header.get('version') != VERSION or not isinstance(header.get('meta'), dict)):
        raise DetectorFileError(f'{path}: not a {FORMAT} version {VERSION} file')
    for k in ARRAYS:
        want = np.int32 if k == 'dilations' else np.float32
        if a[k].dtype != want:
            raise DetectorFileError(f'{path}: array {k} is {a[k].dtype}, '
                                    f'expected {np.dtype(want)}')
    if digest({k: a[k] for k in ARRAYS}, str(a['header'])) != str(a['sha256']):
        raise DetectorFileError(f'{path}: checksum mismatch (the file was changed or damaged); '
                                f'rebuild it with {rebuild}')
    _check(a, path)
    # Float64 for the arithmetic (exact from float32): einsum on mixed types
    # casts on every call, six times slower.
    return CnnModel(*(a[k].astype(np.float64) if k != 'dilations' else a[k] for k in ARRAYS),
                    header['meta'], str(a['sha256']))


@lru_cache(maxsize=2)
def _shipped(path: str | None) -> CnnModel:
    return load(path)


# The four sign conventions of one loop, as factors of (PV and SP, OP): a
# transmitter ranged the other way round, an air-to-close valve, or both.  The
# valve's friction is the same in each, so the answer may not depend on them.
SIGNS = ((1.0, 1.0), (-1.0, 1.0), (1.0, -1.0), (-1.0, -1.0))


def symmetric_logit(net: CnnModel, x: np.ndarray, integrating: bool,
                    conv: Conv = conv1d) -> float:
    """
    Return the mean of ``net``'s logits over the four sign versions of the input ``x``.

    Negating a signal negates its standardised channel and its change exactly,
    so each version is what :func:`channels` gives for that loop.  Trained on
    loops of every sign, the network still reads each version a little
    differently (up to 2.5 in the logit on a plant record); the mean depends
    on none of them.
    """
    out = 0.0
    for pv_sign, op_sign in SIGNS:
        s = np.array([pv_sign, pv_sign, op_sign, pv_sign, op_sign], dtype=x.dtype)
        out += net.logit(x * s[:, None], integrating, conv)
    return out / len(SIGNS)


def cnn_logit(op: np.ndarray, pv: np.ndarray, sp: np.ndarray | None, integrating: bool,
              path: str | None = None) -> float:
    """
    Return the shipped network's log-odds of stiction for one contiguous record.

    The logit is the mean over the loop's four sign conventions
    (:func:`symmetric_logit`).  The four passes of the large network cost
    about 17 us a sample (28 us with einsum's convolution; ``make
    bench-detector``).  A record longer than ``WINDOW`` samples (no
    simulated record is) is read as at most ``WINDOWS`` evenly
    spaced windows of ``WINDOW`` samples, standardised over the whole
    record, and their logits averaged, so a day at 1 s costs what four
    windows do.
    """
    net, x = _shipped(path), channels(op, pv, sp)
    n = x.shape[1]
    if n <= WINDOW:
        return symmetric_logit(net, x, integrating)
    starts = np.unique(np.linspace(0, n - WINDOW, WINDOWS).astype(int))
    return float(np.mean([symmetric_logit(net, x[:, a:a + WINDOW], integrating)
                          for a in starts]))
