"""
Whether the verdict holds when instruments and timing distort the trend (``make robustness``).

Real recordings differ from simulated ones first through instruments and
timing, not friction.  Each simulated record of a seed range is read by the
analyzer's own path (:func:`detect`) as simulated and again under each
distortion of :data:`CONDITIONS`: a damped transmitter, tags skewed in time,
swinging-door compression, a coarser export grid.  The valve is the same in
every condition, so a change of answer is the instrument's doing.

The records scored are those ``make accuracy`` scores: judgeable as
simulated, stiction not hidden under PV's noise, sticky records not
deadband-like.  A distorted record the analyzer cannot judge counts as a
refusal (``cannot tell``), as at run time.  Nothing is fitted or chosen
here; the model is the shipped one.
"""

from dataclasses import dataclass, field
import time
from typing import Callable

import numpy as np

from stiction_ros._threads import pool_map
from stiction_ros.analysis.detection.detect import THRESHOLD
from stiction_ros.study.accuracy import balanced_accuracy, confusion
from stiction_ros.study.distortions import compress, every, lag_filter, shift_pv, Trend

# A distortion of (trend, PV noise SD).
Distortion = Callable[[Trend, float], Trend]


def _as_is(t: Trend, noise: float) -> Trend:
    return t


def _damped(t: Trend, noise: float) -> Trend:
    return Trend(t.op, lag_filter(t.pv, 3.0), t.sp, t.sample_time)


def _late(t: Trend, noise: float) -> Trend:
    return shift_pv(t, 3)


def _early(t: Trend, noise: float) -> Trend:
    return shift_pv(t, -3)


def _compressed(t: Trend, noise: float) -> Trend:
    op_dev = 0.002 * float(np.ptp(t.op))
    return Trend(compress(t.op, op_dev), compress(t.pv, 2.0 * noise), t.sp, t.sample_time)


def _coarse(t: Trend, noise: float) -> Trend:
    return every(t, 2)


# Each condition: (name, what it stands for, its distortion).
CONDITIONS: tuple[tuple[str, str, Distortion], ...] = (
    ('as simulated', 'the reference', _as_is),
    ('PV damped', "PV through a first-order lag of 3 samples (a transmitter's damping)",
     _damped),
    ('PV late', 'PV and SP 3 samples later than OP (a clock skew between two tags)', _late),
    ('PV early', 'PV and SP 3 samples earlier than OP (OP logged late)', _early),
    ('compressed', 'OP and PV through a swinging-door historian (deviation: 2 noise SD of '
     "PV, 0.2 % of OP's range), exported as straight lines between kept points",
     _compressed),
    ('every second row', 'one row in two (twice the sample time)', _coarse),
)


def _read(seed: int) -> tuple:
    """Return (seed, label, kind, scored, [(answer, probability) per condition])."""
    from stiction_ros.analysis.detection.dataset import MIN_FOOTPRINT, stiction_footprint
    from stiction_ros.analysis.detection.deadband_like import slip_footprint
    from stiction_ros.analysis.detection.detect import detect
    from stiction_ros.sim.corpus import draw_scenario, simulate
    sc = draw_scenario(int(seed))
    rec = simulate(sc)
    kind = sc.look_alike or sc.valve
    if sc.label and (stiction_footprint(sc, rec) < MIN_FOOTPRINT
                     or slip_footprint(sc, rec) < MIN_FOOTPRINT):
        return int(seed), bool(sc.label), kind, False, []
    trend = Trend(rec['op'], rec['pv'], rec['sp'], sc.sample_time)
    out = []
    for name, _, distort in CONDITIONS:
        t = distort(trend, sc.noise_std)
        try:
            d = detect(t.op, t.pv, t.sp, t.sample_time, sc.integrating)
        except Exception as exc:
            # An analyzer failure is the finding: say which record and condition.
            raise RuntimeError(f'the analyzer failed on seed {seed}, {name}: {exc!r}') from exc
        if d.probability is None and not out:
            # Not judgeable as simulated: not a record make accuracy scores.
            return int(seed), bool(sc.label), kind, False, []
        out.append((d.answer, d.probability))
    return int(seed), bool(sc.label), kind, True, out


