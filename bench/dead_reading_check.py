"""
The still-valve set-point test on simulated loops it was never tuned on.

Each plain loop of the training corpus (``sim.corpus``: a linear valve, no
look-alike) of the seeds given is run twice: as drawn, its position read by
a dead transmitter (50 % and 0.1 % noise), and with its valve stuck (Kano,
S 100 %, which never breaks away).  Where MV reads still
(:func:`~stiction_ros.analysis.measures.still.still_valve`), the set-point
test (:func:`~stiction_ros.analysis.measures.still.set_point_test`) should
say the loop followed its set point in the first and ignored it in the
second.  Counted: decided, right, by loop type.  Run:
``python -m bench.dead_reading_check [FIRST LAST]`` (default 6700000 6704000,
the seeds the README quotes; 6500000-6500599 and 6600000-6602999 were looked
at while the test was designed); about 1 min on 2 cores; it prints, and
writes nothing.
"""

from concurrent.futures import ProcessPoolExecutor
from dataclasses import replace
import sys

import numpy as np

from stiction_ros.analysis.measures.still import set_point_test, still_valve
from stiction_ros.sim.corpus import draw_scenario, simulate


def one(seed: int) -> list[tuple]:
    """Return (loop type, case, still, answer) for the dead reading and the stuck valve."""
    sc = draw_scenario(seed)
    if sc.valve != 'linear' or sc.look_alike:
        return []
    kind = 'integrating' if sc.integrating else 'self-regulating'
    rec = simulate(sc)
    n = len(rec['op'])
    whole = [(0, n)]
    dead = 50.0 + 0.1 * np.random.default_rng(seed).standard_normal(n)
    stuck = simulate(replace(sc, valve='kano', S=100.0, J=0.0, label=True))
    out = []
    for case, d, mv, right in (('dead reading', rec, dead, True),
                               ('stuck valve', stuck, stuck['mv'], False)):
        still = still_valve(d['op'], mv, whole) is not None
        test = set_point_test(d['pv'], d['sp'], whole) if still else None
        out.append((kind, case, still, None if test is None else test.follows == right))
    return out


def main(argv: list[str]) -> int:
    """Print what the test decided, and how often right, per case and loop type."""
    first, last = (int(argv[0]), int(argv[1])) if len(argv) == 2 else (6_700_000, 6_704_000)
    with ProcessPoolExecutor(2) as pool:
        rows = [r for rs in pool.map(one, range(first, last), chunksize=16) for r in rs]
    print(f'seeds {first}-{last - 1}: {len(rows) // 2} plain loops')
    for case in ('dead reading', 'stuck valve'):
        for kind in ('self-regulating', 'integrating', None):
            sel = [r for r in rows if r[1] == case and (kind is None or r[0] == kind)
                   and r[2]]
            told = [r for r in sel if r[3] is not None]
            right = sum(r[3] for r in told)
            print(f'{case:13s} {kind or "all":16s} read still {len(sel):4d}, decided '
                  f'{len(told):3d}, right {right:3d}')
    return 0


if __name__ == '__main__':
    raise SystemExit(main(sys.argv[1:]))
