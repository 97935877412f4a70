"""
``--explain``'s clock-skew reading on seeds it was never built on.

A closed loop of ``concealed_case('none', seed)`` (a Kano valve, 1 s
sampling), its position read by a frictionless valve (MV = OP) or by the
sticky valve itself, plus 0.1 % noise, shifted by -2 (late), 0, 1, 2, 3 and 5
samples (ahead of OP, which no valve can be).  Counted: leads read to within
half a sample, clock skews named where MV is on time or late, a calibration
named beside a lead, and the friction answer.  Run:
``python -m bench.lead_check`` (about 2 min on 2 cores); it prints, and
writes nothing.
"""

from concurrent.futures import ProcessPoolExecutor
import time

import numpy as np

from stiction_ros.analysis.mismatch import decide, instrument as ins
from stiction_ros.sim.concealed_cases import concealed_case

SEEDS = (910001, 910002, 910003)
LEADS = (-2, 0, 1, 2, 3, 5)


def one(args: tuple) -> dict:
    """Return what ``--explain`` made of one valve read ``lead`` samples ahead."""
    kind, lead, seed = args
    d, _ = concealed_case('none', seed, noise=1.0, family='kano')
    n = len(d['op'])
    whole = [(0, n)]
    noise = 0.1 * np.random.default_rng(seed + 17).standard_normal(n)
    position = d['mv_true'] if kind == 'sticky' else d['op']
    mv = ins.shift(position, -float(lead), whole) + noise
    report, _ = decide.explain_record(d['t'], d['op'], mv, whole, 1.0, reps=1)
    m = report['mismatch']
    return {'kind': kind, 'lead': lead, 'seed': seed,
            'found': (report.get('clock_skew') or {}).get('samples'),
            'effects': [e['id'] for e in m['effects']], 'friction': m['friction']}


def main() -> None:
    """Run every case on two processes and print the counts."""
    t0 = time.perf_counter()
    jobs = [(k, lead, s) for k in ('healthy', 'sticky') for lead in LEADS for s in SEEDS]
    with ProcessPoolExecutor(2) as pool:
        rows = list(pool.map(one, jobs))
    ahead = [r for r in rows if r['lead'] > 0]
    right = sum(r['found'] is not None and abs(r['found'] - r['lead']) <= 0.5 for r in ahead)
    false = sum(r['found'] is not None for r in rows if r['lead'] <= 0)
    calibration = sum('positioner_calibration' in r['effects'] for r in ahead)
    sticky = sum(bool(r['friction']) for r in rows if r['kind'] == 'sticky')
    healthy = sum(not r['friction'] for r in rows if r['kind'] == 'healthy')
    per_kind = len(LEADS) * len(SEEDS)
    print(f'leads read right: {right}/{len(ahead)}; clock skew named where MV is on time '
          f'or late: {false}/{len(rows) - len(ahead)}; calibration named beside a lead: '
          f'{calibration}; stiction claimed on the sticky valve {sticky}/{per_kind}, not on '
          f'the healthy one {healthy}/{per_kind}; {time.perf_counter() - t0:.0f} s')


if __name__ == '__main__':
    main()
