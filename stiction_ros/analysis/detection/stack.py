"""
The detector's last step: the trees' score and a larger network's logit, weighed together.

The boosted trees read the engineered figures (and the small network's logit,
one figure among them) and learn from 3 150 simulated records, since each
costs about 1.8 s of figures.  A network reading the trend itself costs a
few milliseconds a record, so it can learn from 480 000 (``make cnn-large``,
on a GPU).  Alone it scores about what the trees do; a logistic regression
on the two, fitted on the training seeds with the trees' scores out of fold
(``train.fit_stack``), scores better than either (docs/DETECTION.md,
section 3).  The isotonic calibration then maps the stacked score to a
probability.

The weights live in the tree model's header (``meta['stack']``, read by
:meth:`TreeModel.score`) with the SHA-256 of the network they were fitted
with; a different or missing network is a :class:`DetectorFileError`.
"""

from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

from stiction_ros._threads import one_blas_thread
from stiction_ros.analysis.detection import cnn
from stiction_ros.analysis.detection.stale import drop_held
from stiction_ros.errors import DetectorFileError

LARGE_PATH = Path(__file__).resolve().parents[2] / 'resources' / 'stiction_cnn_large.npz'


def large_logit(op: np.ndarray, pv: np.ndarray, sp: np.ndarray | None,
                integrating: bool, path: str | Path | None = None) -> float:
    """Return the large network's log-odds of stiction, on the inputs the figures read."""
    sp_arr = np.full(len(pv), float(np.mean(pv))) if sp is None else sp
    return cnn.cnn_logit(op, pv, sp_arr, integrating, str(path or LARGE_PATH))


def _seed_logit(seed: int) -> float:
    # As dataset.featurize_seed reads a record: simulated, held rows dropped.
    from stiction_ros.sim.corpus import draw_scenario, simulate
    sc = draw_scenario(int(seed))
    rec = simulate(sc)
    op, pv, sp, _ = drop_held(rec['op'], rec['pv'], rec['sp'])
    return large_logit(op, pv, sp, sc.integrating)


def seed_logits(seeds, jobs: int = 1) -> np.ndarray:
    """Return the large network's logit of each simulated record of ``seeds``."""
    seeds = [int(s) for s in seeds]
    if jobs <= 1:
        return np.array([_seed_logit(s) for s in seeds])
    with ProcessPoolExecutor(jobs, initializer=one_blas_thread) as pool:
        return np.array(list(pool.map(_seed_logit, seeds, chunksize=32)))


def network() -> cnn.CnnModel:
    """Return the shipped large network; a missing or damaged file says how to rebuild it."""
    return cnn.load(LARGE_PATH, rebuild='`make cnn-large` (a GPU), then `make detector`')


def check_network(meta: dict, where: str) -> None:
    """Refuse a model whose stack was fitted with another large network than the shipped one."""
    stack = meta.get('stack')
    if stack is None:
        return
    net = network()
    if stack.get('network_sha256') != net.sha256:
        raise DetectorFileError(
            f'{where}: stacked with another large network '
            f'({str(stack.get("network_sha256"))[:12]}) than the one shipped '
            f'({net.sha256[:12]}); rebuild with `make detector`')
