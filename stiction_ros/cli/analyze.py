"""
stiction-analyze: is this valve sticking, how much, and how well do the models fit.

    stiction-analyze INPUT [--model kano|choudhury|both] [--S S --J J]
                     [--fit-filter] [--window T0 T1] [--namespace NS]
                     [--loop-type auto|self-regulating|integrating]
                     [--json REPORT.json] [--html REPORT.html]

INPUT is a rosbag2 directory or .mcap file, a CSV (t, op and any of mv, pv,
sp) or a historian export.  Problems with the input end in one line on stderr
and exit status 2.

INPUT may also be a folder of recordings or a quoted glob ('plant/**/*.csv'):
each is analysed on its own, over ``--jobs`` processes or a Dask cluster
(``--scheduler tcp://HOST:8786``); one line per recording, ``--json`` the
summary of all, ``--out-dir`` a report per recording (stiction_ros.cli.batch).
"""

import argparse
import json
import math
from pathlib import Path
import sys
import time

import numpy as np

from stiction_ros.analysis.detection.model_file import DetectorFileError
from stiction_ros.analysis.identify import IdentifyError
from stiction_ros.analysis.record import InputError

EXIT_INPUT = 2
# The learned detector's model file is missing or damaged: the install, not the input.
EXIT_DETECTOR = 3
VERDICT_WORDS = {True: 'stiction', False: 'no stiction', None: 'cannot tell'}


def _jsonable(x):
    """Return ``x`` with numpy scalars, tuples and non-finite floats made JSON-safe."""
    if isinstance(x, dict):
        return {str(k): _jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_jsonable(v) for v in x]
    if isinstance(x, (np.bool_, bool)):
        return bool(x)
    if isinstance(x, (np.integer,)):
        return int(x)
    if isinstance(x, (float, np.floating)):
        return float(x) if math.isfinite(x) else None
    if isinstance(x, np.ndarray):
        return _jsonable(x.tolist())
    return x


def to_json_text(report):
    """Return the report as indented JSON (NaN written as null)."""
    return json.dumps(_jsonable(report), indent=2, ensure_ascii=False, allow_nan=False)


def parser():
    """Return the argument parser."""
    p = argparse.ArgumentParser(prog='stiction-analyze', description=__doc__.split('\n')[1])
    p.add_argument('input', help='rosbag2 directory, .mcap file, CSV or historian export')
    p.add_argument('--model', default='both', choices=('kano', 'choudhury', 'both'),
                   help='model(s) to fit when MV is present (default both)')
    p.add_argument('--S', type=float, help='use this S (%%) instead of identifying it')
    p.add_argument('--J', type=float, help='use this J (%%) instead of identifying it')
    p.add_argument('--fit-filter', action='store_true',
                   help='also identify the air-chamber lag (kano) or EWMA weight (choudhury)')
    p.add_argument('--window', nargs=2, type=float, metavar=('T0', 'T1'),
                   help='analyse only T0 <= t <= T1, seconds from the start of the record')
    p.add_argument('--namespace', help='namespace of the loop topics in a bag, e.g. /loop1')
    p.add_argument('--loop-type', default='auto',
                   choices=('auto', 'self-regulating', 'integrating'),
                   help='auto: integrating when the tag names a level loop (LIC)')
    p.add_argument('--detector', metavar='FILE', default=None,
                   help='learned stiction detector model file (default: the shipped one, '
                        'rebuilt by `make detector`)')
    p.add_argument('--no-hammerstein', action='store_true',
                   help='skip the Hammerstein quantification of S and J from OP and PV')
    p.add_argument('--explain', action='store_true',
                   help='needs MV: locate where the plain Kano model misses, name the missing '
                        'physics (docs EFFECTS.md), fit it and compare held-out MSE')
    p.add_argument('--holdout', type=float, default=0.3,
                   help='share of samples at the end kept out of every fit and choice '
                        '(default 0.3)')
    p.add_argument('--bootstrap', type=int, default=3,
                   help='effect-free replicates that calibrate the choice (default 3)')
    p.add_argument('--json', dest='json_path', metavar='REPORT.json', help='write the report')
    p.add_argument('--html', dest='html_path', metavar='REPORT.html',
                   help='write the HTML report (figures embedded, PNGs beside it)')
    p.add_argument('--quiet', action='store_true', help='no progress on stderr')
    many = p.add_argument_group('many recordings (INPUT a folder or a quoted glob)')
    many.add_argument('--jobs', type=int, default=None,
                      help='worker processes; for one recording, threads of --explain '
                      '(default: every core this process may use)')
    many.add_argument('--scheduler', metavar='ADDRESS',
                      help='run on this Dask cluster (tcp://host:8786) instead of local processes')
    many.add_argument('--out-dir', metavar='DIR', help='write a JSON report per recording here')
    return p


