"""
``stiction-sim``: run a loop described in YAML offline and write its signals to CSV.

Examples::

    stiction-sim config/concentration_loop.yaml --case no_offset -o loop.csv
    stiction-sim config/concentration_loop.yaml --set valve.model=kano --set valve.S=7
"""

import argparse
import math
import os
import sys

from stiction_ros.cli.text import description, pipe_safe
from stiction_ros.models import ModelError
from stiction_ros.sim.closed_loop import simulate_loop, write_csv
from stiction_ros.sim.launch_plan import resolve_config
from stiction_ros.sim.loop_config import ConfigError, load_loop, parse_overrides
from stiction_ros.sim.plant import PlantError
from stiction_ros.sim.sources import SourceError


def _progress(what):
    def show(done, total):
        sys.stderr.write(f'\r{what}: {100 * done // total:3d} %')
        if done == total:
            sys.stderr.write('\n')
    return show


# What -o must never write CSV text into: another format's file, or the loop file itself.
NOT_CSV = ('.mcap', '.db3', '.yaml', '.yml', '.json', '.html', '.htm')


def _check_output(output: str, config) -> None:
    """Refuse an output that would lose a file, or fail only after the run."""
    from pathlib import Path
    from stiction_ros.app.report_files import unwritable
    out = Path(output)
    if out.suffix.lower() in NOT_CSV:
        raise ConfigError(f'-o {output}: the output is CSV text; name a .csv file (a bag is '
                          'recorded by `loop --record`)')
    if out.exists() and Path(config).exists() and out.resolve() == Path(config).resolve():
        raise ConfigError(f'-o {output} is the loop file itself: name another file')
    why = unwritable(out)
    if why:
        raise ConfigError(f'cannot write {output}: {why} (checked before the run)')


@pipe_safe
def main(argv=None):
    """Run the command; return the process exit code."""
    ap = argparse.ArgumentParser(prog='stiction-sim', description=description(__doc__))
    ap.add_argument('config', help='loop description (YAML): a path, or the name of a '
                    'shipped file, e.g. concentration_loop.yaml')
    ap.add_argument('--case', help='a case from the file\'s "cases" section')
    ap.add_argument('--duration', type=float, help='override the duration, s')
    ap.add_argument('--set', action='append', metavar='KEY=VALUE',
                    help='override a setting, e.g. valve.S=7 (repeatable)')
    ap.add_argument('-o', '--output', default='-', help='CSV file to write (default: stdout)')
    ap.add_argument('--quiet', action='store_true', help='no progress on stderr')
    args = ap.parse_args(argv)
    if args.duration is not None and not (math.isfinite(args.duration) and args.duration > 0):
        ap.error(f'--duration must be a positive number of seconds, got {args.duration:g}')
    try:
        config = resolve_config(args.config)
        if args.output != '-':
            _check_output(args.output, config)
        cfg = load_loop(config, args.case, parse_overrides(args.set))
        show = not args.quiet and sys.stderr.isatty()
        data = simulate_loop(cfg, args.duration, _progress('simulating') if show else None)
        if args.output != '-':
            # As the analyzer's reports do: a missing folder is made.
            os.makedirs(os.path.dirname(args.output) or '.', exist_ok=True)
        write_csv(sys.stdout if args.output == '-' else args.output, data,
                  progress=_progress(f'writing {args.output}') if show and args.output != '-'
                  else None)
    except (ConfigError, ModelError, PlantError, SourceError) as err:
        print(f'stiction-sim: error: {err}', file=sys.stderr)
        return 2
    except BrokenPipeError:
        raise                       # a reader that stopped early: pipe_safe's to handle
    except OSError as err:
        print(f'stiction-sim: error: cannot write {args.output}: {err.strerror or err}',
              file=sys.stderr)
        return 2
    if args.output != '-' and not args.quiet:
        print(f'stiction-sim: wrote {len(data["t"])} samples to {args.output}', file=sys.stderr)
    return 0


if __name__ == '__main__':
    sys.exit(main())
