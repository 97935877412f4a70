"""
Run every benchmark and write docs/BENCHMARKS.md (``make bench``).

Each figure is paired with a baseline measured in the same run, and the
ratio is what to compare across machines: these machines are shared and
noisy.  Timings are the best of several repeats.
"""

import datetime
import os
from pathlib import Path
import subprocess
import sys
import tempfile
import time

from bench.analyzer_startup_bench import bench_analyzer_startup, markdown as \
    analyzer_startup_markdown
from bench.bag_bench import bench_bag, markdown as bag_markdown
from bench.batch_bench import bench_batch, markdown as batch_markdown
from bench.detector_bench import bench_detector, markdown as detector_markdown
from bench.explain_speed import bench_explain_speed, markdown as explain_markdown
from bench.host_state_bench import bench_host_state, markdown as host_state_markdown
from bench.host_state_bench import throughput
from bench.identify_bench import bench_identify, markdown as identify_markdown
from bench.live_bench import bench_live, markdown as live_markdown
from bench.load_bench import carried_section, END as LOAD_END, START as LOAD_START
from bench.loop_bench import bench_loop, markdown as loop_markdown
from bench.physical_bench import bench_physical, markdown as physical_markdown
from bench.startup_bench import bench_startup, markdown as startup_markdown
from bench.transport_bench import END as TRANSPORT_END, START as TRANSPORT_START
import numpy as np

from stiction_ros._jit import load_numba
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


MODEL_KW = {'kano': {'S': 5.0, 'J': 2.0}, 'choudhury': {'S': 5.0, 'J': 2.0},
            'he': {'S': 5.0, 'J': 2.0}, 'stenman': {'S': 5.0}}

# Run in a fresh interpreter with an empty numba cache: the first call compiles.
_FIRST_CALL = """
import sys, time
import numpy as np
t0 = time.perf_counter()
from stiction_ros.models import create
t1 = time.perf_counter()
for name in sys.argv[1:]:
    m = create(name, S=5.0) if name == 'stenman' else create(name, S=5.0, J=2.0)
    t = time.perf_counter()
    m.simulate(np.array([50.0, 51.0]))
    print(name, time.perf_counter() - t)
"""


def first_call_seconds():
    """Return {model: seconds of its first simulate() with nothing compiled yet}."""
    with tempfile.TemporaryDirectory() as cache:
        # Kernels built ahead of time would skip the compilation this measures.
        env = dict(os.environ, NUMBA_CACHE_DIR=cache, STICTION_ROS_JIT_ONLY='1')
        out = subprocess.run([sys.executable, '-c', _FIRST_CALL, *MODEL_KW], env=env,
                             capture_output=True, text=True, check=True, cwd=ROOT).stdout
    return {name: float(t) for name, t in (line.split() for line in out.splitlines())}


def bench_models(n=1_000_000, n_python=100_000, seconds=3.0):
    """Compiled simulate() of each data-driven model against its pure-Python kernel."""
    rng = np.random.default_rng(0)
    op = np.clip(50 + np.cumsum(rng.normal(0, 0.5, n)), 0, 100)
    first = first_call_seconds()
    # The reference: a compiled kernel bound by issue width like the models, timed
    # in turn with each for seconds, so that both meet the same moments of a host
    # that shares the core (bench/host_state_bench.py); the ratio is what to compare.
    y = np.empty(n)
    throughput(op[:10], y[:10])
    rows = []
    for name, kw in MODEL_KW.items():
        model = create(name, **kw)
        model.simulate(op[:10])
        fast, ratio = [], []
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            t0 = time.perf_counter()
            model.simulate(op)
            t1 = time.perf_counter()
            throughput(op, y)
            t2 = time.perf_counter()
            fast.append(t1 - t0)
            ratio.append((t2 - t1) / (t1 - t0))
        # The same model's pure-Python loop on a tenth of the samples (it runs at
        # about 3e5 samples/s); samples/s is what is compared.
        slow = best_time(lambda: model.simulate_reference(op[:n_python]), 2)
        same = bool(np.array_equal(model.simulate(op[:n_python]),
                                   model.simulate_reference(op[:n_python])))
        rows.append((name, n / min(fast), n / float(np.median(fast)), n_python / slow,
                     (n / min(fast)) / (n_python / slow), first[name], same,
                     float(np.median(ratio))))
    return rows


