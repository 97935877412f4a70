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
import sys

from stiction_ros.analysis.detection import dataset
from stiction_ros.app.progress import Step, terminal_progress
from stiction_ros.cli.text import figure, pipe_safe, run_stamp, save_study, seeded_parser
from stiction_ros.errors import DetectorFileError

# The scoring seeds of make accuracy: the first row repeats its simulated row.
SEEDS = dataset.TEST
# The training seeds the clock-skew and lag checks' thresholds were chosen on.
SKEW_SEEDS = range(dataset.TRAIN.start, dataset.TRAIN.start + 1500)


def parser() -> argparse.ArgumentParser:
    """Return the command-line parser."""
    p = seeded_parser('stiction-robustness', __doc__, SEEDS.start, len(SEEDS), 'ROBUSTNESS')
    p.add_argument('--skew-seeds', type=int, default=len(SKEW_SEEDS),
                   help='training records the clock-skew and lag thresholds are chosen on '
                        f'again (seeds from {SKEW_SEEDS.start}; 0 to skip)')
    return p


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
        'not as simulated; "lost": sticky records found as simulated and not here, and of '
        'those, how many were refused (cannot be judged), and how many of these because the '
        'loop now cycles in under 10 samples, a refusal the issue asks for. Median '
        'shift: of the probability against the record as simulated. "realigned": records '
        'the clock-skew check (DETECTION.md, section 1) read shifted, and of those, by the '
        'skew the condition put in; "lag found": records where the lag check found PV '
        'read through a lag after the controller (named, not undone: DETECTION.md, '
        'section 1); "without the checks": the same records read as given (at 0.5, and '
        'with the band).',
        '',
        '| condition | at 0.5 | sticky found | healthy flagged | new flags | lost | lost: '
        'refused (under-sampled) | with the '
        'band | on the decided (share) | refused | median shift healthy / sticky | '
        'realigned (right) | lag found | without the checks: at 0.5 / band |',
        '|---|---|---|---|---|---|---|---|---|---|---|---|---|---|',
    ]
    for r in study['rows']:
        lines.append(
            f"| {r['condition']} | **{figure(r['balanced_accuracy'])}** | {r['tp']}/"
            f"{r['tp'] + r['fn']} | {r['fp']}/{r['fp'] + r['tn']} | {r['new_flags']} | "
            f"{r['lost_finds']} | {r['lost_refused']} ({r['lost_under_sampled']}) | "
            f"{figure(r['banded_balanced_accuracy'])} | "
            f"{figure(r['decided_balanced_accuracy'])} ({r['decided_share']:.2f}) | "
            f"{r['refused']} | {figure(r['median_shift_healthy'], 2)} / "
            f"{figure(r['median_shift_sticky'], 2)} | {r['realigned']} ({r['realigned_right']}) | "
            f"{r.get('lagged', '-')} | "
            f"{figure(r['without_check_balanced_accuracy'])} / "
            f"{figure(r['without_check_banded_balanced_accuracy'])} |")
    lines += ['', '| condition | what it stands for |', '|---|---|']
    lines += [f"| {r['condition']} | {r['what']} |" for r in study['rows']]
    if study.get('skew_choice'):
        lines += skew_table(study['skew_choice'])
    if study.get('lag_choice'):
        lines += lag_table(study['lag_choice'])
    lines += ['', 'What the rows mean for an engineer, and what was done about them: '
              '[DETECTION_LOG.md](DETECTION_LOG.md), "Instruments and timing".', '']
    return '\n'.join(lines)


def skew_table(choice: dict) -> list:
    """Return the lines that show how the clock-skew check's thresholds were chosen."""
    a, b = choice['seeds']
    grids = choice['every']
    lines = ['', "## How the clock-skew check's thresholds were chosen", '',
             f'Training seeds {a}-{b - 1} only (`stiction_ros.study.skew`, '
             f"{choice['seconds']:.0f} s): each record exported every "
             f"{' and every '.join(map(str, grids))} rows (on a coarser grid the "
             "controller's law holds only roughly, as on a plant export) and skewed by "
             f"{', '.join(f'{k:+d}' for k in choice['skews'])} rows. False: unskewed records "
             'realigned; right: skewed records realigned by their skew; wrong: by another. '
             f"Chosen: the most right among the pairs with at most {choice['max_false']:.1%} "
             f"false on every grid: **R² at least {choice['chosen'][0]}, by a margin of "
             f"{choice['chosen'][1]}**.", '']
    return lines + _grid(choice, 'margin', 'wrong')


