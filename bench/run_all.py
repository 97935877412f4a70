"""
Run every benchmark and write docs/BENCHMARKS.md (``make bench``).

Each figure is paired with a baseline measured in the same run, and the
ratio is what to compare across machines: these machines are shared and
noisy.  Timings are the best of several repeats.
"""

import datetime
from pathlib import Path
import time

from bench.identify_bench import bench_identify, markdown as identify_markdown
import numpy as np

from stiction_ros.cli.study import machine_description
from stiction_ros.models import create

ROOT = Path(__file__).resolve().parents[1]


def best_time(fn, repeats=3):
    """Return the shortest wall time of ``repeats`` calls of ``fn``."""
    best = float('inf')
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def bench_models(n=200_000):
    """simulate() of each data-driven model against a per-sample step() loop."""
    rng = np.random.default_rng(0)
    op = np.clip(50 + np.cumsum(rng.normal(0, 0.5, n)), 0, 100)
    rows = []
    for name in ('kano', 'choudhury', 'he', 'stenman'):
        kw = {'S': 5.0} if name == 'stenman' else {'S': 5.0, 'J': 2.0}
        model = create(name, **kw)
        fast = best_time(lambda: model.simulate(op))

        def per_sample():
            model.reset()
            for u in op[: n // 10]:
                model.step(u)
        slow = best_time(per_sample) * 10
        rows.append((name, n / fast, n / slow, slow / fast))
    return rows


def bench_physical(n=20_000):
    """Physical model at a 1 ms loop step: exact integrator against 100 substeps."""
    # A fast I/P (0.2 s) and a wide sine, so the stem sticks and slides every cycle.
    op = 50 + 40 * np.sin(2 * np.pi * np.arange(n) * 1e-3 / 4.0)
    exact = create('physical', sample_time=1e-3, tau_ip=0.2)
    sub = create('physical', sample_time=1e-3, tau_ip=0.2, integrator='substep', substep=1e-5)
    moved = float(np.ptp(exact.simulate(op[: n // 10])))
    te = best_time(lambda: exact.simulate(op), 2) / n
    ts = best_time(lambda: sub.simulate(op[: n // 10]), 2) / (n // 10)
    gap = float(np.max(np.abs(exact.simulate(op[: n // 10]) - sub.simulate(op[: n // 10]))))
    return te, ts, gap, moved


def main():
    """Run the benchmarks and write the report."""
    models = bench_models()
    te, ts, gap, moved = bench_physical()
    ident = [bench_identify(best_time, m) for m in ('kano', 'choudhury')]
    lines = [
        '# Benchmarks',
        '',
        f'Machine: {machine_description()}. Date: {datetime.date.today().isoformat()}.',
        'Command: `make bench`. Best of 3 repeats; the ratio against the baseline measured',
        'in the same run is the figure to compare.',
        '',
        '## Valve models, `simulate()` vs a per-sample `step()` loop (200 000 samples)',
        '',
        '| model | simulate() samples/s | step() loop samples/s | ratio |',
        '|---|---|---|---|',
    ]
    lines += [f'| {n} | {f:.3g} | {s:.3g} | {r:.1f} |' for n, f, s, r in models]
    lines += [
        '',
        'Both run the same pure-Python kernel (no compilation yet); the ratio is the cost',
        'of the per-call overhead. The target of issue 6 is >= 3e8 samples/s compiled.',
        '',
        '## Physical valve at a 1 ms loop step',
        '',
        '| integrator | µs per sample |',
        '|---|---|',
        f'| exact (event-driven matrix exponentials) | {te * 1e6:.2f} |',
        f'| 100 semi-implicit substeps of 10 µs (baseline, numba) | {ts * 1e6:.2f} |',
        '',
        f'Ratio {ts / te:.1f}x. Input: sine 50 ± 40 %, period 4 s, I/P lag 0.2 s; over the',
        f'compared 2 s the stem travels {moved:.1f} % and the two integrators differ by at',
        f'most {gap:.2g} % of travel. The substep integrator is compiled by numba (it',
        'carries the Stribeck, dwell and asymmetric frictions, 10 000 substeps per sample',
        "in --explain's test cases); the exact one is plain Python and numpy, so the ratio",
        'below 1 says the compiled fixed-step loop is the faster at this step; the exact',
        'integrator stays the reference for event times (no discretisation error).',
        '',
    ]
    lines += identify_markdown(ident)
    out = ROOT / 'docs' / 'BENCHMARKS.md'
    out.write_text('\n'.join(lines), encoding='utf-8')
    print(out.read_text())


if __name__ == '__main__':
    main()
