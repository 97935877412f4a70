"""
Score the headline verdict with a measured valve position, blind: docs/MV_VERDICT.md.

    python -m stiction_ros.cli.mv_verdict [--first-seed S] [--seeds N] [--jobs J]
                                          [--markdown docs/MV_VERDICT.md]
                                          [--json docs/mv_verdict.json] [--render-only]

Every case of ``stiction_ros.sim.instrument_cases`` (stiction, play, and the
frictionless instrument and timing effects of a real position reading) on
``--seeds`` seeds, read as ``stiction-analyze`` reads a CSV with MV, under the
shipped rule and the three it grew from (``make mv-verdict``).  These seeds
choose nothing.
"""

import argparse
import json
from pathlib import Path
import sys

from stiction_ros.cli.text import figure, run_seeded, run_stamp, save_study, seeded_parser

# Fresh: the instrument cases' development seeds are 600000 and up, the --explain
# benchmark scores 700000 and up.  760000-761523 scored earlier versions of the rule (the
# page says how); the rule scored here (the three mends of the reading probe's first
# seeds) was fixed on the development seeds 600000-600047 before 761600 and up were read.
FIRST_SEED = 761_600


def page_parser(prog: str, doc: str | None, first_seed: int, seeds: int, page: str,
                seeds_help: str) -> argparse.ArgumentParser:
    """Return a seeded study's parser with ``--render-only`` (rewrite the page from its JSON)."""
    p = seeded_parser(prog, doc, first_seed, seeds, page, seeds_help)
    p.add_argument('--render-only', action='store_true',
                   help='score nothing: rewrite --markdown from the study in --json')
    return p


def parser() -> argparse.ArgumentParser:
    """Return the command-line parser."""
    return page_parser('stiction-mv-verdict', __doc__, FIRST_SEED, 24, 'MV_VERDICT',
                       'seeds per case (default 24)')


# Each rule of study.mv_verdict.RULES, as the page names it (short: in the table headers).
LABELS = (('answer', '**shipped**', 'shipped'),
          ('on_time', "without stick-slip read behind the reading's timing", 'on time'),
          ('jump', 'without the valve without friction to beat', 'no such valve'),
          ('old', "old: S and half of an ideal valve's MSE", 'old'))


def _answers(counts: dict) -> str:
    return ' / '.join(str(counts[a]) for a in ('stiction', 'no stiction', 'cannot tell'))


def summary_row(name: str, t: dict) -> str:
    """Return a rule's row of the summary table: its tally ``t`` under ``name``."""
    sticky, healthy = t['stiction'], t['no stiction']
    decided = t['records'] - t['cannot_tell'] - t['errors']
    return (f"| {name} | {t['wrong']} | {healthy['stiction']}/{sum(healthy.values())} | "
            f"{sticky['no stiction']}/{sum(sticky.values())} | {t['cannot_tell']} | "
            f"{t['errors']} | {figure(t['balanced'])} | {figure(t['balanced_decided'])} "
            f"({100 * decided / max(t['records'], 1):.0f} %) |")


