"""
``stiction-study``: reproduce the chapter's Table 2.1 / Fig. 2.3 study.

Writes ``REPRODUCTION.md``, ``reproduction.json`` and ``figures/*.png`` under
``--out`` (default ``out/study``; ``make reproduce`` writes the committed copy in
``docs``).
"""

import argparse
import datetime
import json
import os
from pathlib import Path
import platform
import re
import sys

from stiction_ros.cli.text import description, pipe_safe
from stiction_ros.errors import StictionError
from stiction_ros.sim.launch_plan import resolve_config
from stiction_ros.study.reproduction import run_study, write_report


def machine_description():
    """Describe this machine in one line (CPU model, cores, Python)."""
    cpu = platform.processor() or platform.machine()
    try:
        with open('/proc/cpuinfo', encoding='utf-8') as f:
            for line in f:
                if line.startswith('model name'):
                    cpu = line.split(':', 1)[1].strip()
                    break
    except OSError:
        pass
    return f'{cpu}, {os.cpu_count()} cores, Python {platform.python_version()}'


@pipe_safe
def main(argv=None):
    """Run the study; return the exit code."""
    ap = argparse.ArgumentParser(prog='stiction-study', description=description(__doc__))
    ap.add_argument('--config', default=None, help='loop file (default: concentration_loop.yaml)')
    ap.add_argument('--out', default='out/study',
                    help='output directory (default: out/study; `make reproduce` uses docs)')
    args = ap.parse_args(argv)
    # A path, or the name of a shipped loop file, as stiction-sim takes it.
    try:
        config = Path(resolve_config(args.config or 'concentration_loop.yaml'))
    except StictionError as err:
        ap.error(f'--config: {err}')
    out = Path(args.out)

    def say(msg):
        print(f'stiction-study: {msg}', file=sys.stderr, flush=True)

    try:
        out.mkdir(parents=True, exist_ok=True)
        results = run_study(config, out, say)
        (out / 'reproduction.json').write_text(json.dumps(results, indent=1, default=float))
        write_report(results, out / 'REPRODUCTION.md', datetime.date.today().isoformat(),
                     machine_description())
    except StictionError as err:
        print(f'stiction-study: error: {err}', file=sys.stderr)
        return 2
    except OSError as err:
        print(f'stiction-study: error: cannot write to {out}: {err.strerror or err}',
              file=sys.stderr)
        return 2
    # Every part that drew one names its figure.
    figures = len(re.findall(r"'figure': '[^']+'", repr(results)))
    say(f'wrote {out / "REPRODUCTION.md"} and {figures} figures')
    for c in results['cases']:
        o = c['oscillation']['op']
        cyc = f"period {o['period']:.1f} s, OP amplitude {o['amplitude']:.2f} %" \
            if o['oscillating'] else 'no limit cycle'
        say(f"  {c['case']:<11} S={c['S']:g} J={c['J']:g}: {cyc}")
    return 0


if __name__ == '__main__':
    sys.exit(main())
