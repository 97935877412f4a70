"""
The detector's last step: the trees' score and a large network's logit, weighed together.

The boosted trees read the engineered figures (and the small network's logit,
one figure among them) and learn from 2 843 simulated records (4 500 seeds
less those that cannot be judged or are deadband-like), since each costs
about 1.8 s of figures.  A network reading the trend itself costs a few
milliseconds a record, so the same shape of network can learn from 480 000
(``make cnn-large``, on a GPU), then from 7 253 more without the
deadband-like sticky ones, a quarter of them carrying a cycle from upstream
(``make cnn-large-tune``).  Alone it scores about
what the trees do; a logistic regression
on the two, fitted on the training seeds with the trees' scores out of fold
(``train.fit_stack``), scores better than either (docs/DETECTION_LOG.md,
"The stack").  The isotonic calibration then maps the stacked score to a
probability.

The weights live in the tree model's header (``meta['stack']``, read by
:meth:`TreeModel.score`) with the SHA-256 of the network they were fitted
with; a different or missing network is a :class:`DetectorFileError`.
"""

import hashlib
from pathlib import Path

import numpy as np

from stiction_ros._threads import worker_pool
from stiction_ros.analysis.detection import cnn
from stiction_ros.analysis.detection.stale import drop_held
from stiction_ros.analysis.detection.timing import realign
from stiction_ros.errors import DetectorFileError

LARGE_PATH = Path(__file__).resolve().parents[2] / 'resources' / 'stiction_cnn_large.npz'


# The stretches of a record the large network reads, as fractions of it: the
# whole and three 80 % windows.  One pass over one stretch is a noisy reading:
# over three 80 % windows of a simulated record the logit's standard deviation
# is 0.27 (median; 0.67 at the 90th percentile), and a plant record's
# probability moved by up to 0.40 when 10 % of each end was dropped.  The mean
# of the four is steadier (docs/DETECTION_LOG.md, "The large network reads four views").
VIEWS = ((0.0, 1.0), (0.0, 0.8), (0.1, 0.9), (0.2, 1.0))


def large_logit(op: np.ndarray, pv: np.ndarray, sp: np.ndarray | None,
                integrating: bool, path: str | Path | None = None) -> float:
    """
    Return the large network's log-odds of stiction: the mean over ``VIEWS``.

    Each view is standardised on its own (no SP: its mean PV, as
    ``cnn.channels``).  A record longer than ``cnn.WINDOW`` samples is
    already read as several windows and gets the whole view only.
    """
    where = str(path or LARGE_PATH)
    n = len(pv)
    if n > cnn.WINDOW:
        return cnn.cnn_logit(op, pv, sp, integrating, where)
    if sp is not None:
        sp = np.broadcast_to(np.asarray(sp, dtype=np.float64), np.shape(pv))
    out = []
    for a, b in VIEWS:
        i, j = int(round(a * n)), int(round(b * n))
        out.append(cnn.cnn_logit(op[i:j], pv[i:j], None if sp is None else sp[i:j],
                                 integrating, where))
    return float(np.mean(out))


def _seed_logit(seed: int) -> float:
    # As dataset.featurize_seed reads a record: simulated, held rows dropped, realigned.
    from stiction_ros.sim.corpus import draw_scenario, simulate
    sc = draw_scenario(int(seed))
    rec = simulate(sc)
    op, pv, sp, held = drop_held(rec['op'], rec['pv'], rec['sp'])
    _, op, pv, sp, _ = realign(op, pv, sp, held.count)
    return large_logit(op, pv, sp, sc.integrating)


def seed_logits(seeds, jobs: int = 1, cache: str | Path | None = None) -> np.ndarray:
    """
    Return the large network's logit of each simulated record of ``seeds``.

    ``cache``: a folder where the logits are kept under a hash of the seeds,
    the network and the code a logit depends on (the simulator's and the
    features' sources, as ``dataset.code_version``, and this file), and read
    back while all of them match.
    """
    seeds = [int(s) for s in seeds]
    path = None
    if cache is not None:
        path = Path(cache) / f'large_logits_{_key(seeds)}.npy'
        if path.is_file():
            return np.load(path, allow_pickle=False)
    if jobs <= 1:
        out = np.array([_seed_logit(s) for s in seeds])
    else:
        with worker_pool(jobs) as pool:
            out = np.array(list(pool.map(_seed_logit, seeds, chunksize=32)))
    if path is not None:
        path.parent.mkdir(parents=True, exist_ok=True)
        np.save(path, out)
    return out


def _key(seeds: list) -> str:
    from stiction_ros.analysis.detection.dataset import code_version
    h = hashlib.sha256(np.asarray(seeds, dtype=np.int64).tobytes())
    h.update(network().sha256.encode())
    h.update(code_version().encode())
    h.update(Path(__file__).read_bytes())
    return f'{seeds[0] if seeds else 0}_{len(seeds)}_{h.hexdigest()[:16]}'


def network() -> cnn.CnnModel:
    """Return the shipped large network; a missing or damaged file says how to rebuild it."""
    return cnn.load(LARGE_PATH, rebuild='`make cnn-large` (a GPU), then `make detector`')


def check_network(meta: dict, where: str) -> None:
    """Refuse a model whose stack was fitted with another large network than the shipped one."""
    stack = meta.get('stack')
    if stack is None:
        return
    net = network()
    # A file from before the views were read the whole record once.
    views, expected = stack.get('views', [[0.0, 1.0]]), [list(v) for v in VIEWS]
    try:
        same = [list(v) for v in views] == expected
    except TypeError:       # an edited header: not a list of pairs
        same = False
    if not same:
        raise DetectorFileError(
            f'{where}: stacked with the large network reading the views {views}, not '
            f'{expected}; rebuild with `make detector`')
    if stack.get('network_sha256') != net.sha256:
        raise DetectorFileError(
            f'{where}: stacked with another large network '
            f'({str(stack.get("network_sha256"))[:12]}) than the one shipped '
            f'({net.sha256[:12]}); rebuild with `make detector`')
