"""
Sticky simulated records that OP and PV cannot tell from a deadband.

Stiction is a deadband plus a slip (Choudhury's S and J).  When the slip is
small and the PV noisy, the sticky valve's record is, within the noise, the
record a pure deadband (backlash, Kano's model with J = 0) would make on the
same OP, and the issue counts a deadband as a look-alike, not as stiction.
Such a record carries no evidence that could tell the two apart, so its
label measures luck, as a record whose stiction is hidden under the noise
does (``dataset.MIN_FOOTPRINT``).

The **slip footprint** of a sticky record is therefore its footprint
(``dataset.stiction_footprint``) against the nearest deadband rather than
against no friction at all: the plant is driven once by the sticky valve's
true position and once by a deadband of width ``S' = k S`` fed the same OP,
for each ``k`` of ``GRID``, and the smallest difference, in noise widths,
is the footprint of the slip.  Below ``MIN_FOOTPRINT`` the record is
*deadband-like*: ``make accuracy`` leaves it out of the simulated score and
prints the score with it counted as sticky beside it, and ``make detector``
leaves it out of the training records and of the calibration map, so the
stated probability is that of a stick-slip OP and PV can show (the trees
since 2026-11-27, fifteenth session; the large network was trained on
without them, ``make cnn-large-tune``).  On the calibration seeds 225 of
the 816 judged sticky records are deadband-like;
the detector before this map called 178 of them stiction and flagged 49 of
the 107 backlash valves, which look the same (docs/DETECTION_LOG.md).

Only the simulated sets use this; a plant record has no true valve position.
"""

import hashlib
from pathlib import Path

import numpy as np

from stiction_ros._threads import worker_pool
from stiction_ros.analysis.detection.dataset import code_version, MIN_FOOTPRINT, \
    stiction_footprint

# Deadband widths tried, as fractions of the sticky valve's S: the nearest
# deadband to a valve that also slips is narrower than its S (the slip
# takes it part of the way) and, with the loop's noise, sometimes wider.
GRID = np.linspace(0.3, 1.6, 27)
SKIP_CODE = 'stiction_as_deadband'


def slip_footprint(sc, rec: dict) -> float:
    """
    Return how far above the PV noise the sticky valve differs from the nearest deadband.

    ``sc``, ``rec``: a scenario and its record (``sim.corpus``).  NaN for a
    record without stiction.
    """
    if not sc.label:
        return float('nan')
    from stiction_ros.models import create
    op = np.clip(np.asarray(rec['op'], dtype=np.float64), 0.0, 100.0)
    mv = np.asarray(rec['mv'], dtype=np.float64)
    best = float('inf')
    for k in GRID:
        band = create('kano', S=max(float(sc.S) * float(k), 1e-3), J=0.0)
        # The deadband's position stands where OP stood in the frictionless
        # footprint: the plant sees one valve, then the other.
        twin = {'mv': mv, 'op': band.simulate(op, y0=float(mv[0]))}
        best = min(best, stiction_footprint(sc, twin))
    return best


def _seed_footprint(seed: int) -> float:
    from stiction_ros.sim.corpus import draw_scenario, simulate
    sc = draw_scenario(int(seed))
    return slip_footprint(sc, simulate(sc)) if sc.label else float('nan')


def seed_footprints(seeds, jobs: int = 1, cache: str | Path | None = None) -> np.ndarray:
    """
    Return the slip footprint of each seed's record (NaN where it has no stiction).

    ``cache``: a folder where they are kept under a hash of the seeds, the
    simulator's and features' sources and this file.
    """
    seeds = [int(s) for s in seeds]
    path = None
    if cache is not None:
        h = hashlib.sha256(np.asarray(seeds, dtype=np.int64).tobytes())
        h.update(code_version().encode())
        h.update(Path(__file__).read_bytes())
        path = Path(cache) / f'slip_footprint_{h.hexdigest()[:16]}.npy'
        if path.is_file():
            return np.load(path)
    if jobs > 1 and len(seeds) > 1:
        with worker_pool(jobs) as pool:
            out = np.array(list(pool.map(_seed_footprint, seeds, chunksize=20)), dtype=float)
    else:
        out = np.array([_seed_footprint(s) for s in seeds], dtype=float)
    if path is not None:
        path.parent.mkdir(parents=True, exist_ok=True)
        np.save(path, out)
    return out


def mark(data: dict, jobs: int = 1, cache: str | Path | None = None) -> dict:
    """Return ``data`` (``dataset.build``) marked: ``deadband_like``, ``slip_footprint``."""
    fp = seed_footprints(data['seed'], jobs, cache)
    return {**data, 'slip_footprint': fp,
            'deadband_like': np.asarray(data['y'], dtype=bool) & (fp < MIN_FOOTPRINT)}


def leave_out(data: dict) -> dict:
    """Return a marked set without its deadband-like records, counted in ``skipped``."""
    drop = data['deadband_like']
    keep = ~drop
    out = {k: (v[keep] if isinstance(v, np.ndarray) and v.shape[:1] == drop.shape else v)
           for k, v in data.items()}
    out['skipped'] = {**data.get('skipped', {}), SKIP_CODE: int(drop.sum())}
    return out
