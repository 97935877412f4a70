"""
Read simulated loops through distorting instruments: docs/ROBUSTNESS.md (``make robustness``).

    python -m stiction_ros.cli.robustness [--first-seed S] [--seeds N] [--jobs J]
                                          [--markdown docs/ROBUSTNESS.md]
                                          [--json docs/robustness.json]

Every record is read by the analyzer's own path as simulated and under each
distortion of ``stiction_ros.study.robustness.CONDITIONS``; the valve is the
same in every condition, so a changed answer is the instrument's doing.  The
default seeds are the spent scoring seeds of ``make accuracy`` (no model is
chosen here), so the first row repeats the simulated row of docs/ACCURACY.md.
"""

import argparse
import datetime
import json
import os
from pathlib import Path
import platform
import sys

from stiction_ros.analysis.detection import dataset
from stiction_ros.app.progress import Step, terminal_progress
from stiction_ros.cli.text import description, pipe_safe
from stiction_ros.errors import DetectorFileError

# The scoring seeds of make accuracy: the first row repeats its simulated row.
SEEDS = dataset.TEST


def parser() -> argparse.ArgumentParser:
    """Return the command-line parser."""
    p = argparse.ArgumentParser(prog='stiction-robustness', description=description(__doc__))
    p.add_argument('--first-seed', type=int, default=SEEDS.start)
    p.add_argument('--seeds', type=int, default=len(SEEDS))
    p.add_argument('--jobs', type=int, default=os.cpu_count() or 1)
    p.add_argument('--markdown', default='docs/ROBUSTNESS.md')
    p.add_argument('--json', default='docs/robustness.json')
    return p


def _f(v: float | None, digits: int = 3) -> str:
    return '-' if v is None or v != v else f'{v:.{digits}f}'


def markdown(study: dict) -> str:
    """Return the page for the JSON of a study (``Robustness.to_json`` plus ``run``)."""
    a, b = study['seeds']
    lines = [
        '# Does the verdict hold when instruments and timing distort the trend?',
        '',
        'Written by `make robustness` (`stiction_ros.study.robustness`); do not edit by hand. '
        f"Run {study['run']['date']} on {study['run']['machine']}, {study['seconds']:.0f} s.",
        '',
        f"Simulated loops of seeds {a}-{b - 1}: the {study['records']} records "
        f"`make accuracy` scores ({study['sticky']} sticky, "
        f"{study['records'] - study['sticky']} healthy; {study['unscored']} others cannot be "
        "judged as simulated, hide their stiction under PV's noise or are deadband-like). "
        "Each is read by the analyzer's own path as simulated and again under each "
        'distortion below. The valve is the same in every row: whatever changes is the '
        "instrument's or the clock's doing. The shipped model; nothing is fitted or chosen "
        'on these records (they are the spent scoring seeds of ACCURACY.md).',
        '',
        '"at 0.5": every judged record answered at a probability of 0.5, a record the '
        'analyzer cannot judge counted as "no stiction". "with the band": the answers the '
        'analyzer gives (cannot tell at 0.25-0.75 counted as "no stiction"), and on the '
        'decided records alone. "new flags": healthy records called sticky at 0.5 that were '
        'not as simulated; "lost": sticky records found as simulated and not here. Median '
        'shift: of the probability against the record as simulated.',
        '',
        '| condition | at 0.5 | sticky found | healthy flagged | new flags | lost | with the '
        'band | on the decided (share) | refused | median shift healthy / sticky |',
        '|---|---|---|---|---|---|---|---|---|---|',
    ]
    for r in study['rows']:
        lines.append(
            f"| {r['condition']} | **{_f(r['balanced_accuracy'])}** | {r['tp']}/"
            f"{r['tp'] + r['fn']} | {r['fp']}/{r['fp'] + r['tn']} | {r['new_flags']} | "
            f"{r['lost_finds']} | {_f(r['banded_balanced_accuracy'])} | "
            f"{_f(r['decided_balanced_accuracy'])} ({r['decided_share']:.2f}) | "
            f"{r['refused']} | {_f(r['median_shift_healthy'], 2)} / "
            f"{_f(r['median_shift_sticky'], 2)} |")
    lines += ['', '| condition | what it stands for |', '|---|---|']
    lines += [f"| {r['condition']} | {r['what']} |" for r in study['rows']]
    lines += ['', 'What the rows mean for an engineer, and what was done about them: '
              '[DETECTION.md](DETECTION.md), section 5.', '']
    return '\n'.join(lines)


@pipe_safe
def main(argv: list[str] | None = None) -> int:
    """Entry point."""
    args = parser().parse_args(argv)
    if args.seeds < 1 or args.jobs < 1 or args.first_seed < 0:
        print('stiction-robustness: error: at least 1 seed and 1 job, a first seed of 0 or '
              'more', file=sys.stderr)
        return 2
    from stiction_ros.study.robustness import run
    seeds = range(args.first_seed, args.first_seed + args.seeds)
    try:
        with terminal_progress() as say:
            study = run(seeds, args.jobs,
                        lambda i, n, s: say(Step('records read', i, n, f'{s:.0f} s')))
    except (DetectorFileError, ValueError) as err:
        print(f'stiction-robustness: error: {err}', file=sys.stderr)
        return 2
    out = {**study.to_json(),
           'run': {'date': datetime.date.today().isoformat(),
                   'machine': f'{platform.machine()}, {os.cpu_count()} cores, {args.jobs} jobs'}}
    for path, text in ((args.json, json.dumps(out, indent=1) + '\n'),
                       (args.markdown, markdown(out))):
        Path(path).parent.mkdir(parents=True, exist_ok=True)
        Path(path).write_text(text, encoding='utf-8')
    for r in out['rows']:
        print(f"{r['condition']:>18}: {r['balanced_accuracy']:.3f} at 0.5 "
              f"({r['tp']}/{r['tp'] + r['fn']} sticky found, {r['fp']}/{r['fp'] + r['tn']} "
              f"healthy flagged; {r['new_flags']} new flags, {r['lost_finds']} lost)")
    print(f'wrote {args.markdown} and {args.json}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
