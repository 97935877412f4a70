"""
Fast DDS over shared memory against UDP on the loopback, in one run.

The loop launcher, the tests and the Makefile run Fast DDS over UDP on the
loopback (``FASTDDS_BUILTIN_TRANSPORTS=UDPv4``) since its shared-memory
transport stalled a node mid-run (docs/RELIABILITY.md).  This measures what
that costs, each transport against the other on the same machine at the same
time: the rclpy round trip, Table 2.1's undershoot loop on wall time at
100 Hz, and the recorder under a flood.  Writes its section of
docs/BENCHMARKS.md.

Usage: ``python -m bench.transport_bench [LOOP_SECONDS]`` (default 60).
"""

import datetime
import os
from pathlib import Path
import sys

from bench import load_bench
from bench.live_bench import live_loop, recorder_flood, round_trip
from stiction_ros.cli.study import machine_description

START, END = '<!-- transport-bench:start -->', '<!-- transport-bench:end -->'
TRANSPORTS = ('DEFAULT', 'UDPv4')      # DEFAULT: Fast DDS's own choice, shared memory first
DOC = Path(__file__).resolve().parents[1] / 'docs' / 'BENCHMARKS.md'


def measure(seconds: float) -> dict:
    """Return ``{transport: figures}``, each transport in turn under the same load."""
    out = {}
    for tr in TRANSPORTS:
        os.environ['FASTDDS_BUILTIN_TRANSPORTS'] = tr     # the node processes inherit it
        print(f'transport {tr}: round trip, loop, flood', file=sys.stderr, flush=True)
        out[tr] = {'rtt': round_trip(2000), 'loop': live_loop(100.0, seconds),
                   'flood': recorder_flood(20000, seconds / 2)}
    return out


def markdown(r: dict, seconds: float) -> list[str]:
    """Return the section's lines."""
    lines = [START, '## Fast DDS transport: shared memory against UDP on the loopback', '',
             f'Machine: {machine_description()}. Date: {datetime.date.today().isoformat()}. '
             f'Command: `python -m bench.transport_bench {seconds:g}`.', '',
             '| transport | round trip p50 / p99 (µs) | 100 Hz loop: cycles on schedule | '
             'missed PV / OP / MV | OP to MV p50 / p99 (ms) | flood: lost of sent | '
             'recorder CPU s per 60 s |', '|---|---|---|---|---|---|---|']
    for tr, x in r.items():
        lo, fl = x['loop'], x['flood']
        missed = ' / '.join(str(lo[k]['missed']) for k in ('pv', 'op', 'mv'))
        lines.append(
            f'| `{tr}` | {x["rtt"]["p50"]:.0f} / {x["rtt"]["p99"]:.0f} | '
            f'{100 * lo["on_time"]:.3f} % | {missed} | {lo["op_to_mv_ms"][0]:.2f} / '
            f'{lo["op_to_mv_ms"][1]:.2f} | {fl["lost"]} of {fl["sent"]} | '
            f'{fl["cpu"] * 60 / fl["seconds"]:.1f} |')
    lines += ['', f'Each transport in turn: 2 000 round trips, the loop for {seconds:g} s, '
              f'20 000 messages/s for {seconds / 2:g} s into the recorder. `DEFAULT` is '
              "Fast DDS's own choice (shared memory between processes of one machine); "
              '`UDPv4` is what `loop`, the tests and the Makefile set.', END]
    return lines


def main() -> int:
    """Measure and write the section."""
    seconds = float(sys.argv[1]) if len(sys.argv) > 1 else 60.0
    lines = markdown(measure(seconds), seconds)
    load_bench.write_section(lines, DOC, (START, END))
    print('\n'.join(lines))
    return 0


if __name__ == '__main__':
    sys.exit(main())