def _forwarded(args):
    # The options of one recording's analysis, for the batch workers.
    # Each worker is one process already: its --explain runs on one thread.
    argv = ['--model', args.model, '--loop-type', args.loop_type,
            '--holdout', repr(args.holdout), '--bootstrap', str(args.bootstrap), '--jobs', '1']
    for flag, value in (('--S', args.S), ('--J', args.J), ('--namespace', args.namespace),
                        ('--detector', getattr(args, 'detector', None))):
        if value is not None:
            argv += [flag, str(value)]
    if args.window:
        argv += ['--window', *map(repr, args.window)]
    for flag, on in (('--fit-filter', args.fit_filter), ('--no-hammerstein', args.no_hammerstein),
                     ('--explain', args.explain)):
        if on:
            argv.append(flag)
    return argv


def run_many(args, paths, say):
    """Analyse every recording in ``paths``; print a line each; return the exit status."""
    from stiction_ros.cli import batch
    if args.html_path:
        raise ValueError('--html takes one recording; for many use --out-dir (JSON reports)')
    jobs = args.jobs if args.jobs is not None else batch.default_jobs()
    if jobs < 1:
        raise ValueError(f'--jobs must be 1 or more, got {jobs}')
    where = f'Dask cluster {args.scheduler}' if args.scheduler else f'{jobs} process(es)'
    say(f'{len(paths)} recordings from {args.input} on {where}')
    root = args.input if Path(args.input).is_dir() else '.'
    rows, seconds = batch.run_batch(paths, _forwarded(args), jobs, args.scheduler,
                                    args.out_dir, root, say)
    for row in rows:
        if row['ok']:
            # Recordings often share a tag name; the path tells them apart.
            first, *rest = row['summary'].split('\n')
            print('\n'.join([f'{row["input"]}: {first.split(": ", 1)[-1]}', *rest]))
        else:
            print(f'{row["input"]}: error: {row["error"]}')
    failed = sum(not r['ok'] for r in rows)
    tally = {}
    for r in rows:
        if r['ok']:
            word = VERDICT_WORDS[r['detected']]
            tally[word] = tally.get(word, 0) + 1
    print(f'{len(rows)} recordings in {seconds:.1f} s ({len(rows) / seconds:.2f}/s on {where}): '
          + ', '.join(f'{n} {w}' for w, n in sorted(tally.items()))
          + (f', {failed} failed' if failed else ''))
    if args.json_path:
        write_text(args.json_path, to_json_text({
            'input': args.input, 'recordings': len(rows), 'failed': failed,
            'seconds': round(seconds, 3), 'workers': where, 'rows': rows}))
        say(f'wrote {args.json_path}')
    return EXIT_INPUT if failed else 0


def run(args, say):
    """Analyse as ``args`` asks; return the report dict."""
    return run_analysis(args, say).report


