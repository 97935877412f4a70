"""
Read loops the simulator never draws: docs/PROBES.md (``make probes``).

    python -m stiction_ros.cli.probes [--first-seed S] [--seeds N] [--jobs J]
                                      [--markdown docs/PROBES.md] [--json docs/probes.json]

Each probe of ``stiction_ros.study.probes.PROBES`` draws its loops from its
own generator, and the shipped detector reads them as the analyzer does.  A
healthy loop called ``stiction`` is a confident wrong answer on a kind of loop
the model never saw; these seeds choose nothing.
"""

import argparse
import sys

from stiction_ros.cli.text import run_seeded, run_stamp, save_study, seeded_parser

# Seeds of the probes' own generators (streams [seed, 11] and [seed, 13]) and of the
# corpus for the detuned and fast-controller loops (the rate from [seed, 17]):
# 3960000- is where the limit-cycling refusal was scored.
FIRST_SEED = 3_960_000


def parser() -> argparse.ArgumentParser:
    """Return the command-line parser."""
    return seeded_parser('stiction-probes', __doc__, FIRST_SEED, 200, 'PROBES',
                         'records per probe (default 200)')


def markdown(study: dict) -> str:
    """Return the page for the JSON of a study (``Probes.to_json`` plus ``run``)."""
    a, b = study['seeds']
    lines = [
        '# What the detector answers on loops the simulator never draws',
        '',
        'Written by `make probes` (`stiction_ros.study.probes`); do not edit by hand. '
        f"Run {study['run']['date']} on {study['run']['machine']}, {study['seconds']:.0f} s; "
        f'seeds {a}-{b - 1} of each probe, read by the shipped detector as the analyzer '
        'reads a record. Nothing is chosen on these records.',
        '',
        '| probe | valve | records | stiction | no stiction | cannot tell: balanced '
        '| cannot tell: refused | at 0.5: flagged of judged |',
        '|---|---|---|---|---|---|---|---|',
    ]
    for r in study['rows']:
        refused = ', '.join(f'{n} {c.replace("_", " ")}' for c, n in sorted(r['refused'].items()))
        lines.append(f"| {r['probe']} | {'sticky' if r['label'] else 'healthy'} | "
                     f"{r['records']} | {r['stiction']} | {r['no_stiction']} | {r['balanced']} | "
                     f"{refused or '0'} | {r['at_half']}/{r['judged']} |")
    lines += ['', 'The probes:', '']
    seen = set()
    for r in study['rows']:
        if r['probe'] not in seen:
            seen.add(r['probe'])
            lines.append(f"* **{r['probe']}**: {r['what']}.")
    lines += ['', 'On a healthy row every `stiction` is a wrong answer the model gave with a '
              'probability of 0.75 or more; docs/DETECTION_LOG.md ("Loops the simulator '
              'never draws") says what was done about each.', '']
    return '\n'.join(lines)


def main(argv: list[str] | None = None) -> int:
    """Entry point."""
    args = parser().parse_args(argv)
    from stiction_ros.study.probes import run
    study = run_seeded('stiction-probes', args, run, 'records read')
    if study is None:
        return 2
    out = {**study.to_json(), 'run': run_stamp(args.jobs)}
    if not save_study('stiction-probes', out, args, markdown):
        return 2
    for r in out['rows']:
        print(f"{r['probe']:>20} {'sticky' if r['label'] else 'healthy':>7}: "
              f"{r['stiction']} stiction, {r['no_stiction']} no stiction, "
              f"{r['records'] - r['stiction'] - r['no_stiction']} cannot tell "
              f"of {r['records']}")
    print(f'wrote {args.markdown} and {args.json}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
