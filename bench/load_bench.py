"""
Load: many loops at once, each in its own namespace, recorded into one bag (``make bench-load``).

Each loop is the Table 2.1 undershoot loop on wall time, at a 0.1 s
sample time (10 Hz, ten times the chapter's rate) and at the chapter's 1 s:
plant, controller and valve as three node processes that save their state
after every sample, and one
recorder for every loop's sp, op, mv, pv and held_inputs.  After every node
has acted once, a window of ``--seconds`` is measured:

- rate: messages per second of each node's output, from the bag;
- lateness: how long after its phase instant each message left (its send
  stamp in the bag minus ``(k + phase) Ts``), p50, p99 and max over all
  nodes, and the share within 1 ms and within a quarter sample (the scan
  order holds when a message leaves within a quarter sample);
- missed: samples of the window with no message from a node;
- lost: messages the recorder did not get, from the gaps in each
  publisher's sequence numbers (the recorder counts them);
- CPU: the loop's three processes' CPU seconds per second of the window
  (``/proc``), and the recorder's.

The baseline is one loop measured the same way in the same run; the ratios
are the figures to compare.  The section it writes into docs/BENCHMARKS.md is
kept when ``make bench`` rewrites the rest.
"""

import argparse
import datetime
import os
from pathlib import Path
import re
import sys
import tempfile
import time

import numpy as np
from stiction_ros.bag.reader import read_bag
from stiction_ros.cli.loop import node_command, Processes
from stiction_ros.cli.study import machine_description
from stiction_ros.nodes import state_file
from stiction_ros.resources import config_file
from stiction_ros.sim.loop_config import load_loop
from stiction_ros.sim.ros_params import LOOP_NODES, params_file, PHASES
import yaml

ROOT = Path(__file__).resolve().parents[1]
BENCH = ROOT / 'docs' / 'BENCHMARKS.md'
START, END = '<!-- load-bench: start -->', '<!-- load-bench: end -->'
OUTPUT = {'plant': 'pv', 'controller': 'op', 'valve': 'mv'}
LOST = re.compile(r'(\d+) lost on the way .*?\), (\d+) sent before the recorder subscribed')
TICK = os.sysconf('SC_CLK_TCK')


def _cpu_seconds(pid):
    try:
        fields = Path(f'/proc/{pid}/stat').read_text().rsplit(')', 1)[1].split()
    except OSError:
        return float('nan')
    return (int(fields[11]) + int(fields[12])) / TICK


def _has_acted(path):
    # The state file exists from the start; it holds a state after the first sample.
    try:
        return state_file.read(path)['k'] >= 0
    except (state_file.StateFileError, KeyError, TypeError):
        return False


def run_loops(n_loops, seconds, sample_time=0.1, say=print):
    """Run ``n_loops`` loops for a window of ``seconds``; return the measured figures."""
    env = dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST',
               ROS_DOMAIN_ID=os.environ.get('STICTION_BENCH_DOMAIN', '88'), PYTHONPATH=str(ROOT))
    cfg = load_loop(config_file('concentration_loop.yaml'), 'undershoot',
                    {'sample_time': sample_time})
    work = Path(tempfile.mkdtemp(prefix='stiction_load_'))
    spaces = [f'/loop{i:02d}' for i in range(n_loops)]
    bag = work / 'bag'
    topics = [f'{ns}/{t}' for ns in spaces for t in ('sp', 'op', 'mv', 'pv', 'held_inputs')]
    rec_params = work / 'recorder.yaml'
    rec_params.write_text(yaml.safe_dump({'/recorder': {'ros__parameters': {
        'output': str(bag), 'topics': topics, 'depth': 10000}}}))
    procs = Processes(work)
    procs.start('recorder', node_command('recorder', '', rec_params), env)
    time.sleep(3.0)
    pids = {}
    # One loop at a time: sixty processes importing at once starve the ones running.
    for ns in spaces:
        params = work / f'{ns.strip("/")}.yaml'
        params.write_text(params_file(cfg, ns), encoding='utf-8')
        keys = []
        for name in LOOP_NODES:
            key = f'{ns.strip("/")}_{name}'
            state = work / f'{key}.state'
            procs.start(key, node_command(name, ns, params, [
                '-p', 'use_sim_time:=false', '-p', f'state_file:={state}']), env)
            pids[key] = procs.procs[key][0].pid
            keys.append(key)
        deadline = time.monotonic() + 120
        while not all(_has_acted(work / f'{key}.state') for key in keys):
            if time.monotonic() > deadline or procs.failed():
                procs.stop(list(procs.procs))
                raise RuntimeError(f'load: {ns} did not start; logs in {work}')
            time.sleep(0.2)
    say(f'load: {3 * n_loops} loop nodes and a recorder running')
    time.sleep(2.0)
    cpu0 = {key: _cpu_seconds(pid) for key, pid in pids.items()}
    rec0 = _cpu_seconds(procs.procs['recorder'][0].pid)
    t0 = time.time()
    say(f'load: all running; measuring {seconds:g} s')
    time.sleep(seconds)
    t1 = time.time()
    cpu1 = {key: _cpu_seconds(pid) for key, pid in pids.items()}
    rec1 = _cpu_seconds(procs.procs['recorder'][0].pid)
    procs.stop([k for k in procs.procs if k != 'recorder'], timeout=30.0)
    procs.stop(['recorder'], timeout=60.0)
    return _figures(read_bag(bag), work, spaces, sample_time, (t0, t1),
                    {k: cpu1[k] - cpu0[k] for k in pids}, rec1 - rec0)


