"""
The detector's last step: the trees' score and the large networks' logits, weighed together.

The boosted trees read the engineered figures (and the small network's logit,
one figure among them) and learn from 2 818 simulated records (4 500 seeds
less those that cannot be judged or are deadband-like), since each costs
about 1.8 s of figures.  A network reading the trend itself costs a few
milliseconds a record, so the same shape of network can learn from 480 000
(``make cnn-large``, on a GPU), then from 7 262 more without the
deadband-like sticky ones (``make cnn-large-tune``).  Alone it scores about
what the trees do; a logistic regression
on the two, fitted on the training seeds with the trees' scores out of fold
(``train.fit_stack``), scores better than either (docs/DETECTION.md,
section 3).  A second network of twice the width, trained on the same
corpus (``make cnn-wide``, ``make cnn-wide-tune``), errs on partly other
records, and the stack weighs both (docs/DETECTION.md, "Both large
networks, stacked").  The isotonic calibration then maps the stacked score
to a probability.

The weights live in the tree model's header (``meta['stack']``, read by
:meth:`TreeModel.score`) with the file and SHA-256 of each network they were
fitted with; a different or missing network is a :class:`DetectorFileError`.
"""

from concurrent.futures import ProcessPoolExecutor
from functools import partial
import hashlib
from pathlib import Path

import numpy as np

from stiction_ros._threads import one_blas_thread
from stiction_ros.analysis.detection import cnn
from stiction_ros.analysis.detection.model_file import stack_networks
from stiction_ros.analysis.detection.stale import drop_held
from stiction_ros.analysis.detection.timing import realign
from stiction_ros.errors import DetectorFileError

RESOURCES = Path(__file__).resolve().parents[2] / 'resources'
LARGE_PATH = RESOURCES / 'stiction_cnn_large.npz'
WIDE_PATH = RESOURCES / 'stiction_cnn_wide.npz'
# The networks ``make detector`` stacks, by the name each logit goes by in the
# evidence, and how to make each again.
NETWORKS = (('cnn_large_logit', LARGE_PATH, '`make cnn-large` (a GPU), then `make detector`'),
            ('cnn_wide_logit', WIDE_PATH, '`make cnn-wide` (a GPU), then `make detector`'))


# The stretches of a record the large network reads, as fractions of it: the
# whole and three 80 % windows.  One pass over one stretch is a noisy reading:
# over three 80 % windows of a simulated record the logit's standard deviation
# is 0.27 (median; 0.67 at the 90th percentile), and a plant record's
# probability moved by up to 0.40 when 10 % of each end was dropped.  The mean
# of the four is steadier (docs/DETECTION.md, section 3).
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


def logits(networks: list[dict], op: np.ndarray, pv: np.ndarray, sp: np.ndarray | None,
           integrating: bool) -> np.ndarray:
    """Return the logit of each network a stack weighs (``TreeModel.networks``), in its order."""
    return np.array([large_logit(op, pv, sp, integrating, RESOURCES / n['file'])
                     for n in networks])


def _seed_logit(seed: int, path: str | None = None) -> float:
    # As dataset.featurize_seed reads a record: simulated, held rows dropped, realigned.
    from stiction_ros.sim.corpus import draw_scenario, simulate
    sc = draw_scenario(int(seed))
    rec = simulate(sc)
    op, pv, sp, held = drop_held(rec['op'], rec['pv'], rec['sp'])
    _, op, pv, sp, _ = realign(op, pv, sp, held.count)
    return large_logit(op, pv, sp, sc.integrating, path)


def seed_logits(seeds, jobs: int = 1, cache: str | Path | None = None,
                path: str | Path | None = None) -> np.ndarray:
    """
    Return the logit of the network at ``path`` (default: the large one) of each simulated record.

    ``cache``: a folder where the logits are kept under a hash of the seeds,
    the network and the code a logit depends on (the simulator's and the
    features' sources, as ``dataset.code_version``, and this file), and read
    back while all of them match.
    """
    seeds = [int(s) for s in seeds]
    where = str(path or LARGE_PATH)
    file = None
    if cache is not None:
        file = Path(cache) / f'large_logits_{_key(seeds, where)}.npy'
        if file.is_file():
            return np.load(file, allow_pickle=False)
    one = partial(_seed_logit, path=where)
    if jobs <= 1:
        out = np.array([one(s) for s in seeds])
    else:
        with ProcessPoolExecutor(jobs, initializer=one_blas_thread) as pool:
            out = np.array(list(pool.map(one, seeds, chunksize=32)))
    if file is not None:
        file.parent.mkdir(parents=True, exist_ok=True)
        np.save(file, out)
    return out


def seed_logit_columns(networks: list[dict], seeds, jobs: int = 1,
                       cache: str | Path | None = None) -> np.ndarray:
    """Return the logits of each simulated record (rows) by each network (columns, in order)."""
    cols = [seed_logits(seeds, jobs, cache, RESOURCES / n['file']) for n in networks]
    return np.column_stack(cols) if cols else np.zeros((len(list(seeds)), 0))


def shipped_networks() -> list[dict]:
    """Return the networks ``make detector`` stacks, named as a stack header names them."""
    return [{'name': name, 'file': path.name, 'sha256': network(path).sha256}
            for name, path, _ in NETWORKS]


def _key(seeds: list, where: str) -> str:
    from stiction_ros.analysis.detection.dataset import code_version
    h = hashlib.sha256(np.asarray(seeds, dtype=np.int64).tobytes())
    h.update(cnn.load(where).sha256.encode())
    h.update(code_version().encode())
    h.update(Path(__file__).read_bytes())
    return f'{seeds[0] if seeds else 0}_{len(seeds)}_{h.hexdigest()[:16]}'


def network(path: str | Path | None = None) -> cnn.CnnModel:
    """Load a shipped stacked network, by default the large one; a bad file says how to rebuild."""
    where = Path(path or LARGE_PATH)
    rebuild = next((r for _, p, r in NETWORKS if p.name == where.name), '`make detector`')
    return cnn.load(where, rebuild=rebuild)


def check_network(meta: dict, where: str) -> None:
    """Refuse a model whose stack was fitted with other networks than the shipped ones."""
    stack = meta.get('stack')
    if stack is None:
        return
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
    for n in stack_networks(stack):
        net = network(RESOURCES / n['file'])
        if n['sha256'] != net.sha256:
            raise DetectorFileError(
                f'{where}: stacked with another {n["file"]} ({str(n["sha256"])[:12]}) than '
                f'the one shipped ({net.sha256[:12]}); rebuild with `make detector`')
