"""
The analyzer's wall time for one command, by ``/usr/bin/time``, against ``python -c pass``.

Each command runs as a user types it, in a fresh process (best of 5, and the
median): ``stiction-analyze --help``; one Kano identification of 8 641
samples (a day at 10 s, the chapter's industrial record length) from a CSV;
the same with ``--model both`` (the default); and the Kano run again with
``STICTION_ROS_JIT_ONLY=1``, where the kernels built ahead of time are
ignored and numba loads its cached compilations (what every run cost before).
Targets (issue 22): ``--help`` <= 0.3 s, the Kano run <= 1.0 s.
"""

import os
from pathlib import Path
import shutil
import statistics
import subprocess
import sys
import tempfile

N_SAMPLES = 8641
REPEATS = 5


def _wall(args, env=None):
    """Return the wall seconds ``/usr/bin/time`` reports for one run of ``args``."""
    run = subprocess.run(['/usr/bin/time', '-f', 'WALL %e', *args], capture_output=True,
                         text=True, env={**os.environ, **(env or {})}, timeout=300)
    if run.returncode != 0:
        raise RuntimeError(f'{" ".join(args)} failed: {run.stderr[-500:]}')
    return float(run.stderr.strip().splitlines()[-1].split()[1])


def bench_analyzer_startup(repeats=REPEATS):
    """Return [(label, best s, median s, target s or None)] and the record's path."""
    if not shutil.which('/usr/bin/time'):
        raise RuntimeError('/usr/bin/time is missing (Debian package: time)')
    py = sys.executable
    with tempfile.TemporaryDirectory(prefix='analyzer_startup_') as tmp:
        csv = str(Path(tmp) / 'day.csv')
        subprocess.run([py, '-m', 'stiction_ros.cli.sim', 'concentration_loop.yaml', '--case',
                        'undershoot', '--duration', str(N_SAMPLES - 1), '--quiet', '-o', csv],
                       check=True)
        analyze = [py, '-m', 'stiction_ros.cli.analyze']
        cases = [('python -c pass', [py, '-c', 'pass'], None, None),
                 ('stiction-analyze --help', [*analyze, '--help'], None, 0.3),
                 (f'stiction-analyze FILE --model kano ({N_SAMPLES} samples)',
                  [*analyze, csv, '--model', 'kano', '--quiet'], None, 1.0),
                 ('the same, --model both (the default)', [*analyze, csv, '--quiet'], None,
                  None),
                 ('--model kano, kernels through numba (STICTION_ROS_JIT_ONLY=1)',
                  [*analyze, csv, '--model', 'kano', '--quiet'],
                  {'STICTION_ROS_JIT_ONLY': '1'}, None)]
        _wall(cases[2][1])  # warm the page cache
        rows = []
        for label, args, env, target in cases:
            times = [_wall(args, env) for _ in range(repeats)]
            rows.append((label, min(times), statistics.median(times), target))
    return rows


def markdown(rows):
    """Return the report lines."""
    base = rows[0][1]
    lines = [
        '## Analyzer start-up: one command, wall time',
        '',
        f'`/usr/bin/time` of each command in a fresh process, best and median of {REPEATS}.',
        "The analysis of a day's record loads no numba and no scipy: its kernels are built",
        'ahead of time by `stiction-precompile`, and the signal processing it needed from',
        'scipy.signal and scipy.stats is in `stiction_ros.analysis.dsp`. The last row is',
        'the same run with those kernels ignored (numba loads its cache: the old cost).',
        '',
        '| command | best (s) | median (s) | best / python -c pass | target (s) | met |',
        '|---|---|---|---|---|---|',
    ]
    for label, best, median, target in rows:
        met = '' if target is None else ('yes' if best <= target else 'NO')
        lines.append(f'| {label} | {best:.2f} | {median:.2f} | {best / base:.1f} | '
                     f'{"" if target is None else target} | {met} |')
    return lines + ['']


if __name__ == '__main__':
    print('\n'.join(markdown(bench_analyzer_startup())))
