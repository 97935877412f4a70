"""
Whether the verdict holds when instruments and timing distort the trend (``make robustness``).

Real recordings differ from simulated ones first through instruments and
timing, not friction.  Each simulated record of a seed range is read by the
analyzer's own path (:func:`detect`) as simulated and again under each
distortion of :data:`CONDITIONS`: PV damped after the controller read
it (on the lag check's grid and off it, rounded after the filter), tags
skewed in time, swinging-door compression, a coarser export grid, the set
point left out of the export.
The valve is the same in every condition, so a change of answer is the
instrument's doing.

The records scored are those ``make accuracy`` scores: judgeable as
simulated, stiction not hidden under PV's noise, sticky records not
deadband-like.  A distorted record the analyzer cannot judge counts as a
refusal (``cannot tell``), as at run time.  Nothing is fitted or chosen
here; the model is the shipped one.  A record the timing checks
(:mod:`stiction_ros.analysis.detection.timing`: a clock skew, a lag after the
controller) realign is read again without them, so each row shows what the
checks bought.
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
# The refusal the issue asks for where a regular cycle spans under 10 samples
# (resolve.cycle_judgeable), or where OP and PV alternate from sample to sample.
UNDER = 'under_sampled'


def _as_is(t: Trend, noise: float) -> Trend:
    return t


def _damped(t: Trend, noise: float) -> Trend:
    return Trend(t.op, lag_filter(t.pv, 3.0), t.sp, t.sample_time)


def _damped_rounded(t: Trend, noise: float) -> Trend:
    # A time constant off the lag check's grid, and a historian's resolution after
    # the filter, which undoing the lag amplifies.
    pv = lag_filter(t.pv, 4.5)
    q = (float(np.ptp(t.pv)) or 1.0) / 2000.0
    return Trend(t.op, np.round(pv / q) * q, t.sp, t.sample_time)


def _late(t: Trend, noise: float) -> Trend:
    return shift_pv(t, 3)


def _early(t: Trend, noise: float) -> Trend:
    return shift_pv(t, -3)


def _compressed(t: Trend, noise: float) -> Trend:
    op_dev = 0.002 * float(np.ptp(t.op))
    return Trend(compress(t.op, op_dev), compress(t.pv, 2.0 * noise), t.sp, t.sample_time)


def _coarse(t: Trend, noise: float) -> Trend:
    return every(t, 2)


def _late_one(t: Trend, noise: float) -> Trend:
    return shift_pv(t, 1)


def _coarse_late(t: Trend, noise: float) -> Trend:
    return shift_pv(every(t, 2), 1)


def _no_set_point(t: Trend, noise: float) -> Trend:
    return Trend(t.op, t.pv, None, t.sample_time)


# Each condition: (name, what it stands for, its distortion, the rows it makes PV
# late against OP: the skew the clock check should find, 0 for none).
CONDITIONS: tuple[tuple[str, str, Distortion, int], ...] = (
    ('as simulated', 'the reference', _as_is, 0),
    ('PV damped', 'PV through a first-order lag of 3 samples that the controller did not see '
     "(a filter between the controller and the historian; a transmitter's damping that "
     'the controller sees is a lag of the plant with coloured noise, which the corpus '
     'draws)', _damped, 0),
    ('PV damped 4.5, rounded', 'PV through a first-order lag of 4.5 samples the controller '
     'did not see, then rounded to 1/2000 of its range (a resolution after the filter)',
     _damped_rounded, 0),
    ('PV late', 'PV and SP 3 samples later than OP (a clock skew between two tags)', _late, 3),
    ('PV early', 'PV and SP 3 samples earlier than OP (OP logged late)', _early, -3),
    ('compressed', 'OP and PV through a swinging-door historian (deviation: 2 noise SD of '
     "PV, 0.2 % of OP's range), exported as straight lines between kept points",
     _compressed, 0),
    ('every second row', 'one row in two (twice the sample time)', _coarse, 0),
    ('PV late 1', 'PV and SP 1 row later than OP', _late_one, 1),
    ('every second row, PV late 1', 'one row in two, then PV and SP 1 row later than OP (the '
     "controller's law holds only roughly on the coarser grid)", _coarse_late, 1),
    ('no set point', 'OP and PV exported without SP: the analyzer stands the mean PV in for '
     'it, as for any record without one (no training record lacks it)', _no_set_point, 0),
)


def _read(seed: int) -> tuple:
    """
    Return one seed's label, kind, whether it is scored, and its answers.

    That is (seed, label, kind, scored, [(answer, probability, shift, refusal,
    lag) per condition], as given); ``shift`` is the rows the skew check moved
    PV by and ``lag`` the rows of lag the lag check found; ``refusal`` is the
    code of the reason a record was not judged ('' when it was).

    ``as given``: (answer, probability) of each condition read without the
    timing checks (the same as with them where they moved nothing).
    """
    from stiction_ros.analysis.detection.dataset import MIN_FOOTPRINT, stiction_footprint
    from stiction_ros.analysis.detection.deadband_like import slip_footprint
    from stiction_ros.analysis.detection.detect import detect
    from stiction_ros.sim.corpus import draw_scenario, simulate
    sc = draw_scenario(int(seed))
    rec = simulate(sc)
    kind = sc.look_alike or sc.valve
    if sc.label and (stiction_footprint(sc, rec) < MIN_FOOTPRINT
                     or slip_footprint(sc, rec) < MIN_FOOTPRINT):
        return int(seed), bool(sc.label), kind, False, [], []
    trend = Trend(rec['op'], rec['pv'], rec['sp'], sc.sample_time)
    out, given = [], []
    for name, _, distort, _ in CONDITIONS:
        t = distort(trend, sc.noise_std)
        try:
            d = detect(t.op, t.pv, t.sp, t.sample_time, sc.integrating)
            timing = d.details.get('timing', {})
            shift, lag = timing.get('shift_rows', 0), timing.get('lag_found_rows', 0.0)
            d0 = detect(t.op, t.pv, t.sp, t.sample_time, sc.integrating,
                        realign=False) if shift or timing.get('lag_rows') else d
        except Exception as exc:
            # An analyzer failure is the finding: say which record and condition.
            raise RuntimeError(f'the analyzer failed on seed {seed}, {name}: {exc!r}') from exc
        if d.probability is None and not out:
            # Not judgeable as simulated: not a record make accuracy scores.
            return int(seed), bool(sc.label), kind, False, [], []
        out.append((d.answer, d.probability, shift, '' if d.judge.ok else d.judge.code, lag))
        given.append((d0.answer, d0.probability))
    return int(seed), bool(sc.label), kind, True, out, given


@dataclass
class Robustness:
    """The answers of every scored record under every condition, and what they add up to."""

    seeds: range
    label: np.ndarray
    kind: np.ndarray
    answer: np.ndarray          # (records, conditions): the analyzer's three answers
    probability: np.ndarray     # (records, conditions); NaN where the record was not judged
    shift: np.ndarray           # (records, conditions): rows the clock-skew check realigned by
    refusal: np.ndarray         # (records, conditions): why not judged ('' where judged)
    given_answer: np.ndarray    # the same two read without the check
    given_probability: np.ndarray
    seconds: float
    unscored: int = 0
    seed: np.ndarray = field(default_factory=lambda: np.empty(0, dtype=np.int64))
    # (records, conditions): rows of lag the lag check found on PV (0: none)
    lag: np.ndarray | None = None
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
        given = confusion(y, np.nan_to_num(self.given_probability[:, j], nan=0.0) >= THRESHOLD)
        shifted, skew = self.shift[:, j], CONDITIONS[j][3]
        return {'condition': CONDITIONS[j][0], 'what': CONDITIONS[j][1],
                'balanced_accuracy': balanced_accuracy(c), **c,
                'realigned': int(np.sum(shifted != 0)),
                'realigned_right': int(np.sum(shifted == skew)) if skew else 0,
                'lagged': 0 if self.lag is None else int(np.sum(self.lag[:, j] > 0)),
                'without_check_balanced_accuracy': balanced_accuracy(given),
                'without_check_banded_balanced_accuracy': balanced_accuracy(
                    confusion(y, self.given_answer[:, j] == 'stiction')),
                'banded_balanced_accuracy': balanced_accuracy(banded),
                'decided_balanced_accuracy': balanced_accuracy(decided),
                'decided_share': float(told.mean()),
                'refused': int(np.isnan(p).sum()),
                'new_flags': int(np.sum(~y & forced & ~ref)),
                'lost_finds': int(np.sum(y & ~forced & ref)),
                # A find lost to a refusal the issue asks for (a cycle under 10 samples)
                # is not the same finding as one the model reads lower.
                'lost_refused': int(np.sum(y & ref & np.isnan(p))),
                'lost_under_sampled': int(np.sum(y & ref & (self.refusal[:, j] == UNDER))),
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
    ans = np.array([[c[0] for c in r[4]] for r in kept])
    prob = np.array([[np.nan if c[1] is None else c[1] for c in r[4]] for r in kept])
    shift = np.array([[c[2] for c in r[4]] for r in kept], dtype=np.int64)
    refusal = np.array([[c[3] for c in r[4]] for r in kept], dtype=object)
    lag = np.array([[c[4] for c in r[4]] for r in kept], dtype=np.float64)
    ans0 = np.array([[c[0] for c in r[5]] for r in kept])
    prob0 = np.array([[np.nan if c[1] is None else c[1] for c in r[5]] for r in kept])
    return Robustness(seeds, np.array([r[1] for r in kept]), np.array([r[2] for r in kept]),
                      ans, prob, shift, refusal, ans0, prob0, time.perf_counter() - t0,
                      len(got) - len(kept), np.array([r[0] for r in kept], dtype=np.int64),
                      lag)


def _tick(say, i: int, n: int, t0: float) -> None:
    if say is not None and (i % 100 == 0 or i == n):
        say(i, n, time.perf_counter() - t0)