def _figures(got, work, spaces, ts, window, cpu, rec_cpu):
    t0, t1 = window
    span = t1 - t0
    late, rates, missed = [], [], 0
    log = (work / 'recorder.log').read_text(errors='replace')
    found = LOST.search(log)
    lost = int(found.group(1)) if found else -1
    early = int(found.group(2)) if found else -1
    for ns in spaces:
        for name in LOOP_NODES:
            topic = got.topic(f'{ns}/{OUTPUT[name]}')
            sent = topic.publish_time / 1e9
            inside = sent[(sent >= t0) & (sent < t1)]
            k = np.floor(inside / ts)
            late.append((inside - (k + PHASES[name]) * ts) * 1e3)
            rates.append(len(inside) / span)
            first, last = int(np.ceil(t0 / ts)), int(np.floor(t1 / ts)) - 1
            missed += max((last - first + 1) - len(np.unique(k)), 0)
    late = np.concatenate(late)
    loop_cpu = [sum(cpu[f'{ns.strip("/")}_{n}'] for n in LOOP_NODES) / span for ns in spaces]
    return {
        'loops': len(spaces), 'seconds': span, 'sample_time': ts,
        'messages': sum(t.count for t in got.topics.values()),
        'rate_min': min(rates), 'rate_mean': float(np.mean(rates)),
        'late_p50': float(np.percentile(late, 50)), 'late_p99': float(np.percentile(late, 99)),
        'late_max': float(late.max()), 'within_1ms': float(np.mean(late <= 1.0)),
        'within_quarter': float(np.mean(late <= 250.0 * ts)),
        'missed': int(missed), 'lost': lost, 'before_match': early,
        'cpu_per_loop': float(np.mean(loop_cpu)), 'cpu_per_loop_max': float(max(loop_cpu)),
        'recorder_cpu': rec_cpu / span, 'complete': got.complete,
        'node_samples': (len(spaces) * len(LOOP_NODES)
                         * (int(np.floor(t1 / ts)) - int(np.ceil(t0 / ts)))),
    }


