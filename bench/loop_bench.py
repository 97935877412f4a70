"""
Offline closed loop, Table 2.1's undershoot case: compiled loop against the per-sample loop.

The compiled loop (``loop_kernel``) runs 1e6 samples; the per-sample Python
loop that steps the controller, valve and plant objects runs 1e5 (it is about
30x slower); samples per second are compared, and the two outputs over the
first 1e5 samples are checked equal bit for bit.
"""

import numpy as np

from stiction_ros.resources import config_file
from stiction_ros.sim.closed_loop import simulate_loop
from stiction_ros.sim.loop_config import load_loop


def bench_loop(best_time, n=1_000_000, n_python=100_000):
    """Return a dict of samples/s of each loop and whether they agree."""
    cfg = load_loop(config_file('concentration_loop.yaml'), 'undershoot',
                    {'noise': {'pv_std': 0.02, 'seed': 1}})
    simulate_loop(cfg, duration=10.0)
    fast = best_time(lambda: simulate_loop(cfg, duration=n - 1.0), 3)
    slow = best_time(lambda: simulate_loop(cfg, duration=n_python - 1.0, compiled=False), 1)
    a = simulate_loop(cfg, duration=n_python - 1.0)
    b = simulate_loop(cfg, duration=n_python - 1.0, compiled=False)
    return {'n': n, 'compiled': n / fast, 'python': n_python / slow,
            'same': all(np.array_equal(a[k], b[k]) for k in b)}


def markdown(r):
    """Return the report lines."""
    return [
        '## Offline closed loop (Table 2.1 undershoot case)',
        '',
        '| loop | samples/s |',
        '|---|---|',
        f'| compiled (`loop_kernel`), {r["n"]:.0e} samples | {r["compiled"]:.3g} |',
        f'| per-sample Python loop (baseline), 1e5 samples | {r["python"]:.3g} |',
        '',
        f'Ratio {r["compiled"] / r["python"]:.0f}x; outputs over 1e5 samples '
        f'{"equal bit for bit" if r["same"] else "DIFFERENT"}. Choudhury valve S = 5, J = 2,',
        'plant 3 e^-10s / (10 s + 1), PI 0.2 (1 + 1/10 s), PV noise 0.02, Ts = 1 s.',
        'Target of issue 6: >= 1e6 samples/s.',
        '',
    ]