def run_analysis(args, say):
    """Analyse as ``args`` asks, write what it asks for; return the :class:`Analysis`."""
    from stiction_ros.analysis.pipeline import analyze, Options
    from stiction_ros.analysis.readers import load_record
    t0 = time.perf_counter()
    options = Options(model=args.model, S=args.S, J=args.J, fit_filter=args.fit_filter,
                      loop_type=args.loop_type, hammerstein=not args.no_hammerstein,
                      detector=getattr(args, 'detector', None))
    say(f'reading {args.input}')
    record = load_record(args.input, namespace=args.namespace,
                         window=tuple(args.window) if args.window else None)
    say(f'{record.samples} samples at {record.sample_time:g} s, signals '
        f'{", ".join(s for s in ("op", "mv", "pv", "sp") if record.has(s))}')
    analysis = analyze(record, options,
                       progress=lambda level, n: say(f'  search level {level}: {n} evaluations'))
    report = analysis.report
    if getattr(args, 'explain', False):
        run_explain(analysis, args, say)
    report['elapsed_s'] = round(time.perf_counter() - t0, 3)
    if args.json_path:
        write_text(args.json_path, to_json_text(report))
        say(f'wrote {args.json_path}')
    if args.html_path:
        write_html(analysis, args.html_path, say)
    return analysis


def run_explain(analysis, args, say):
    """Add the ``--explain`` sections to the report of ``analysis``."""
    from stiction_ros.analysis.mismatch.decide import explain_record
    rec = analysis.record
    if not rec.has('mv'):
        # Not an input error: the rest of the report stands, and says why this part cannot.
        analysis.report['mismatch'] = {
            'effect': 'cannot_tell', 'effects': [], 'friction': None, 'reason': 'no_mv',
            'explanation': (
                'Cannot explain a mismatch without the valve position (MV): with OP and PV '
                'alone, dead time, lag and calibration of the valve cannot be told from the '
                "plant's own dynamics, so no effect can be located or named. Record the "
                'positioner feedback (or a flow right after the valve) and run --explain '
                'again; the stiction verdict above is what OP and PV can say.')}
        return
    if args.bootstrap < 0:
        raise ValueError(f'--bootstrap must be 0 or more, got {args.bootstrap}')
    from stiction_ros.cli.batch import default_jobs
    jobs = args.jobs if getattr(args, 'jobs', None) is not None else default_jobs()
    sections, arrays = explain_record(rec.t, rec.signals['op'], rec.signals['mv'],
                                      rec.valve_segments(min_samples=2), rec.sample_time,
                                      holdout=args.holdout, reps=args.bootstrap,
                                      progress=say, jobs=max(1, jobs))
    analysis.report.update(sections)
    analysis.explain_arrays = arrays


def write_text(path, text):
    """Write ``text`` to ``path``, creating its folder."""
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    p.write_text(text + '\n', encoding='utf-8')


def write_html(analysis, path, say):
    """Write the figures beside ``path`` and the HTML page embedding them."""
    from stiction_ros.analysis import figures
    from stiction_ros.analysis.identify import mse_landscape
    from stiction_ros.analysis.report_html import render
    from stiction_ros.analysis.signatures.plots import signature_figure
    html_path = Path(path)
    fig_dir = html_path.with_name(html_path.stem + '_figures')
    fig_dir.mkdir(parents=True, exist_ok=True)
    rec = analysis.record
    paths = [figures.trends_figure(analysis, fig_dir / 'trends.png'),
             figures.maps_figure(analysis, fig_dir / 'maps.png')]
    if getattr(analysis, 'explain_arrays', None) is not None:
        from stiction_ros.analysis.mismatch.figures import mismatch_figure
        paths.append(mismatch_figure(analysis.report, analysis.explain_arrays,
                                     fig_dir / 'mismatch.png'))
    if analysis.signatures:
        x = analysis.signature_inputs
        paths.append(signature_figure(x['op'], x['pv'], rec.sample_time, analysis.signatures,
                                      fig_dir / 'signatures.png'))
    for fit in analysis.fits:
        if fit.source == 'identified':
            land = mse_landscape(rec.signals['op'], rec.signals['mv'], fit,
                                 rec.valve_segments(min_samples=2), rec.sample_time)
            paths.append(figures.landscape_figure(land, fig_dir / f'landscape_{fit.model}.png'))
    write_text(html_path, render(analysis.report, [p for p in paths if p]))
    say(f'wrote {html_path} (figures in {fig_dir})')


