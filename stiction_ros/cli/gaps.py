"""
Judge simulated loops cut by a gap: docs/GAPS.md (``make gaps``).

    python -m stiction_ros.cli.gaps [--first-seed S] [--seeds N] [--jobs J]
                                    [--markdown docs/GAPS.md] [--json docs/gaps.json]

Every record is read whole and with a share of it cut out; the stretches
either side are judged alone, and the longest stretch's answer is compared
with every stretch's pooled (``stiction_ros.study.gaps``).  The default
seeds were drawn for this study and scored it once (2026-12-06); no model
is chosen here.
"""

import argparse
import sys

from stiction_ros.cli.text import figure, pipe_safe, run_seeded, run_stamp, save_study, \
    seeded_parser

# Seeds drawn for the gap study, never read by any other study or fit.
SEEDS = range(7_000_000, 7_002_000)


def parser() -> argparse.ArgumentParser:
    """Return the command-line parser."""
    return seeded_parser('stiction-gaps', __doc__, SEEDS.start, len(SEEDS), 'GAPS')


def markdown(study: dict) -> str:
    """Return the page for the JSON of a study (``Gaps.to_json`` plus ``run``)."""
    a, b = study['seeds']
    lines = [
        '# A record cut by a gap: the longest stretch, or every stretch',
        '',
        'Written by `make gaps` (`stiction_ros.study.gaps`); do not edit by hand. '
        f"Run {study['run']['date']} on {study['run']['machine']}, {study['seconds']:.0f} s.",
        '',
        f"Simulated loops of seeds {a}-{b - 1}: the {study['records']} records "
        f"`make accuracy` would score ({study['sticky']} sticky, "
        f"{study['records'] - study['sticky']} healthy; {study['unscored']} others cannot be "
        "judged whole, hide their stiction under PV's noise or are deadband-like). Each is "
        'read whole, then with a share of it cut out at a place its seed draws (at least '
        '15 % from either end); the stretches either side are judged alone when they hold '
        '100 samples or more. "longest stretch": its answer alone; "every stretch pooled": '
        "the length-weighted mean of the judged stretches' log-odds "
        '(`detection/stretches.py`). The shipped model; nothing is fitted here.',
        '',
        '"at 0.5": every judged record answered at 0.5, a record not judged counted as "no '
        'stiction"; "with the band": the analyzer\'s answers (cannot tell at 0.25-0.75 '
        'counted as "no stiction"), and on the decided records alone. "differ": records '
        'answered at 0.5 otherwise than whole.',
        '',
        '| gap | answer from | at 0.5 | sticky found | healthy flagged | with the band | '
        'on the decided (share) | not judged | differ |',
        '|---|---|---|---|---|---|---|---|---|',
    ]
    for r in study['rows']:
        bold = '**' if r['rule'] != 'whole record' else ''
        lines.append(
            f"| {r['share']:.0%} | {r['rule']} | {bold}{figure(r['balanced_accuracy'])}{bold} | "
            f"{r['tp']}/{r['tp'] + r['fn']} | {r['fp']}/{r['fp'] + r['tn']} | "
            f"{figure(r['banded_balanced_accuracy'])} | {figure(r['decided_balanced_accuracy'])} "
            f"({r['decided_share']:.2f}) | {r['refused']} | {r['differ_from_whole']} |")
    lines += ['', 'Why the analyzer pools, and the rule written before these seeds were '
              'read: [DETECTION_LOG.md](DETECTION_LOG.md), "A record cut by a gap".', '']
    return '\n'.join(lines)


@pipe_safe
def main(argv: list[str] | None = None) -> int:
    """Entry point."""
    args = parser().parse_args(argv)
    from stiction_ros.study.gaps import run
    try:
        study = run_seeded('stiction-gaps', args, run, 'records read')
    except ValueError as err:
        print(f'stiction-gaps: error: {err}', file=sys.stderr)
        return 2
    if study is None:
        return 2
    out = {**study.to_json(), 'run': run_stamp(args.jobs)}
    if not save_study('stiction-gaps', out, args, markdown):
        return 2
    for r in out['rows']:
        print(f"gap {r['share']:.0%}, {r['rule']:>20}: {figure(r['balanced_accuracy'])} at 0.5, "
              f"{figure(r['banded_balanced_accuracy'])} with the band")
    print(f'wrote {args.markdown} and {args.json}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
