"""
Records cut by a gap: judged on the longest stretch, or on every stretch (``make gaps``).

A gap cuts a record into two stretches.  Each simulated record of a seed
range is read whole, and again with a share of it (:data:`SHARES`) cut out
at a place its seed draws, the stretches read by the analyzer's own path
(:func:`detect`), each one of at least ``MIN_SIGNATURE_SAMPLES`` samples.
Two answers are compared on the same cut records: the longest stretch
alone, as the analyzer read a record with gaps until 2026-12-06, and every
judged stretch pooled by :func:`stretches.pooled_probability`.  The records
scored are those ``make accuracy`` scores; nothing is fitted here.
"""

from dataclasses import dataclass
import time

import numpy as np

from stiction_ros._threads import pool_map
from stiction_ros.analysis.detection.detect import answer_of, THRESHOLD
from stiction_ros.analysis.detection.stretches import pooled_probability
from stiction_ros.study.accuracy import balanced_accuracy, confusion

# Shares of the record a gap takes out: a few minutes of a two-hour export, a
# manual period, most of the record.
SHARES = (0.05, 0.2, 0.4)
# The gap starts this far into the record at least, and ends as far before its end.
MARGIN = 0.15
MIN_STRETCH = 100     # pipeline.MIN_SIGNATURE_SAMPLES: a shorter stretch is not read
RULES = ('whole record', 'longest stretch', 'every stretch pooled')


def gap_of(n: int, share: float, seed: int) -> tuple[int, int]:
    """Return the first sample of the gap and the first after it, drawn from ``seed``."""
    g = int(round(share * n))
    rng = np.random.default_rng([int(seed), int(round(1000 * share))])
    lo, hi = int(MARGIN * n), int((1.0 - MARGIN) * n) - g
    a = int(rng.integers(lo, max(hi, lo + 1)))
    return a, a + g


def _read(seed: int) -> tuple:
    """Return (seed, label, kind, whole, {share: [(samples, probability) per stretch]})."""
    from stiction_ros.analysis.detection.dataset import MIN_FOOTPRINT, stiction_footprint
    from stiction_ros.analysis.detection.deadband_like import slip_footprint
    from stiction_ros.analysis.detection.detect import detect
    from stiction_ros.sim.corpus import draw_scenario, simulate
    sc = draw_scenario(int(seed))
    rec = simulate(sc)
    if sc.label and (stiction_footprint(sc, rec) < MIN_FOOTPRINT
                     or slip_footprint(sc, rec) < MIN_FOOTPRINT):
        return int(seed), None
    op, pv, sp = (np.asarray(rec[k], dtype=np.float64) for k in ('op', 'pv', 'sp'))
    whole = detect(op, pv, sp, sc.sample_time, sc.integrating).probability
    if whole is None:
        return int(seed), None
    cut = {}
    for share in SHARES:
        a, b = gap_of(len(op), share, seed)
        parts = []
        for lo, hi in ((0, a), (b, len(op))):
            p = None
            if hi - lo >= MIN_STRETCH:
                p = detect(op[lo:hi], pv[lo:hi], sp[lo:hi], sc.sample_time,
                           sc.integrating).probability
            parts.append((hi - lo, p))
        cut[share] = parts
    return int(seed), (bool(sc.label), sc.look_alike or sc.valve, float(whole), cut)


def answers(parts: list) -> tuple[float, float]:
    """Return the longest stretch's probability and the pooled one (NaN: not judged)."""
    longest = max(parts, key=lambda s: s[0])[1]
    judged = [(n, p) for n, p in parts if p is not None]
    # As the analyzer pools (pipeline.pool_stretches): one judged stretch keeps its own.
    pooled = (None if not judged else judged[0][1] if len(judged) == 1 else
              pooled_probability([p for _, p in judged], [n for n, _ in judged]))
    return (np.nan if longest is None else longest), (np.nan if pooled is None else pooled)


@dataclass
class Gaps:
    """The probabilities of every scored record, whole and cut, and what they add up to."""

    seeds: range
    label: np.ndarray
    kind: np.ndarray
    probability: dict       # (share, rule) -> probabilities; NaN where not judged
    seconds: float
    unscored: int

    def row(self, share: float, rule: str) -> dict:
        """Return the figures of one rule on the records cut by ``share``."""
        y, p = self.label, self.probability[(share, rule)]
        q = np.nan_to_num(p, nan=0.0)
        answer = np.array(['cannot tell' if np.isnan(v) else answer_of(v) for v in p])
        told = answer != 'cannot tell'
        c = confusion(y, q >= THRESHOLD)
        whole = np.nan_to_num(self.probability[(share, RULES[0])], nan=0.0) >= THRESHOLD
        return {'share': share, 'rule': rule, 'balanced_accuracy': balanced_accuracy(c), **c,
                'banded_balanced_accuracy': balanced_accuracy(
                    confusion(y, answer == 'stiction')),
                'decided_balanced_accuracy': balanced_accuracy(
                    confusion(y[told], answer[told] == 'stiction')),
                'decided_share': float(told.mean()), 'refused': int(np.isnan(p).sum()),
                'differ_from_whole': int(np.sum((q >= THRESHOLD) != whole))}

    def to_json(self) -> dict:
        """Return the study as plain JSON types."""
        rows = [self.row(s, r) for s in SHARES for r in RULES]
        rows = [{k: (None if isinstance(v, float) and v != v else v) for k, v in r.items()}
                for r in rows]
        return {'seeds': [self.seeds.start, self.seeds.stop], 'records': int(len(self.label)),
                'sticky': int(self.label.sum()), 'unscored': self.unscored,
                'seconds': round(self.seconds, 1), 'rows': rows}


def run(seeds: range, jobs: int = 1, say=None) -> Gaps:
    """Return the :class:`Gaps` of the simulated records of ``seeds``."""
    t0, got = time.perf_counter(), []
    for i, r in enumerate(pool_map(_read, seeds, jobs, chunksize=10), 1):
        got.append(r)
        if say is not None and (i % 50 == 0 or i == len(seeds)):
            say(i, len(seeds), time.perf_counter() - t0)
    kept = [r[1] for r in got if r[1] is not None]
    if not kept:
        raise ValueError(f'no record of seeds {seeds.start}-{seeds.stop - 1} can be scored')
    prob = {}
    for share in SHARES:
        pairs = np.array([answers(r[3][share]) for r in kept], dtype=np.float64)
        prob[(share, RULES[0])] = np.array([r[2] for r in kept])
        prob[(share, RULES[1])], prob[(share, RULES[2])] = pairs[:, 0], pairs[:, 1]
    return Gaps(seeds, np.array([r[0] for r in kept]), np.array([r[1] for r in kept]), prob,
                time.perf_counter() - t0, len(got) - len(kept))