@dataclass
class Robustness:
    """The answers of every scored record under every condition, and what they add up to."""

    seeds: range
    label: np.ndarray
    kind: np.ndarray
    answer: np.ndarray          # (records, conditions): the analyzer's three answers
    probability: np.ndarray     # (records, conditions); NaN where the record was not judged
    seconds: float
    unscored: int = 0
    seed: np.ndarray = field(default_factory=lambda: np.empty(0, dtype=np.int64))
    rows: list = field(init=False)

    def __post_init__(self):
        self.rows = [self._row(j) for j in range(len(CONDITIONS))]

    def _row(self, j: int) -> dict:
        y, p, a = self.label, self.probability[:, j], self.answer[:, j]
        # The probability as the analyzer reports it (4 decimals), at make accuracy's 0.5.
        forced = np.nan_to_num(p, nan=0.0) >= THRESHOLD
        ref = np.nan_to_num(self.probability[:, 0], nan=0.0) >= THRESHOLD
        c = confusion(y, forced)
        told = a != 'cannot tell'
        banded = confusion(y, a == 'stiction')
        decided = confusion(y[told], a[told] == 'stiction')
        return {'condition': CONDITIONS[j][0], 'what': CONDITIONS[j][1],
                'balanced_accuracy': balanced_accuracy(c), **c,
                'banded_balanced_accuracy': balanced_accuracy(banded),
                'decided_balanced_accuracy': balanced_accuracy(decided),
                'decided_share': float(told.mean()),
                'refused': int(np.isnan(p).sum()),
                'new_flags': int(np.sum(~y & forced & ~ref)),
                'lost_finds': int(np.sum(y & ~forced & ref)),
                'median_shift_healthy': _median_shift(p, self.probability[:, 0], ~y),
                'median_shift_sticky': _median_shift(p, self.probability[:, 0], y)}

    def to_json(self) -> dict:
        """Return the study as plain JSON types (an undefined figure as None)."""
        rows = [{k: (None if isinstance(v, float) and v != v else v) for k, v in r.items()}
                for r in self.rows]
        return {'seeds': [self.seeds.start, self.seeds.stop], 'records': int(len(self.label)),
                'sticky': int(self.label.sum()), 'unscored': self.unscored,
                'seconds': round(self.seconds, 1), 'rows': rows}


def _median_shift(p: np.ndarray, ref: np.ndarray, sel: np.ndarray) -> float:
    both = sel & np.isfinite(p) & np.isfinite(ref)
    return float(np.median(p[both] - ref[both])) if both.any() else float('nan')


def run(seeds: range, jobs: int = 1, say=None) -> Robustness:
    """Return the :class:`Robustness` of the simulated records of ``seeds``."""
    t0, got = time.perf_counter(), []
    for i, r in enumerate(pool_map(_read, seeds, jobs, chunksize=10), 1):
        got.append(r)
        _tick(say, i, len(seeds), t0)
    kept = [r for r in got if r[3]]
    if not kept:
        raise ValueError(f'no record of seeds {seeds.start}-{seeds.stop - 1} can be scored')
    ans = np.array([[a for a, _ in r[4]] for r in kept])
    prob = np.array([[np.nan if q is None else q for _, q in r[4]] for r in kept])
    return Robustness(seeds, np.array([r[1] for r in kept]), np.array([r[2] for r in kept]),
                      ans, prob, time.perf_counter() - t0, len(got) - len(kept),
                      np.array([r[0] for r in kept], dtype=np.int64))


def _tick(say, i: int, n: int, t0: float) -> None:
    if say is not None and (i % 100 == 0 or i == n):
        say(i, n, time.perf_counter() - t0)
