"""
Physical valve at a 1 ms loop step: the compiled exact integrator against 100 substeps.

Accuracy is measured against a third run with 10 000 substeps per sample
(1e-7 s), two orders finer than the baseline, on the first 4 s.
"""

import numpy as np

from stiction_ros.models import create

# A fast I/P (0.2 s) and a wide sine, so the stem sticks and slides every cycle.
KW = {'sample_time': 1e-3, 'tau_ip': 0.2}


def bench_physical(best_time, n=200_000, n_check=4000):
    """Return a dict of µs per sample and errors (% of travel) of each integrator."""
    op = 50 + 40 * np.sin(2 * np.pi * np.arange(n) * 1e-3 / 4.0)
    exact = create('physical', **KW)
    sub = create('physical', integrator='substep', substep=1e-5, **KW)
    fine = create('physical', integrator='substep', substep=1e-7, **KW)
    exact.simulate(op[:10])
    sub.simulate(op[:10])
    n_sub = n // 10
    y_fine = fine.simulate(op[:n_check])
    y_exact = exact.simulate(op[:n_check])
    return {
        'exact_us': best_time(lambda: exact.simulate(op), 5) / n * 1e6,
        'python_us': best_time(lambda: exact.simulate_reference(op[:n_sub // 10]), 1)
        / (n_sub // 10) * 1e6,
        'substep_us': best_time(lambda: sub.simulate(op[:n_sub]), 3) / n_sub * 1e6,
        'err_exact': float(np.abs(y_exact - y_fine).max()),
        'err_substep': float(np.abs(sub.simulate(op[:n_check]) - y_fine).max()),
        'python_gap': float(np.abs(exact.simulate_reference(op[:n_check]) - y_exact).max()),
        'moved': float(np.ptp(y_exact)),
    }


def markdown(r):
    """Return the report lines."""
    ratio = r['substep_us'] / r['exact_us']
    return [
        '## Physical valve at a 1 ms loop step',
        '',
        '| integrator | µs per sample | max error vs 10 000 substeps (% of travel) |',
        '|---|---|---|',
        f'| exact, compiled (event-driven matrix exponentials) | {r["exact_us"]:.3f} | '
        f'{r["err_exact"]:.2g} |',
        f'| exact, pure-Python reference | {r["python_us"]:.2f} | same to {r["python_gap"]:.1g} |',
        f'| 100 semi-implicit substeps of 10 µs (baseline, numba) | {r["substep_us"]:.3f} | '
        f'{r["err_substep"]:.2g} |',
        '',
        f'Ratio {ratio:.0f}x (baseline time / exact time). Target of issue 6: <= 0.2 µs per',
        'sample at the accuracy of 100 substeps. Input: sine 50 ± 40 %, period 4 s, I/P lag',
        '0.2 s, 200 000 samples; over the first 4 s, where the errors are measured, the stem',
        f'travels {r["moved"]:.1f} %. Between friction events a sample of sliding is one product',
        'with a tabulated matrix exponential, stuck a closed-form breakaway test; events are',
        'timed by bisection to 1e-10 s. The substep integrator stays for the frictions the',
        'exact one cannot carry (Stribeck, dwell, asymmetry, first-order hold).',
        '',
    ]