def summary_line(report):
    """Return the one-line verdict printed at the end."""
    st = report['stiction']
    word = VERDICT_WORDS[st['detected']]
    fits = '; '.join(f'{f["model"]} S={f["S"]:.2f} J={f["J"]:.2f} MSE={f["mse"]:.4g}'
                     for f in report['fits'])
    if st.get('probability') is not None:
        how = f'probability {st["probability"]:.2f}'
    elif st['detected'] is None:
        how = st.get('reason', '')
    else:
        how = f'score {st["score"]:.2f}'
    line = (f'{report.get("name") or report["input"].get("path")}: {word} ({how})'
            + (f'; {fits}' if fits else ''))
    for ev in st.get('evidence', [])[:2]:
        line += f'\n  evidence: {ev}'
    if st.get('size_withheld'):
        line += f'\n  no size given: {st["size_withheld"]}'
    if 'mismatch' in report and 'baseline' not in report:
        line += f'\nmismatch: cannot tell: {report["mismatch"]["explanation"]}'
    elif 'mismatch' in report:
        m, b = report['mismatch'], report['baseline']
        line += f'\nplain model: kano S={b["S"]:.3f} J={b["J"]:.3f} MSE fit {b["mse_fit"]:.4g}'
        if m.get('regimes'):
            r = m['regimes'][0]
            line += (f'\nlocated: {r["regime"]} holds {100 * r["residual_share"]:.0f} % of the '
                     f'residual in {100 * r["sample_share"]:.0f} % of the samples')
        if m.get('regions'):
            g = m['regions'][0]
            line += (f'; worst stretch t={g["t_start"]:.0f}-{g["t_end"]:.0f} s ({g["regime"]}, '
                     f'{100 * g["residual_share"]:.0f} % of the residual)')
        line += _chain_lines(report)
        names = [e['id'] for e in m.get('effects', [])]
        told = ' '.join(e['sentence'] for e in m['effects']) if names else m['explanation']
        line += (f'\nmismatch: {", ".join(names) or m["effect"]} (confidence '
                 f'{m["confidence"]:.2f}): {told}\nheld-out MSE: plain '
                 f'{b["mse_holdout"]:.4g} -> explained {m["mse_holdout"]:.4g}')
        if m.get('note'):
            line += f'\nnote: {m["note"]}'
        if report['stiction'].get('detected') and m.get('friction') is False:
            line += ('\nnote: the stiction verdict above comes from valve models without dead '
                     'time or calibration; no friction beats the best valve without friction '
                     'here')
    return line


FRICTION_WORDS = {'stiction': 'stiction claimed', 'backlash': 'backlash (play without stick)',
                  'none': 'not claimed'}


def _chain_lines(report):
    f = report.get('frictionless')
    if not f:
        return ''
    kind = report['mismatch'].get('friction_kind', 'none')
    return (f'\nbest valve without friction: dead time {f["dead_time_s"]:.3g} s, lag '
            f'{f["lag_s"]:.3g} s, offset {f["offset"]:+.3g} %, gain {f["gain"]:.4g} (stages '
            f'kept: {", ".join(f["stages"]) or "none"}), held-out MSE {f["mse_holdout"]:.4g}'
            f'\nfriction: {FRICTION_WORDS[kind]}')


def main(argv=None):
    """Entry point of ``stiction-analyze``."""
    args = parser().parse_args(argv)

    def say(msg):
        if not args.quiet:
            print(msg, file=sys.stderr, flush=True)
    try:
        from stiction_ros.cli.batch import expand
        paths = expand(args.input)
        if paths is not None:
            return run_many(args, paths, say)
        report = run(args, say)
    except (InputError, IdentifyError, ValueError, OSError) as exc:
        print(f'stiction-analyze: error: {exc}', file=sys.stderr)
        return EXIT_INPUT
    except DetectorFileError as exc:
        print(f'stiction-analyze: error: {exc}', file=sys.stderr)
        return EXIT_DETECTOR
    print(summary_line(report))
    return 0


if __name__ == '__main__':
    sys.exit(main())
