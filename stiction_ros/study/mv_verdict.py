"""
The headline verdict with a measured valve position, scored blind (``make mv-verdict``).

With MV in a recording the answer to "does this valve stick?" comes from the
valve fits (:func:`stiction_ros.analysis.verdict.from_fits`), not from the
learned detector, so ``docs/ACCURACY.md`` (OP and PV only) does not score it.
Here every closed loop of :mod:`stiction_ros.sim.instrument_cases` (stiction,
play without slip, and the frictionless instrument and timing effects a real
position reading carries: dead time, lag, calibration, rate limit, travel
stop, quantisation) is written to a CSV with ``t, sp, pv, op, mv`` and read
as ``stiction-analyze`` reads it.  A noisier position transmitter than the
loops' own (MV noise 1 or 2 %) is added on a third of the runs each, since
that is where the rules meet their limits.

The shipped rule is scored beside three it grew from, on the same fits: the
same without stick-slip refitted behind the reading's dead time and
calibration (``on_time``), without a valve without friction to beat at all
(``jump``), and the rule
before the slip-jump and noise tests (``old``: S's range above ``MIN_S``
and half of an ideal valve's MSE removed, stiction; else none).  Truth:
stiction where the case hides friction (Kano with J > 0), no stiction
otherwise (play is a look-alike, as issue 18 counts a deadband).  Nothing
here is fitted or chosen; the seeds are fresh.
"""

from dataclasses import dataclass
import math
from pathlib import Path
import tempfile
import time
from typing import Callable

import numpy as np

from stiction_ros._threads import pool_map
from stiction_ros.analysis.pipeline import analyze
from stiction_ros.analysis.readers import load_record
from stiction_ros.analysis.verdict import ANSWER, from_fits, MIN_IMPROVEMENT, MIN_S
from stiction_ros.errors import StictionError
from stiction_ros.sim import reading_probes
from stiction_ros.sim.closed_loop import write_csv
from stiction_ros.sim.instrument_cases import CASES, instrument_case

SAMPLE_TIMES = (0.1, 0.5, 1.0, 2.0, 5.0)
NOISES = (0.5, 1.0, 2.0)            # the loop's own noise: MV 0.05, 0.1, 0.2 %
EXTRA_MV_NOISE = (0.0, 1.0, 2.0)    # % of span, a noisier position transmitter
N_SAMPLES = 4321
ANSWERS = ('stiction', 'no stiction', 'cannot tell')
# The rules scored, by the key of their answer in a row: the shipped one, the same without
# stick-slip refitted behind the reading's timing and calibration, without the frictionless
# valve to beat at all, and the rule before the slip-jump and noise tests.
RULES = ('answer', 'on_time', 'jump', 'old')


@dataclass(frozen=True)
class Run:
    """One record: the case, its seed, sampling and noise, and which cases it is of."""

    case: str
    seed: int
    sample_time: float
    noise: float
    extra_mv_noise: float
    family: str = 'instrument'


# The cases each family draws: the instrument cases the rule was set on, and the reading
# effects it never met (stiction_ros.sim.reading_probes).
FAMILIES = {'instrument': CASES, 'probe': reading_probes.CASES}