def main():
    """Run the benchmarks and write the report."""
    # The in-process figures are numba's kernels, as the nodes run them; the
    # analyzer start-up section measures the ones built ahead of time.
    load_numba()
    models = bench_models()
    host_state = bench_host_state()
    physical = bench_physical(best_time)
    loop = bench_loop(best_time)
    bag = bench_bag(best_time)
    # STICTION_BENCH_LIVE_SECONDS shortens the 10-minute live loop for a quick look.
    live = bench_live(float(os.environ.get('STICTION_BENCH_LIVE_SECONDS', 600)))
    ident = [bench_identify(best_time, m) for m in ('kano', 'choudhury')]
    ident.append(bench_identify(best_time, 'kano', 1_000_000))
    explain = bench_explain_speed()
    startup = bench_startup()
    analyzer_startup = bench_analyzer_startup()
    loops = ROOT.parent / 'shared' / 'data' / 'plant_loops'
    batch = bench_batch(loops) if loops.is_dir() else None
    detector = bench_detector(best_time, loops) if loops.is_dir() else None
    lines = [
        '# Benchmarks',
        '',
        f'Machine: {machine_description()}. Date: {datetime.date.today().isoformat()}.',
        'Command: `make bench`. Best of 3 repeats; the ratio against the baseline measured',
        'in the same run is the figure to compare.',
        '',
        '## Valve models: compiled `simulate()` vs the pure-Python kernel',
        '',
        'One core, 1 000 000 samples of a random walk, called for 3 s in turn with the'
        ' reference: "best" is the fastest call (a moment when the host left us the core,'
        ' see the next section), "median" the middle one. The pure-Python loop of the same'
        ' model on 100 000 samples (best of 2). "Same" checks the two outputs are equal'
        ' sample for sample. First call: the first `simulate()` in a fresh process with an'
        ' empty numba cache (compilation; later processes load the cache). "vs reference":'
        " the median over the calls of the model's speed over a compiled kernel bound by"
        ' issue width like the models (independent arithmetic per sample) timed right after'
        ' it; it moves with the host as the models do, so this ratio is the figure to'
        ' compare between runs and machines.',
        '',
        '| model | compiled samples/s, best | median | pure-Python samples/s | ratio (best) |'
        ' first call (s) | same | vs reference |',
        '|---|---|---|---|---|---|---|---|',
    ]
    lines += [f'| {n} | {f:.3g} | {m:.3g} | {s:.3g} | {r:.0f} | {c:.2f} |'
              f' {"yes" if same else "NO"} | {ref:.2f} |'
              for n, f, m, s, r, c, same, ref in models]
    lines += [
        '',
        'Target of issue 6: >= 3e8 samples/s per model on one core.',
        '',
    ]
    lines += host_state_markdown(host_state)
    lines += physical_markdown(physical)
    lines += identify_markdown(ident)
    lines += explain_markdown(explain)
    lines += startup_markdown(startup)
    lines += analyzer_startup_markdown(analyzer_startup)
    lines += loop_markdown(loop)
    lines += bag_markdown(bag)
    lines += live_markdown(live)
    if batch:
        lines += [''] + batch_markdown(batch, 'The labelled plant loops of ../shared/data')
    if detector:
        lines += [''] + detector_markdown(detector)
    # The load benchmark (make bench-load) takes a quarter of an hour, and the transport
    # comparison (bench.transport_bench) is run on its own: their sections stay.
    for markers in ((LOAD_START, LOAD_END), (TRANSPORT_START, TRANSPORT_END)):
        carried = carried_section(markers=markers)
        if carried:
            lines += [''] + carried
    out = ROOT / 'docs' / 'BENCHMARKS.md'
    out.write_text('\n'.join(lines), encoding='utf-8')
    print(out.read_text())


if __name__ == '__main__':
    main()