def _grid(choice: dict, knob: str, third: str) -> list:
    """Return the table of a threshold grid: R² floor, ``knob``, and three shares per grid."""
    grids = choice['every']
    lines = [f'| R² at least | {knob} | ' + ' | '.join(
                 f'every {k}: false / right / {third}' for k in grids) + ' |',
             '|---|---|' + '---|' * len(grids)]
    for r in choice['rows']:
        cells = [' / '.join(f"{100 * r[f'every_{k}'][c]:.1f} %" for c in ('false', 'right', third))
                 for k in grids]
        mark = '**' if [r['min_r2'], r[knob]] == list(choice['chosen']) else ''
        lines.append(f"| {mark}{r['min_r2']}{mark} | {mark}{r[knob]}{mark} | "
                     + ' | '.join(cells) + ' |')
    return lines


def lag_table(choice: dict) -> list:
    """Return the lines that show how the lag check's thresholds were chosen."""
    a, b = choice['seeds']
    grids = choice['every']
    lines = ['', "## How the lag check's thresholds were chosen", '',
             f'Training seeds {a}-{b - 1} only (`stiction_ros.study.lag`, '
             f"{choice['seconds']:.0f} s): each record exported every "
             f"{', every '.join(map(str, grids))} rows, then as given, with PV through a "
             'first-order lag of '
             f"{', '.join(f'{d:g}' for d in choice['damped'])} samples of the simulation, and "
             f"skewed by {', '.join(f'{k:+d}' for k in choice['skews'])} rows; the law is read "
             f"through lags of {', '.join(f'{v:g}' for v in choice['lags'])} rows. False: "
             'a lag found in records as given; right: in lagged records; stolen: in skewed '
             'records, instead of their shift. A lag is found '
             'when the law through it reaches the R² below and leaves at most 1/ratio of '
             'what the best shift leaves unexplained. Chosen: the most right among the pairs '
             f"with at most {choice['max_false']:.1%} false on every grid: **R² at least "
             f"{choice['chosen'][0]}, ratio {choice['chosen'][1]}**.", '']
    return lines + _grid(choice, 'ratio', 'stolen')


@pipe_safe
def main(argv: list[str] | None = None) -> int:
    """Entry point."""
    args = parser().parse_args(argv)
    if args.seeds < 1 or args.jobs < 1 or args.first_seed < 0 or args.skew_seeds < 0:
        print('stiction-robustness: error: at least 1 seed and 1 job, a first seed and '
              '--skew-seeds of 0 or more', file=sys.stderr)
        return 2
    from stiction_ros.study.robustness import run
    from stiction_ros.study import lag, skew
    seeds = range(args.first_seed, args.first_seed + args.seeds)
    chosen_on = range(SKEW_SEEDS.start, SKEW_SEEDS.start + args.skew_seeds)
    try:
        choice = skew.choose(chosen_on, args.jobs).to_json() if args.skew_seeds > 0 else None
        lags = lag.choose(chosen_on, args.jobs).to_json() if args.skew_seeds > 0 else None
        with terminal_progress() as say:
            study = run(seeds, args.jobs,
                        lambda i, n, s: say(Step('records read', i, n, f'{s:.0f} s')))
    except (DetectorFileError, ValueError) as err:
        print(f'stiction-robustness: error: {err}', file=sys.stderr)
        return 2
    out = {**study.to_json(), 'skew_choice': choice, 'lag_choice': lags,
           'run': run_stamp(args.jobs)}
    if not save_study('stiction-robustness', out, args, markdown):
        return 2
    for r in out['rows']:
        print(f"{r['condition']:>18}: {r['balanced_accuracy']:.3f} at 0.5 "
              f"({r['tp']}/{r['tp'] + r['fn']} sticky found, {r['fp']}/{r['fp'] + r['tn']} "
              f"healthy flagged; {r['new_flags']} new flags, {r['lost_finds']} lost)")
    print(f'wrote {args.markdown} and {args.json}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
