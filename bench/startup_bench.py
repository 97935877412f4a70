"""
Start-up: how long a node takes to its first message, with its kernels compiled or cached.

A node process is started and timed until an rclpy subscriber in this process
hears its first message (``valve``: ``mv``; ``plant``: ``pv``), on wall time
at 20 Hz.  "Compiling": numba's cache directory is empty, as after an install
that skipped ``stiction-precompile``; "cached": the same directory after
``stiction-precompile`` filled it.  The baseline is ``python -c pass``.

Every process here keeps DDS on this machine and on its own domain.
"""

import os
import subprocess
import sys
import tempfile
import time

import rclpy
from rclpy.executors import SingleThreadedExecutor
from std_msgs.msg import Float64

from stiction_ros.nodes.sampled import DATA_QOS

TOPIC = {'valve': 'mv', 'plant': 'pv'}


def _env(cache):
    env = dict(os.environ, NUMBA_CACHE_DIR=cache)
    env.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    return env


def _first_message(node, name, cache, timeout=120.0):
    """Return seconds from starting node ``name`` to its first message."""
    ns = f'/startup_{os.getpid()}_{time.monotonic_ns()}'
    heard = []
    sub = node.create_subscription(Float64, f'{ns}/{TOPIC[name]}',
                                   lambda m: heard.append(time.perf_counter()), DATA_QOS)
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    module = f'stiction_ros.nodes.{name}_node'
    t0 = time.perf_counter()
    proc = subprocess.Popen([sys.executable, '-m', module, '--ros-args', '-r', f'__ns:={ns}',
                             '-p', 'sample_time:=0.05'], env=_env(cache),
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        while not heard and time.perf_counter() - t0 < timeout:
            executor.spin_once(timeout_sec=0.01)
    finally:
        proc.send_signal(2)
        proc.wait(30)
        executor.remove_node(node)
        node.destroy_subscription(sub)
    if not heard:
        raise RuntimeError(f'{name} sent nothing in {timeout} s')
    return heard[0] - t0


def _python_pass():
    t0 = time.perf_counter()
    subprocess.run([sys.executable, '-c', 'pass'], check=True)
    return time.perf_counter() - t0


def bench_startup(repeats=3):
    """Return {'python': s, 'nodes': [(name, compiling s, cached s)], 'precompile': s}."""
    # This process is a ROS node too: DDS stays on this machine (read at init).
    os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    rclpy.init()
    node = rclpy.create_node('startup_bench')
    rows = []
    try:
        python = min(_python_pass() for _ in range(repeats))
        for name in TOPIC:
            cold = []
            for _ in range(repeats):
                with tempfile.TemporaryDirectory(prefix='numba_cold_') as cache:
                    cold.append(_first_message(node, name, cache))
            rows.append([name, min(cold)])
        with tempfile.TemporaryDirectory(prefix='numba_warm_') as cache:
            t0 = time.perf_counter()
            subprocess.run([sys.executable, '-m', 'stiction_ros.cli.precompile'], env=_env(cache),
                           check=True, stderr=subprocess.DEVNULL)
            precompile = time.perf_counter() - t0
            for row in rows:
                row.append(min(_first_message(node, row[0], cache) for _ in range(repeats)))
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
    return {'python': python, 'nodes': [tuple(r) for r in rows], 'precompile': precompile}


def markdown(r):
    """Return the report lines."""
    lines = [
        '## Node start-up: kernels compiled at install vs at first start',
        '',
        'Seconds from starting a node process to its first message, heard by a subscriber in',
        'the benchmark (wall time, 20 Hz; best of 3). "Compiling": an empty numba cache, as',
        'after an install without `stiction-precompile`; "cached": after it. Baseline:',
        f'`python -c pass` {r["python"]:.3f} s. `stiction-precompile` itself took'
        f' {r["precompile"]:.1f} s (tools/bootstrap.sh and `colcon build` run it).',
        '',
        '| node | compiling (s) | cached (s) | ratio | cached / python -c pass |',
        '|---|---|---|---|---|',
    ]
    lines += [f'| {n} | {c:.2f} | {w:.2f} | {c / w:.1f} | {w / r["python"]:.0f} |'
              for n, c, w in r['nodes']]
    return lines + ['']


if __name__ == '__main__':
    print('\n'.join(markdown(bench_startup())))
