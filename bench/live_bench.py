"""
Live benchmarks over real DDS: the loop at 100 Hz and 1 kHz, the recorder under a flood.

- Baseline: the rclpy publish/subscribe round trip between two processes.
- Live loop: Table 2.1's undershoot loop on wall time, plant, controller and
  valve as three node processes, recorded.  Each node acts at its phase of
  the sample (plant 1/4, controller 1/2, valve 3/4); from the send stamps in
  the bag, a cycle is on schedule when its message left within 1 ms of that
  instant, and a sample with no message is a missed cycle.  OP to MV latency
  is the valve's MV send time minus the send time of the newest OP sent before
  it (a quarter sample by design, plus the valve's timer jitter; more where
  the valve acted on an older OP); the transport delay is the recorder's
  receive time minus the send time.
- Recorder: 20 000 messages/s over five topics (four Float64 carrying their
  sequence number, one String) for 60 s into one bag; lossless when every
  sequence number is in the bag once, in order.  Its CPU time and bag size
  are compared with the ``mcap`` writer alone writing the same messages.

Every process here keeps DDS on this machine and on its own domain.
"""

import json
import os
from pathlib import Path
import signal
import subprocess
import sys
import tempfile
import time

from bench.ros_peers import FLOAT_TOPICS, TEXT_TOPIC
from mcap.writer import CompressionType, Writer
import numpy as np
from rclpy.serialization import serialize_message
from std_msgs.msg import Float64, String

from stiction_ros.bag.reader import read_bag
from stiction_ros.cli.loop import node_command, run_loop
from stiction_ros.resources import config_file
from stiction_ros.sim.loop_config import load_loop

ROOT = Path(__file__).resolve().parents[1]
PHASES = {'pv': 0.25, 'op': 0.5, 'mv': 0.75}


def ros_env():
    """Return the environment of the benchmark's ROS processes (and set it here)."""
    os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    os.environ.setdefault('ROS_DOMAIN_ID', os.environ.get('STICTION_BENCH_DOMAIN', '87'))
    return dict(os.environ, PYTHONPATH=str(ROOT))


def _peer(*args):
    return [sys.executable, '-m', 'bench.ros_peers', *map(str, args)]


def round_trip(n=3000):
    """Return (p50, p99) of the rclpy round trip between two processes, in µs."""
    env = ros_env()
    echo = subprocess.Popen(_peer('echo'), env=env, cwd=ROOT, stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)
    try:
        out = subprocess.run(_peer('ping', n), env=env, cwd=ROOT, capture_output=True,
                             text=True, check=True, timeout=300).stdout
    finally:
        echo.send_signal(signal.SIGINT)
        echo.wait(10)
    rtt = np.array([float(x) for x in out.split()])
    return {'n': rtt.size, 'p50': float(np.percentile(rtt, 50)),
            'p99': float(np.percentile(rtt, 99))}


def bare_timer(rate_hz, seconds):
    """
    Return how late a bare Python loop wakes at the middle of each sample (no ROS at all).

    The floor under every node: a process that only sleeps until its instant, on
    the same machine in the same run.
    """
    ts_ns = int(round(1e9 / rate_hz))
    n = int(seconds * rate_hz)
    late = np.empty(n)
    k0 = time.time_ns() // ts_ns + 1
    for i in range(n):
        target = (k0 + i) * ts_ns + ts_ns // 2
        wait = target - time.time_ns()
        if wait > 0:
            time.sleep(wait / 1e9)
        late[i] = (time.time_ns() - target) / 1e6
    return {'rate_hz': rate_hz, 'seconds': seconds, 'on_time': float(np.mean(late <= 1.0)),
            'p99_ms': float(np.percentile(late, 99)), 'max_ms': float(late.max()),
            'over_half': int(np.sum(late > 500.0 / rate_hz))}


def newest_input_age(inputs: np.ndarray, outputs: np.ndarray) -> np.ndarray:
    """
    Return, for each output stamp, its time since the newest input stamp at or before it.

    Outputs before the first input are left out.  Pairing each MV with the OP
    of its own send-time bin instead reads a negative latency once a late OP
    lands in the next bin (-0.87 ms at 1 kHz composed, 2026-11-26).
    """
    inputs = np.sort(np.asarray(inputs))
    outputs = np.asarray(outputs)
    newest = np.searchsorted(inputs, outputs, side='right') - 1
    return outputs[newest >= 0] - inputs[newest[newest >= 0]]