def markdown(study: dict) -> str:
    """Return the page for the JSON of a study (``MvVerdictStudy.to_json`` plus ``run``)."""
    a = study['first_seed']
    b = a + study['per_case'] - 1
    # A study written before a rule was added is drawn without it.
    rules = [r for r in LABELS if r[0] in study]
    lines = [
        '# The verdict with a measured valve position, scored blind',
        '',
        'Written by `make mv-verdict` (`stiction_ros.study.mv_verdict`); do not edit by hand. '
        f"Run {study['run']['date']} on {study['run']['machine']}, {study['seconds']:.0f} s; "
        f'seeds {a}-{b} of every case of `stiction_ros/sim/instrument_cases.py`, '
        f"{len(study['rows'])} records.",
        '',
        'With MV in a recording the headline answer comes from the valve fits, not from the '
        'learned detector that docs/ACCURACY.md scores. Each record is a 4 321-sample closed '
        'loop (a random FOPDT or integrating plant under SIMC PI, set-point and load steps) '
        'at a sample time of 0.1-5 s, its valve sticky (Kano, S 2-5 %, J 0.2-0.6 S), play '
        'without slip (backlash 1-4 %) or frictionless, read through the instrument and '
        'timing effects of a real position reading (dead time, lag, calibration, rate limit, '
        'travel stop, quantisation; docs/EXPLAIN_BENCHMARK.md gives the sizes). MV noise is '
        "the loop's own (0.05-0.2 %) on a third of the records, and a noisier transmitter "
        '(1 or 2 %) on a third each. The CSV (t, sp, pv, op, mv) is read as '
        '`stiction-analyze` reads it, without `--explain`. Truth: stiction where the valve '
        'sticks with a slip jump; no stiction for play and for every frictionless valve. '
        "The old rule (stiction where S's 95 % range starts above 0.2 % and the fit removes "
        "half of an ideal valve's MSE) is read off the same fits. Nothing is chosen on "
        'these records.',
        '',
        '| rule | wrong answers | healthy called stiction | sticky called no stiction '
        '| cannot tell | errors | balanced accuracy (cannot tell as no stiction) '
        '| balanced accuracy on decided (share decided) |',
        '|---|---|---|---|---|---|---|---|',
        *(summary_row(label, study[key]) for key, label, _ in rules),
        '',
        '## By case',
        '',
        'Answers as stiction / no stiction / cannot tell.',
        '',
        '| case | truth | records | ' + ' | '.join(short for _, _, short in rules)
        + ' | why cannot tell (shipped) |',
        '|---|---|---|' + '---|' * len(rules) + '---|',
    ]
    for r in study['by_case']:
        codes = ', '.join(f'{n} `{c}`' for c, n in sorted(r['codes'].items()))
        lines.append(f"| `{r['case']}` | {r['truth']} | {r['records']} | "
                     + ' | '.join(_answers(r[key]) for key, _, _ in rules)
                     + f" | {codes or '-'} |")
    lines += ['', '## By MV noise', '',
              'Wrong answers / cannot tell, and balanced accuracy on the decided records.',
              '',
              '| transmitter noise added | records | '
              + ' | '.join(short for _, _, short in rules) + ' | balanced accuracy on decided: '
              + ' / '.join(short for _, _, short in rules) + ' |',
              '|---|---|' + '---|' * len(rules) + '---|']
    for r in study['by_noise']:
        lines.append(f"| {r['extra_mv_noise']:g} % | {r['answer']['records']} | "
                     + ' | '.join(f"{r[key]['wrong']} / {r[key]['cannot_tell']}"
                                  for key, _, _ in rules) + ' | '
                     + ' / '.join(figure(r[key]['balanced_decided']) for key, _, _ in rules)
                     + ' |')
    lines += ['', '## How the rule was set', '',
              'Its thresholds (S above 0.2 %, J above 0.05 %, half of the MSE removed, 1.5 '
              "times MV's noise variance, a calibration within gain 0.8-1.25 and 10 % at "
              'mid-span) were fixed before any scoring seed was read. Which valve without '
              'friction to weigh the claim against, and that "no stiction" needs one that '
              'explains MV, were chosen on the development seeds 600000-600011. A first '
              "version fitted `--explain`'s fuller chain (a second lag, a rate limit, travel "
              'stops) with scipy and scored seeds 760000-760023 (two draws of their noises: '
              '11 and 17 wrong, 1 and 0 of 240 healthy called stiction); it took 3 s more per '
              'record, so the chain became the grid search of '
              '`stiction_ros/analysis/without_friction.py`, checked on the development seeds '
              'again (the same 7 wrong of 156) and scored on seeds 760100-760123: 17 wrong '
              '(1/240 healthy called stiction, 16/72 sticky no stiction), 59 cannot tell. A '
              'review of the code then found two bugs in the no-stiction test, which let a '
              'stick-slip fit to the noise, or a frictionless valve with a calibration no '
              'reading has, stand for "a valve without friction explains MV" (7 of those 16 '
              'sticky misses), and an OP past the valve stops fed to that valve unclipped. '
              'Mended to the rule as written (the development seeds gave the same 7 wrong '
              'again), it scored seeds 760200-760223: 20 wrong (1/240, 19/72), 60 cannot '
              'tell. The sticky misses were answered no stiction where the valve without '
              'friction fitted MV to its noise although stick-slip with a clear band and '
              'jump fitted it better; no stiction now also asks that valve to fit at least '
              'as well, as stiction asks stick-slip to fit twice as well (the development '
              'seeds: 6 wrong of 156). That rule scored 760300-760323: 10 wrong (1/240, '
              '9/72), 62 cannot tell, beside 41 and 66 wrong for the two rules before. On '
              'those records three healthy loops read at 0.1 s with 1 % MV noise (seed '
              '760310) had their MV set aside as a dead reading: OP spread mostly by its '
              'own noise, MV following its slow part through a lag. A still-looking MV that '
              'a valve without friction explains down to its noise is no longer read as '
              'still; with that, on the same seeds: 10 wrong, 63 cannot tell (one no '
              'stiction became cannot tell), 42 and 68 for the rules before. That rule '
              'scored 760400-760423: 11 wrong (0/240, 11/72), 62 cannot tell, 26 of 72 '
              'sticky valves found. Stick-slip refitted behind the dead time and calibration '
              'of the valve without friction was then chosen on the development seeds (18 of '
              '36 sticky valves found against 13, none of 120 healthy called stiction). Seeds '
              "760500-760523 first stopped on a crash in identify's 95 % range (seed 760512, "
              'a healthy valve: a coarsened window missed a thin S-J ridge; mended), then '
              'scored 15 wrong (2/240, 13/72), 52 cannot tell, 27 of 72 sticky valves found '
              'against 18 without the refit. The two healthy valves called stiction had '
              'play that the plain fit, read on time, fitted better than the refit did; the '
              'refit must now also fit MV better than the plain fit (on 760500, no longer '
              'held out: 13 wrong, 0/240). That rule scored 760600-760623: 8 wrong (2/240, '
              'a backlash and a travel stop, the same without the refit; 6/72), 61 cannot '
              'tell, 33 of 72 sticky valves found against 21 without the refit. Travel '
              'stops were then added to the valve without friction (each end, its '
              'calibration solved again with the stop, kept where the SSE drops past the '
              '1 % chi-square quantile), chosen on the development seeds: 11 of 12 travel '
              'stops answered no stiction against 6, nothing else changed. That rule '
              'scored 760700-760723: 9 wrong (0/240, 9/72, all at 2 % MV noise), 46 cannot '
              'tell, 37 of 72 sticky valves found, every travel stop no stiction. A rate '
              'limit was then added the same way (on shares of the largest step of OP, '
              'its dead time, lag and rate refined together), chosen on the development '
              'seeds: 11 of 12 rate limits no stiction against 10, nothing else changed. '
              'That rule scored 760800-760823: 13 wrong (0/240, 13/72, 12 of them at 2 % '
              'MV noise), 40 cannot tell, 33 of 72 sticky valves found. On the sticky '
              'record of the start-up benchmark the valve without friction then held MV at '
              'stops at both ends of a 4 % limit cycle, where the valve rests at its '
              'reversals; a stop is now kept at one end only, the more significant (the '
              'development seeds: the same answers). That rule scored 760900-760923: 12 '
              'wrong (0/240, 12/72), 40 cannot tell, 38 of 72 sticky valves found. A review '
              'then found the test of those stages too lenient (samples that follow each other '
              'counted as independent, the level picked among 41): a stop or a rate limit '
              'must now also remove a third of the SSE, its likelihood ratio counted on the '
              'effective samples of its residuals (their lag-1 autocorrelation), and the '
              'steps of the rate are taken within runs; the development seeds gave the same '
              'answers, and the sticky record lost its stop. That rule scored '
              '761000-761023: 20 wrong (0/240, 20/72, all at 1-2 % MV noise), 36 cannot '
              'tell, 30 of 72 sticky valves found. One of those misses, read closely, '
              'showed the fits starting the valve at the first measured sample: the model '
              "carried that sample's noise through the whole first rest, hundreds of "
              'samples before the first set-point step, and the fit escaped it with a '
              'smaller band and no jump (S 1.99 %, J 0 for a valve of 2.43 % and 0.61 %). '
              'The first rest is now scored at its own mean, the start that fits it best '
              '(a still reading fits as before); the development seeds: 3 wrong of 156 '
              'against 5, 27 cannot tell against 23, one backlash read at 5 s (its '
              'improvement 0.4987 before, 0.5001 now) called stiction. That rule scored '
              '761100-761123: 8 wrong (0/240, 8/72), 56 cannot tell, 33 of 72 sticky valves '
              'found; the rule before it, on the same seeds only to compare, 12 wrong, 39 '
              'cannot tell, 34 found: with the valve started right, 2 % MV noise turns more '
              'fits into a clear band and jump that removes too little of an ideal '
              "valve's MSE (`noisy_mv`), on healthy valves too. The backlash above had a "
              "slip jump of 0.13-0.15 %, within OP's move in one sample while the valve "
              'moves (0.16 %): a valve breaks away between two samples, so play taken up '
              'between them shows as a jump that size. A slip jump must now clear that '
              'move too (the development seeds: 2 wrong, none of 120 healthy valves called '
              'stiction, the same 18 of 36 sticky valves found). That rule scored '
              '761200-761223: 4 wrong (0/240, 4/72, all at 2 % MV noise), 62 cannot tell, 33 '
              'of 72 sticky valves found (the rule before it, on the same seeds: 5 wrong, 1/240 '
              'a backlash whose jump was 0.06-0.07 %). At 2 % MV noise most of what an ideal '
              'valve misses is the noise, which no model removes: a fit that explains every '
              'slip removes a fifth of it (`noisy_mv`). A fit may now instead remove half of '
              'what an ideal valve leaves above the noise, where that excess is larger than '
              "the noise estimate's error (`stiction_ros/analysis/noise_share.py`); the claim "
              'against the valve without friction counts the same way, and no stiction from '
              'that valve asks it to leave at most half of what stick-slip leaves above the '
              'noise. The development seeds then showed a healthy travel stop called stiction '
              'by a fit of S 13 %, J 12 % whose valve never moved (a constant that beat an '
              'ideal valve): a fit whose valve starts to move fewer than 3 times now claims '
              'nothing (`few_slips`), and play or an unresolved jump that a valve without '
              'friction fits down to the noise, and as well, is no stiction. Chosen on the '
              'development seeds: 2 wrong, none of 120 healthy valves called stiction, 27 of '
              '36 sticky valves found against 18. That rule is scored here, on seeds no '
              'version had read; the rule before it, run on the same seeds only to compare, '
              'gave the same 8 wrong (0/240, 8/72), 59 cannot tell and found 28 sticky '
              "valves. A review then found three gaps, mended before the page's run and "
              'answering every record here as before: a fit below the noise estimate (too '
              'high then) made a share above 1; a refit behind the timing was not held to '
              '3 slips; play given way to that valve kept its score. On seeds 761400-761423, '
              'fresh, the rule as mended gave 5 wrong (0/240, 5/72, all at 2 % MV noise), 40 '
              'cannot tell, 51 of 72 sticky valves found, balanced accuracy 0.854 (0.955 on '
              'the 87 % decided); on 761200-761223 (read before by the rule before it alone) '
              '3 wrong (0/240), 48 cannot tell, 53 found. Its wrong answers were sticky '
              'valves that a valve without friction (a lag or dead time and a calibration) '
              'fitted within 1.5 times the noise, so no stiction rested on that valve, while '
              'stick-slip read behind its timing was fitted only where that valve left more '
              'than the noise, and then had to remove half of its MSE, out of reach over a '
              'noisy reading. Now no stiction that rests on the valve must beat that refit '
              'too: it is fitted wherever the plain fits show no stiction, and may remove half '
              "of the valve's MSE or of what it leaves above the noise (the development "
              'seeds: 1 wrong, none of 120 healthy valves called stiction, 34 of 36 sticky '
              'valves found against 27, the same time). That rule scored seeds 761500-761523: '
              '2 wrong (1/240, a backlash read at 2 s under 2 % noise; 1/72), 28 cannot tell, '
              '65 of 72 sticky valves found, balanced accuracy 0.949 (0.990 on the 91 % '
              'decided); the rule before it, on the same seeds only to compare, 6 wrong (1/240, '
              '5/72), 35 cannot tell, 54 found. A blind probe of reading effects this page does '
              'not draw (docs/MV_PROBES.md) then found holes, mended on its first seeds and on '
              'development seeds three times as many as before (600000-600047): play at '
              "another S inside a fitted jump's 95 % region is now found, and J's range then "
              'reaches 0; a claim must fit MV better than a valve without friction even where '
              'that valve needs a calibration no working reading has (`reading_fault`); a band '
              'removing too little is no stiction only over a known noise (`noise_unknown`); '
              'play is no stiction only where it fits MV within 1.5 times its noise. On the '
              'development seeds none of 480 healthy answers moved to stiction and 130 of 144 '
              'sticky valves were found against 133. Tried there and not adopted: the slip jump '
              'fitted on each half of the record and scored on the other against play, which '
              'turned the 2 backlash valves called stiction under 2 % noise into cannot tell but '
              '4 of 36 sticky valves too (a dead time or a slip on a knife edge moves the '
              "halves' fits). That rule is scored here; the rule before it, on the same seeds "
              'only to compare, gave 2 wrong (0/240, 2/72), 28 cannot tell and found 63.',
              '', "The `cannot tell` codes are the README's (`stiction.cannot_tell`); "
              '`stiction-analyze --explain` answers most of them by fitting friction together '
              'with the instrument effects and testing both on held-out data '
              '(docs/EXPLAIN_BENCHMARK.md).', '']
    return '\n'.join(lines)