def runs(per_case: int, first_seed: int, family: str = 'instrument') -> list[Run]:
    """
    Return the runs: each case of ``family`` on seeds ``first_seed`` onwards.

    Sample time, the loop's noise and the extra MV noise cycle over the runs
    of a case so that each meets each, and one seed draws one loop for every
    case (so the cases of a seed differ only in what they hide).
    """
    out = []
    for case in FAMILIES[family]:
        for i in range(per_case):
            out.append(Run(case, first_seed + i, SAMPLE_TIMES[i % len(SAMPLE_TIMES)],
                           NOISES[(i // len(EXTRA_MV_NOISE)) % len(NOISES)],
                           EXTRA_MV_NOISE[i % len(EXTRA_MV_NOISE)], family))
    return out


def old_rule(stiction: dict, fits: list[dict]) -> str:
    """Return the answer of the rule before the slip-jump and noise tests, on the same fits."""
    if stiction.get('cannot_tell') in ('mv_still', 'mv_dead'):
        return 'cannot tell'
    best = min(fits, key=lambda f: f['mse'])
    lo = best['S_interval'][0] if best.get('S_interval') else best['S']
    improvement = best.get('improvement')
    banded = lo >= MIN_S and (improvement is None or improvement >= MIN_IMPROVEMENT)
    return 'stiction' if banded else 'no stiction'


def _without(stiction: dict, fits: list[dict], keys: tuple[str, ...]) -> str:
    """Return the shipped rule's answer on the fits without the entries ``keys``."""
    if stiction.get('cannot_tell') in ('mv_still', 'mv_dead'):
        return 'cannot tell'
    return ANSWER[from_fits([{k: v for k, v in f.items() if k not in keys}
                             for f in fits]).detected]


def on_time_rule(stiction: dict, fits: list[dict]) -> str:
    """Return the shipped rule's answer without stick-slip read behind the reading's timing."""
    return _without(stiction, fits, ('behind',))


def jump_rule(stiction: dict, fits: list[dict]) -> str:
    """Return the shipped rule's answer without the valve without friction to beat."""
    return _without(stiction, fits, ('frictionless', 'calibrated_mse', 'behind'))


def read(run: Run) -> dict:
    """Simulate one run, analyse its CSV as the analyzer does, return what it answered."""
    if run.family == 'probe':
        # The probe adds the noisier transmitter itself, before the reading's effect.
        record, truth = reading_probes.probe_case(run.case, run.seed, run.sample_time,
                                                  N_SAMPLES, run.noise, run.extra_mv_noise)
        mv = record['mv']
    else:
        record, truth = instrument_case(run.case, run.seed, sample_time=run.sample_time,
                                        n_samples=N_SAMPLES, noise=run.noise)
        # Its own stream: the loop of a seed stays the same in every case.
        mv = record['mv'] + run.extra_mv_noise * np.random.default_rng(
            [run.seed, 29]).standard_normal(len(record['mv']))
    base = {'case': run.case, 'seed': run.seed, 'sample_time': run.sample_time,
            'extra_mv_noise': run.extra_mv_noise,
            'mv_noise': round(math.hypot(0.1 * run.noise, run.extra_mv_noise), 4),
            'truth': 'stiction' if truth['friction'] else 'no stiction'}
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / 'loop.csv'
        write_csv(path, {'t': record['t'], 'sp': record['sp'], 'pv': record['pv'],
                         'op': record['op'], 'mv': mv}, columns=('t', 'sp', 'pv', 'op', 'mv'))
        try:
            report = analyze(load_record(path)).report
        except StictionError as err:
            # Scored as neither answer, and shown: the analyzer failed on a plain loop.
            return {**base, **dict.fromkeys(RULES, 'error'), 'error': str(err)}
    st, fits = report['stiction'], report['fits']
    if not fits:
        # MV set aside as a dead reading (mv_dead): OP and PV answered, under every rule.
        return {**base, **dict.fromkeys(RULES, st['answer']), 'cannot_tell':
                st.get('cannot_tell'), 'mv_dead': True, 'S': None, 'J': None}
    best = min(fits, key=lambda f: f['mse'])
    return {**base, 'answer': st['answer'], 'cannot_tell': st.get('cannot_tell'),
            'play': st.get('play'), 'on_time': on_time_rule(st, fits),
            'jump': jump_rule(st, fits), 'old': old_rule(st, fits),
            'S': best['S'], 'J': best['J'], 'S_interval': best.get('S_interval'),
            'J_interval': best.get('J_interval'), 'improvement': best.get('improvement')}


@dataclass
class MvVerdictStudy:
    """Every run's answers under each rule of :data:`RULES`."""

    first_seed: int
    per_case: int
    rows: list
    seconds: float

    def tally(self, rule: str, rows: list | None = None) -> dict:
        """
        Return the counts of ``rule`` (a key of :data:`RULES`) and its scores.

        ``wrong``: decided against the truth.  ``balanced`` counts ``cannot
        tell`` as no stiction (a refusal earns nothing, as docs/ACCURACY.md
        scores the plant loops); ``balanced_decided`` scores the decided only.
        """
        rows = self.rows if rows is None else rows
        out: dict = {'records': len(rows)}
        for label in ('stiction', 'no stiction'):
            sub = [r for r in rows if r['truth'] == label]
            out[label] = {a: sum(r[rule] == a for r in sub) for a in ANSWERS}
        sticky, healthy = out['stiction'], out['no stiction']
        out['wrong'] = sticky['no stiction'] + healthy['stiction']
        out['cannot_tell'] = sticky['cannot tell'] + healthy['cannot tell']
        out['errors'] = sum(r[rule] == 'error' for r in rows)
        out['balanced'] = _balanced(sticky['stiction'], sum(sticky.values()),
                                    healthy['no stiction'] + healthy['cannot tell'],
                                    sum(healthy.values()))
        out['balanced_decided'] = _balanced(
            sticky['stiction'], sticky['stiction'] + sticky['no stiction'],
            healthy['no stiction'], healthy['no stiction'] + healthy['stiction'])
        return out

    def by_case(self) -> list[dict]:
        """Return one row per case: truth, and each rule's answers."""
        out = []
        for case in dict.fromkeys(r['case'] for r in self.rows):
            sub = [r for r in self.rows if r['case'] == case]
            codes: dict[str, int] = {}
            for r in sub:
                if r['cannot_tell']:
                    codes[r['cannot_tell']] = codes.get(r['cannot_tell'], 0) + 1
            out.append({'case': case, 'truth': sub[0]['truth'], 'records': len(sub),
                        **{rule: {a: sum(r[rule] == a for r in sub) for a in ANSWERS}
                           for rule in RULES},
                        'codes': codes})
        return out

    def by_noise(self) -> list[dict]:
        """Return the tallies of every rule at each extra MV noise (0, 1 and 2 %)."""
        out = []
        for extra in EXTRA_MV_NOISE:
            sub = [r for r in self.rows if r['extra_mv_noise'] == extra]
            if sub:
                out.append({'extra_mv_noise': extra,
                            **{rule: self.tally(rule, sub) for rule in RULES}})
        return out

    def to_json(self) -> dict:
        """Return the study as a JSON-able dict."""
        return {'first_seed': self.first_seed, 'per_case': self.per_case,
                'seconds': round(self.seconds, 1),
                **{rule: self.tally(rule) for rule in RULES}, 'by_case': self.by_case(),
                'by_noise': self.by_noise(), 'rows': self.rows}


def _balanced(tp: int, pos: int, tn: int, neg: int) -> float | None:
    if not pos or not neg:
        return None
    return round(0.5 * (tp / pos + tn / neg), 4)


def run(per_case: int, first_seed: int, jobs: int = 1,
        say: Callable[[int, int, float], None] | None = None,
        family: str = 'instrument') -> MvVerdictStudy:
    """Return the study of ``per_case`` seeds of every case of ``family`` from ``first_seed``."""
    t0, rows = time.perf_counter(), []
    todo = runs(per_case, first_seed, family)
    for i, row in enumerate(pool_map(read, todo, jobs, chunksize=2), 1):
        rows.append(row)
        if say is not None:
            say(i, len(todo), time.perf_counter() - t0)
    return MvVerdictStudy(first_seed, per_case, rows, time.perf_counter() - t0)