def live_loop(rate_hz, seconds, realtime_priority=0, composed=False):
    """
    Run the loop on wall time at ``rate_hz`` for ``seconds``; return schedule figures.

    ``composed``: plant, controller and valve in one process on one executor.
    """
    ros_env()
    cfg = load_loop(config_file('concentration_loop.yaml'), 'undershoot',
                    {'sample_time': 1.0 / rate_hz})
    with tempfile.TemporaryDirectory() as tmp:
        bag = run_loop(cfg, namespace=f'/bench{int(rate_hz)}', duration=seconds,
                       record=Path(tmp) / 'bag', log_dir=Path(tmp) / 'logs',
                       realtime_priority=realtime_priority, composed=composed)
        topics = read_bag(bag)
        sent = {k: topics.topic(k).publish_time for k in PHASES}
        got = {k: topics.topic(k).log_time for k in PHASES}
        # Nodes that returned to the normal scheduler (nodes/realtime.py: over a core).
        gave_up = sum('back on the normal scheduler' in p.read_text(errors='replace')
                      for p in (Path(tmp) / 'logs').glob('*.log'))
    ts = int(round(1e9 / rate_hz))
    first = max(int(v[0] // ts) for v in sent.values()) + 1
    last = min(int(v[-1] // ts) for v in sent.values()) - 1
    expected = last - first + 1
    out = {'rate_hz': rate_hz, 'seconds': seconds, 'samples': expected,
           'realtime_priority': realtime_priority, 'composed': composed,
           'fifo_given_up': gave_up}
    for name, stamps in sent.items():
        k = stamps // ts
        keep = (k >= first) & (k <= last)
        k, stamps = k[keep], stamps[keep]
        late = (stamps - k * ts - int(PHASES[name] * ts)) / 1e6
        uniq, idx = np.unique(k, return_index=True)
        on_time = int(np.sum(late[idx] <= 1.0))
        out[name] = {'missed': expected - uniq.size, 'on_time': on_time / expected,
                     'late_p99_ms': float(np.percentile(late, 99)),
                     'late_max_ms': float(late.max())}
    mv_sent = sent['mv'][(sent['mv'] // ts >= first) & (sent['mv'] // ts <= last)]
    op_mv = newest_input_age(sent['op'], mv_sent) / 1e6
    transport = (got['op'] - sent['op']) / 1e6
    out['op_to_mv_ms'] = (float(np.percentile(op_mv, 50)), float(np.percentile(op_mv, 99)))
    out['transport_ms'] = (float(np.percentile(transport, 50)),
                           float(np.percentile(transport, 99)))
    out['on_time'] = min(out[k]['on_time'] for k in PHASES)
    return out


def _cpu_seconds(pid):
    fields = Path(f'/proc/{pid}/stat').read_text().rsplit(')', 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf('SC_CLK_TCK')


def recorder_flood(rate=20000, seconds=60.0):
    """Flood the recorder; return loss, CPU and size figures, and the writer baseline."""
    env = ros_env()
    with tempfile.TemporaryDirectory() as tmp:
        bag = Path(tmp) / 'bag'
        topics = '[' + ','.join(FLOAT_TOPICS + (TEXT_TOPIC,)) + ']'
        params = Path(tmp) / 'empty.yaml'
        params.write_text('/**:\n  ros__parameters: {}\n', encoding='utf-8')
        cmd = node_command('recorder', '', params, [
            '-p', f'output:={bag}', '-p', f'topics:={topics}', '-p', 'depth:=100000'])
        log = open(Path(tmp) / 'recorder.log', 'wb')
        rec = subprocess.Popen(cmd, env=env, cwd=ROOT, stdout=log, stderr=subprocess.STDOUT)
        try:
            cpu0 = _cpu_seconds(rec.pid)
            flood = subprocess.run(_peer('flood', rate, seconds), env=env, cwd=ROOT,
                                   capture_output=True, text=True, timeout=seconds + 120)
            if flood.returncode != 0:
                raise RuntimeError(f'flood failed: {flood.stderr[-2000:]}')
            sent = json.loads(flood.stdout.strip().splitlines()[-1])
            time.sleep(2.0)
            cpu = _cpu_seconds(rec.pid) - cpu0
        finally:
            rec.send_signal(signal.SIGINT)
            rec.wait(60)
            log.close()
        size = sum(f.stat().st_size for f in bag.iterdir())
        got = read_bag(bag)
        lost = 0
        in_order = True
        for name, n in sent['counts'].items():
            topic = got.topics.get(name)
            count = topic.count if topic is not None else 0
            lost += n - count
            if name != TEXT_TOPIC and topic is not None:
                in_order &= bool(np.array_equal(topic.values(), np.arange(count, dtype=float)))
    total = sum(sent['counts'].values())
    writer_cpu, writer_size = writer_alone(sent['counts'], rate)
    return {'rate': rate, 'seconds': sent['seconds'], 'sent': total, 'lost': lost,
            'in_order': in_order, 'cpu': cpu, 'mb_per_min': size / 2**20 / (seconds / 60.0),
            'writer_cpu': writer_cpu, 'writer_mb_per_min': writer_size / 2**20 / (seconds / 60.0)}


def writer_alone(counts, rate):
    """Return (CPU s, bytes) of the ``mcap`` writer alone writing the flood's messages."""
    fmsg, smsg = Float64(), String()
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / 'alone.mcap'
        t0 = time.process_time()
        with open(path, 'wb') as f:
            w = Writer(f, chunk_size=262144, compression=CompressionType.ZSTD)
            w.start('ros2', 'bench')
            schema = w.register_schema('std_msgs/msg/Float64', 'ros2msg', b'float64 data\n')
            tschema = w.register_schema('std_msgs/msg/String', 'ros2msg', b'string data\n')
            chans = [w.register_channel(t, 'cdr', schema) for t in FLOAT_TOPICS]
            text = w.register_channel(TEXT_TOPIC, 'cdr', tschema)
            seq = [0] * 4
            total = sum(counts.values())
            for i in range(total):
                t = 10**9 + int(i * 1e9 / rate)
                if i % 10 == 9:
                    smsg.data = f'message {i}: status text of a typical length'
                    w.add_message(text, t, serialize_message(smsg), t)
                else:
                    j = (i % 10) % 4
                    fmsg.data = float(seq[j])
                    seq[j] += 1
                    w.add_message(chans[j], t, serialize_message(fmsg), t, sequence=seq[j])
            w.finish()
        return time.process_time() - t0, path.stat().st_size


# SCHED_FIFO priority of the loop nodes in the real-time runs (root or CAP_SYS_NICE).
RT_PRIORITY = 20


def bench_live(loop_seconds=600.0, short_seconds=60.0, flood_seconds=60.0):
    """Run every live benchmark; return the figures."""
    return {'round_trip': round_trip(),
            'bare': bare_timer(100.0, short_seconds),
            'loops': [live_loop(100.0, loop_seconds),
                      live_loop(100.0, 2 * short_seconds, RT_PRIORITY),
                      live_loop(1000.0, short_seconds),
                      live_loop(1000.0, short_seconds, RT_PRIORITY),
                      # Composition against the three processes above, same run.
                      live_loop(100.0, 2 * short_seconds, composed=True),
                      live_loop(100.0, 2 * short_seconds, RT_PRIORITY, composed=True),
                      live_loop(1000.0, short_seconds, composed=True)],
            'recorder': recorder_flood(20000, flood_seconds)}


def markdown(r):
    """Return the report lines."""
    rt = r['round_trip']
    lines = [
        '## Live loop over DDS (wall time)',
        '',
        f'Baseline: rclpy publish/subscribe round trip between two processes (Float64,'
        f' reliable, {rt["n"]} trips): p50 {rt["p50"]:.0f} µs, p99 {rt["p99"]:.0f} µs.',
        '',
        f'Floor: a bare Python loop (no ROS) sleeping until the middle of each 10 ms sample'
        f' for {r["bare"]["seconds"]:.0f} s woke within 1 ms {100 * r["bare"]["on_time"]:.2f} %'
        f' of the time (p99 {r["bare"]["p99_ms"]:.2f} ms, max {r["bare"]["max_ms"]:.1f} ms;'
        f' {r["bare"]["over_half"]} wake-ups more than half a sample late). This machine is a'
        ' 2-vCPU virtual machine whose host stalls it for milliseconds now and then; no'
        ' process on it, ROS or not, can keep 99.9 % of 10 ms cycles within 1 ms.',
        '',
        '| loop | processes | scheduler | run (s) | samples | cycles on schedule (within 1 ms,'
        ' none missed) | missed PV / OP / MV | late p99 PV / OP / MV (ms) | OP to MV p50 / p99'
        ' (ms) | DDS transport p50 / p99 (ms) |',
        '|---|---|---|---|---|---|---|---|---|---|',
    ]
    for x in r['loops']:
        sched = f'SCHED_FIFO {x["realtime_priority"]}' if x['realtime_priority'] else 'normal'
        if x.get('fifo_given_up'):
            sched += f' (given up by {x["fifo_given_up"]} node processes)'
        lines.append(
            f'| {x["rate_hz"]:.0f} Hz | {"1 (composed)" if x.get("composed") else "3"} |'
            f' {sched} | {x["seconds"]:.0f} | {x["samples"]} |'
            f' {100 * x["on_time"]:.3f} % | {x["pv"]["missed"]} / {x["op"]["missed"]} /'
            f' {x["mv"]["missed"]} | {x["pv"]["late_p99_ms"]:.2f} / {x["op"]["late_p99_ms"]:.2f}'
            f' / {x["mv"]["late_p99_ms"]:.2f} | {x["op_to_mv_ms"][0]:.2f} /'
            f' {x["op_to_mv_ms"][1]:.2f} | {x["transport_ms"][0]:.2f} /'
            f' {x["transport_ms"][1]:.2f} |')
    f = r['recorder']
    lines += [
        '',
        "Three node processes (plant, controller, valve) and the recorder, Table 2.1's"
        ' undershoot loop at that sample time. "On schedule": the message of every sample'
        ' left within 1 ms of its phase instant (plant 1/4, controller 1/2, valve 3/4 of the'
        ' sample); the worst of the three topics is shown. OP to MV: each MV against the'
        ' newest OP sent before it, a quarter sample by design (the valve acts 1/4 sample'
        ' after the controller), more where the valve acted on an older OP. On wall time each node'
        ' ticks once per sample just after its phase instant; a tick that comes after its'
        ' sample is over is a missed cycle. SCHED_FIFO: `loop --realtime-priority`. Target of'
        ' issue 6: >= 99.9 % at 100 Hz; 1 kHz attempted. "1 (composed)": the three nodes in'
        ' one process on one executor (`loop --composed`), against the three processes in'
        ' the same run; target of issue 21: >= 99 % within 1 ms at 100 Hz. "Given up": a'
        ' node under SCHED_FIFO that used over 90 % of a core for 3 s returns to the normal'
        ' scheduler, so that it cannot starve the machine (nodes/realtime.py).',
        '',
        '## Recorder under a flood',
        '',
        '| writer | messages | lost | CPU s per 60 s | MB/min |',
        '|---|---|---|---|---|',
        f'| `recorder` node (rclpy raw subscriptions + BagWriter) | {f["sent"]} | {f["lost"]}'
        f'{"" if f["in_order"] else " (out of order)"} | {f["cpu"] * 60 / f["seconds"]:.1f} |'
        f' {f["mb_per_min"]:.1f} |',
        f'| `mcap` Writer alone, same messages (baseline) | {f["sent"]} | - |'
        f' {f["writer_cpu"] * 60 / f["seconds"]:.1f} | {f["writer_mb_per_min"]:.1f} |',
        '',
        f'{f["rate"]} messages/s for {f["seconds"]:.0f} s from another process over five topics'
        ' (four Float64 with sequence numbers, one String), reliable QoS; zstd chunks of'
        ' 256 KiB. CPU ratio recorder / writer alone:'
        f' {f["cpu"] / max(f["writer_cpu"], 1e-9):.1f}x. Target of issue 6: lossless at'
        ' 20 000 messages/s.',
        '',
    ]
    return lines


if __name__ == '__main__':
    seconds = float(sys.argv[1]) if len(sys.argv) > 1 else 600.0
    print('\n'.join(markdown(bench_live(seconds, min(60.0, seconds), min(60.0, seconds)))))
