"""
``--explain``'s clock-skew reading on seeds it was never built on.

A closed loop of ``concealed_case('none', seed)`` (a Kano valve, 1 s
sampling), its position read by a frictionless valve (MV = OP) or by the
sticky valve itself, directly or through a first-order lag of 3 s (a slow
transmitter; its own seeds), plus 0.1 % noise, shifted by -2 (late), 0, 1, 2,
3 and 5 samples (ahead of OP, which no valve can be).  Counted: leads read to
within half a sample, clock skews named where MV is on time or late, a
calibration named beside a lead, and the friction answer.  Run:
``python -m bench.lead_check`` (about 5 min on 2 cores); it prints, and
writes nothing.
"""

from concurrent.futures import ProcessPoolExecutor
import time

import numpy as np
from scipy.signal import lfilter

from stiction_ros.analysis.mismatch import decide, instrument as ins
from stiction_ros.sim.concealed_cases import concealed_case

SEEDS = (910001, 910002, 910003)
# Drawn after the lag search was changed, for the lagged readings alone.
LAG_SEEDS = (910011, 910012, 910013)
LEADS = (-2, 0, 1, 2, 3, 5)
KINDS = ('healthy', 'sticky', 'healthy+lag', 'sticky+lag')
LAG_S = 3.0


def one(args: tuple) -> dict:
    """Return what ``--explain`` made of one valve read ``lead`` samples ahead."""
    kind, lead, seed = args
    d, _ = concealed_case('none', seed, noise=1.0, family='kano')
    n = len(d['op'])
    whole = [(0, n)]
    noise = 0.1 * np.random.default_rng(seed + 17).standard_normal(n)
    position = d['mv_true'] if kind.startswith('sticky') else d['op']
    if kind.endswith('+lag'):
        a = np.exp(-1.0 / LAG_S)
        position = lfilter([1.0 - a], [1.0, -a], position - position[0]) + position[0]
    mv = ins.shift(position, -float(lead), whole) + noise
    report, _ = decide.explain_record(d['t'], d['op'], mv, whole, 1.0, reps=1)
    m = report['mismatch']
    return {'kind': kind, 'lead': lead, 'seed': seed,
            'found': (report.get('clock_skew') or {}).get('samples'),
            'effects': [e['id'] for e in m['effects']], 'friction': m['friction']}


def main() -> None:
    """Run every case on two processes and print the counts."""
    t0 = time.perf_counter()
    jobs = [(k, lead, s) for k in KINDS for lead in LEADS
            for s in (LAG_SEEDS if k.endswith('+lag') else SEEDS)]
    with ProcessPoolExecutor(2) as pool:
        rows = list(pool.map(one, jobs))
    for lagged in (False, True):
        part = [r for r in rows if r['kind'].endswith('+lag') == lagged]
        ahead = [r for r in part if r['lead'] > 0]
        right = sum(r['found'] is not None and abs(r['found'] - r['lead']) <= 0.5
                    for r in ahead)
        false = sum(r['found'] is not None for r in part if r['lead'] <= 0)
        calibration = sum('positioner_calibration' in r['effects'] for r in ahead)
        sticky = [bool(r['friction']) for r in part if r['kind'].startswith('sticky')]
        healthy = [not r['friction'] for r in part if r['kind'].startswith('healthy')]
        print(f'{"read through a 3 s lag" if lagged else "read directly"}: leads read right '
              f'{right}/{len(ahead)}; clock skew named where MV is on time or late: '
              f'{false}/{len(part) - len(ahead)}; calibration named beside a lead: '
              f'{calibration}; stiction claimed on the sticky valve {sum(sticky)}/'
              f'{len(sticky)}, not on the healthy one {sum(healthy)}/{len(healthy)}')
    print(f'{time.perf_counter() - t0:.0f} s')


if __name__ == '__main__':
    main()