def markdown(runs, command):
    """Return the report section (between the markers) as lines; ``runs``: [(base, load)]."""
    def row(name, r):
        return (f'| {name} | {r["sample_time"]:g} | {r["loops"]} | {r["rate_mean"]:.3f} (min '
                f'{r["rate_min"]:.3f}) | {r["late_p50"]:.2f} / {r["late_p99"]:.2f} / '
                f'{r["late_max"]:.1f} | {100 * r["within_1ms"]:.1f} % | '
                f'{100 * r["within_quarter"]:.2f} % | {r["missed"]} | {r["lost"]} | '
                f'{r["before_match"]} | {100 * r["cpu_per_loop"]:.2f} % | '
                f'{100 * r["recorder_cpu"]:.1f} % |')
    lines = [
        START,
        '## Load: many loops in separate namespaces, one bag',
        '',
        f'Machine: {machine_description()}. Date: {datetime.date.today().isoformat()}. '
        f'Command: `{command}`.',
        '',
        "Table 2.1's undershoot loop on wall time at each sample time Ts, three node",
        'processes per loop (each saving its state every sample), one recorder for all of',
        'them; measured over a window that starts once every node has acted. Lateness: a',
        "message's send stamp minus its phase instant (all nodes, ms). Missed: samples of",
        'the window without a message from a node. Lost: messages the recorder did not get',
        "(gaps in the publishers' sequence numbers, over the whole run); before match:",
        "messages sent before the recorder's subscription matched their publisher (a",
        "loop's first seconds). CPU: the three processes' CPU time per second, per loop",
        '(100 % = one core).',
        '',
        '| run | Ts (s) | loops | msgs/s per node | lateness p50 / p99 / max (ms) | '
        'within 1 ms | within Ts/4 | missed | lost | before match | CPU per loop | '
        'recorder CPU |',
        '|---|---|---|---|---|---|---|---|---|---|---|---|',
    ]
    for base, load in runs:
        lines += [row(f'baseline, {base["seconds"]:.0f} s', base),
                  row(f'load, {load["seconds"]:.0f} s', load)]
    lines.append('')
    for base, load in runs:
        ts = load['sample_time']
        lines += [
            f'Ts {ts:g} s: ratios load / baseline: lateness p99 '
            f'{load["late_p99"] / base["late_p99"]:.2f}, CPU per loop '
            f'{load["cpu_per_loop"] / base["cpu_per_loop"]:.2f}; {load["messages"]} messages in '
            f'the bag, complete: {load["complete"]}. Bound: every node within '
            f'{100 * max(0.0, 1 - load["rate_min"] * ts):.2f} % of its rate '
            f'({load["rate_min"]:.3f} msgs/s at least, for {1 / ts:g}); '
            f'{100 * load["missed"] / max(load["node_samples"], 1):.2f} % of node-samples '
            'missed.',
            '']
    lines.append(END)
    return lines


def write_section(lines, path=BENCH, markers=(START, END)):
    """Put the section (between ``markers``) into the report, replacing an older one."""
    start, end = markers
    text = path.read_text(encoding='utf-8') if path.exists() else '# Benchmarks\n'
    block = '\n'.join(lines)
    if start in text and end in text:
        a, b = text.index(start), text.index(end) + len(end)
        text = text[:a] + block + text[b:]
    else:
        text = text.rstrip('\n') + '\n\n' + block + '\n'
    path.write_text(text, encoding='utf-8')


def carried_section(path=BENCH, markers=(START, END)):
    """Return a section of the current report (for ``make bench``), or []."""
    start, end = markers
    text = path.read_text(encoding='utf-8') if path.exists() else ''
    if start not in text or end not in text:
        return []
    return text[text.index(start):text.index(end) + len(end)].splitlines()


def main(argv=None):
    """Run the baseline and the load; write the section of docs/BENCHMARKS.md."""
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[1])
    ap.add_argument('--loops', type=int, default=20)
    ap.add_argument('--seconds', type=float, default=600.0, help='measured window (default 600)')
    ap.add_argument('--baseline-seconds', type=float, default=60.0)
    ap.add_argument('--sample-time', type=float, nargs='+', default=[0.1, 1.0],
                    help='one run (baseline and load) per sample time, s (default: 0.1 1)')
    args = ap.parse_args(argv)
    say = lambda msg: print(msg, file=sys.stderr, flush=True)  # noqa: E731
    runs = []
    for ts in args.sample_time:
        base = run_loops(1, args.baseline_seconds, ts, say)
        say(f'load: baseline {base}')
        load = run_loops(args.loops, args.seconds, ts, say)
        say(f'load: {load}')
        runs.append((base, load))
    command = 'make bench-load' if argv is None and len(sys.argv) == 1 else \
        'python -m bench.load_bench ' + ' '.join(sys.argv[1:] if argv is None else argv)
    lines = markdown(runs, command)
    write_section(lines)
    print('\n'.join(lines))
    return 0 if all(load['lost'] == 0 for _, load in runs) else 1


if __name__ == '__main__':
    sys.exit(main())