def render_only(prog: str, args, page) -> int:
    """Rewrite ``args.markdown`` with ``page`` of the study in ``args.json``; return the code."""
    try:
        study = json.loads(Path(args.json).read_text(encoding='utf-8'))
        Path(args.markdown).write_text(page(study), encoding='utf-8')
    except (OSError, ValueError, KeyError) as err:
        print(f'{prog}: error: cannot render {args.json}: {err}', file=sys.stderr)
        return 2
    print(f'wrote {args.markdown}')
    return 0


def score(prog: str, args, page, family: str = 'instrument') -> int:
    """Score ``family``'s cases on the seeds ``args`` give (or only render); return the code."""
    if args.render_only:
        return render_only(prog, args, page)
    from stiction_ros.study.mv_verdict import run

    def study_run(seeds, jobs, say):
        return run(len(seeds), seeds.start, jobs, say, family=family)
    study = run_seeded(prog, args, study_run, 'records read')
    if study is None:
        return 2
    out = {**study.to_json(), 'run': run_stamp(args.jobs)}
    if not save_study(prog, out, args, page):
        return 2
    for key, _, name in LABELS:
        t = out[key]
        print(f"{name:>13}: {t['wrong']} wrong, {t['cannot_tell']} cannot tell, "
              f"{t['errors']} errors of {t['records']}")
    print(f'wrote {args.markdown} and {args.json}')
    return 0


def main(argv: list[str] | None = None) -> int:
    """Entry point."""
    return score('stiction-mv-verdict', parser().parse_args(argv), markdown)


if __name__ == '__main__':
    sys.exit(main())
