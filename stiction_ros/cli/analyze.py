"""
stiction-analyze: is this valve sticking, how much, and how well do the models fit.

    stiction-analyze INPUT [--model kano|choudhury|both] [--S S --J J]
                     [--fit-filter] [--window T0 T1] [--namespace NS]
                     [--columns op=COL,pv=COL,...] [--date-order dmy|mdy]
                     [--loop-type auto|self-regulating|integrating]
                     [--json REPORT.json] [--html REPORT.html]

INPUT is a rosbag2 directory or .mcap file, a CSV or a historian export (see
INPUTS below).  Problems with the input end in one line on stderr and exit
status 2.

INPUT may also be a folder of recordings or a quoted glob ('plant/**/*.csv'):
each is analysed on its own, over ``--jobs`` processes or a Dask cluster
(``--scheduler tcp://HOST:8786``); one line per recording, ``--json`` the
summary of all, ``--out-dir`` a report per recording (and with ``--pages``
its HTML page, and an index.html linking them) (stiction_ros.app.batch).
Recordings that cycle at one period (within 15 %) over the same hours are
listed together after them, with the likely source: the loop whose
stiction probability is 0.5 or more and 0.2 above the others' (README,
"Cycles shared between recordings").
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
from typing import TYPE_CHECKING

# Only what --help needs is imported here: the analysis (numpy, scipy, numba)
# loads in main(), so that the help answers in the time Python starts.
from stiction_ros.app.choices import DATE_ORDERS, LOOP_TYPES, MODEL_CHOICES
from stiction_ros.cli.text import description, pipe_safe
from stiction_ros.errors import DetectorFileError, InputError, StictionError

if TYPE_CHECKING:
    from stiction_ros.app.analyze import AnalyzeOptions, Say
    from stiction_ros.app.batch import Batch

EXIT_INPUT = 2
# The learned detector's model file is missing or damaged: the install, not the input.
EXIT_DETECTOR = 3

EPILOG = """\
inputs:
  bag        a rosbag2 directory or .mcap file with std_msgs/Float64 topics op and any
             of mv, pv, sp (under one namespace: --namespace)
  CSV        a header row, then one row per sample, separated by , or ; or tab:
             time   t, time, timestamp, datetime, 'Time (s)', 'time [ms]', 'Timestamp
                    (UTC)', or date + time columns: seconds, or dates such as
                    2026-03-01 12:00:00, 2026-03-01T12:00:00Z, 2026-03-01T12:00:00+01:00,
                    01.03.2026 12:00:00, 13-Jun-24 14:00, Jun 13, 2024 2:00 PM
                    (--date-order dmy or mdy where no day over 12 shows the order)
             op     controller output (required), mv valve position, pv, sp: named
                    so, or by tag: FIC101.OP, FIC101_PV, 'FIC101 SP' (.SV is sp; a
                    lone FIC101.MV is the controller output, as DCS historians name it)
             anything else: --columns op=FIC101.OUT,pv=FIC101.MEAS,t=Zeit
             decimal commas (1,25) are read in files separated by ; or tab; rows
             that are not on one sample grid are resampled (linear interpolation
             between stored values; the period and why are in the report's notes)
  historian  an export whose first line is PROCESSDATA (<TAG>.MV is the controller
             output)
  Excel      .xlsx/.xls/.ods are refused: save the sheet as CSV (File > Save As >
             CSV UTF-8) and pass that file

exit status:
  0  analysed (many recordings: all of them)
  2  bad input or option: one line on stderr names the problem and the fix (many
     recordings: any failed)
  3  the learned detector's model file is missing or damaged
"""


def parser() -> argparse.ArgumentParser:
    """Return the argument parser."""
    p = argparse.ArgumentParser(prog='stiction-analyze', description=description(__doc__),
                                epilog=EPILOG,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument('input', help='rosbag2 directory, .mcap file, CSV or historian export '
                                 '(see inputs below)')
    p.add_argument('--model', default='both', choices=MODEL_CHOICES,
                   help='model(s) to fit when MV is present (default both)')
    p.add_argument('--S', type=float, help='use this S (%%) instead of identifying it')
    p.add_argument('--J', type=float, help='use this J (%%) instead of identifying it')
    p.add_argument('--fit-filter', action='store_true',
                   help='also identify the air-chamber lag (kano) or EWMA weight (choudhury)')
    p.add_argument('--window', nargs=2, type=float, metavar=('T0', 'T1'),
                   help='analyse only T0 <= t <= T1, seconds from the start of the record')
    p.add_argument('--namespace', help='namespace of the loop topics in a bag, e.g. /loop1')
    p.add_argument('--columns', metavar='SIGNAL=COLUMN,...', action='append',
                   help='which CSV or historian columns hold t, op, mv, pv, sp, mode where '
                        'their names do not say, e.g. op=FIC101.OP,pv=FIC101.PV,t=Timestamp '
                        '(given more than once, all of them count)')
    p.add_argument('--date-order', choices=DATE_ORDERS, default=None,
                   help="a CSV's dates where no day over 12 shows the order: dmy (day first, "
                        '03/01/2026 is 3 January) or mdy (month first, 1 March); without it '
                        'such dates are refused, or read by a convention with a note (dots '
                        'day first, AM/PM month first)')
    p.add_argument('--loop-type', default='auto', choices=LOOP_TYPES,
                   help='auto: integrating when the tag names a level loop (LIC)')
    p.add_argument('--detector', metavar='FILE', default=None,
                   help='learned stiction detector model file (default: the shipped one, '
                        'rebuilt by `make detector`)')
    p.add_argument('--no-hammerstein', action='store_true',
                   help='skip the Hammerstein quantification of S and J from OP and PV')
    p.add_argument('--explain', action='store_true',
                   help='needs MV: locate where the plain Kano model misses, name the missing '
                        'physics (docs/EFFECTS.md), fit it and compare held-out MSE')
    p.add_argument('--holdout', type=float, default=0.3,
                   help='share of samples at the end kept out of every fit and choice '
                        '(default 0.3)')
    p.add_argument('--bootstrap', type=int, default=3,
                   help='effect-free replicates that calibrate the choice (default 3)')
    p.add_argument('--json', dest='json_path', metavar='REPORT.json', help='write the report')
    p.add_argument('--html', dest='html_path', metavar='REPORT.html',
                   help='write the HTML report (figures embedded, PNGs beside it)')
    p.add_argument('--quiet', action='store_true', help='no progress on stderr')
    many = p.add_argument_group(
        'many recordings (INPUT a folder or a quoted glob)',
        'Each recording is analysed on its own. Those that cycle at one period\n'
        '(within 15 %) over the same hours are listed together after them, with the\n'
        'likely source: the loop whose stiction probability is 0.5 or more and 0.2\n'
        "above the others'. Pairs at one period whose clock times keep them apart\n"
        'are listed as not compared.')
    many.add_argument('--jobs', type=int, default=None,
                      help='worker processes; for one recording, threads of --explain '
                      '(default: every core this process may use)')
    many.add_argument('--scheduler', metavar='ADDRESS',
                      help='run on this Dask cluster (tcp://host:8786) instead of local processes')
    many.add_argument('--out-dir', metavar='DIR', help='write a JSON report per recording here '
                      '(one recording: its report, named as in a folder run)')
    many.add_argument('--pages', action='store_true',
                      help='with --out-dir: an HTML page per recording beside its report '
                      '(figures drawn: a few seconds more each)')
    return p


def options_from_args(args: argparse.Namespace) -> AnalyzeOptions:
    """
    Return the :class:`AnalyzeOptions` of parsed arguments.

    Attributes the namespace lacks take the defaults of ``stiction-analyze``,
    so a namespace made by hand with only some of them still works.
    """
    from stiction_ros.app.analyze import AnalyzeOptions
    given = vars(args)
    names = {f.name for f in dataclasses.fields(AnalyzeOptions)}
    kwargs = {k: v for k, v in given.items() if k in names}
    if isinstance(kwargs.get('columns'), list):
        # --columns op=A --columns pv=B is one list; a signal named twice is refused.
        kwargs['columns'] = ','.join(kwargs['columns'])
    if 'no_hammerstein' in given:
        kwargs['hammerstein'] = not given['no_hammerstein']
    return AnalyzeOptions(**kwargs)


def run_many(args: argparse.Namespace, options: AnalyzeOptions, paths: list[str],
             say: Say) -> Batch:
    """Analyse every recording in ``paths``; write the ``--json`` summary; return the batch."""
    from stiction_ros.app.batch import analyze_many
    from stiction_ros.app.report_files import write_index, write_json
    pages = getattr(args, 'pages', False)
    batch = analyze_many(options, paths, args.scheduler, args.out_dir, say, pages)
    if options.json_path:
        write_json(options.json_path, batch.summary())
        say(f'wrote {options.json_path}')
    if pages:
        say(f'wrote {write_index(batch.summary(), args.out_dir)}')
    return batch


def one_report_in(options: AnalyzeOptions, out_dir: str | None,
                  pages: bool = False) -> AnalyzeOptions:
    """
    Return ``options`` with its JSON report in ``out_dir`` (one recording, ``--out-dir``).

    A script that audits a folder file by file gets the report (and with
    ``pages`` the page) where a folder's run would put it, rather than none
    without a word.
    """
    if not out_dir:
        if pages:
            raise InputError('--pages writes each page beside its JSON report: give --out-dir')
        return options
    if options.json_path:
        raise InputError('--out-dir and --json both say where the report of one recording '
                         'goes; give one of them')
    from pathlib import Path
    from stiction_ros.app.batch import report_name
    source = Path(options.input).resolve()
    report = Path(out_dir) / report_name(source, source.parent)
    if pages and options.html_path:
        raise InputError('--pages and --html both say where the page of one recording goes; '
                         'give one of them')
    page = str(report.with_name(report.name[:-len('.json')] + '.html')) if pages else None
    return dataclasses.replace(options, json_path=str(report),
                               html_path=page or options.html_path)


def shared_cycle_lines(batch: Batch) -> list[str]:
    """Return a line per period that several recordings cycle at, its likely source named."""
    out = []
    for g in batch.shared.groups:
        # The paths as given: two level.csv of different units must not read as one.
        names = ', '.join(
            f'{m.name} (' + ('-' if m.p is None else f'{m.p:.3f}')
            + (', likely source' if m.name == g.source else '') + ')' for m in g.members)
        clock = '' if g.clock else '; no clock times: taken as recorded together'
        source = '' if g.source else f'; source cannot be told: {g.reason}'
        out.append(f'cycle of {g.period_s:.0f} s in {len(g.members)} loops: {names}'
                   f'{source}{clock}')
    # A missing group must not read as "not coupled" when the clocks kept them apart.
    for n in batch.shared.not_compared:
        out.append(f'cycle of {n.period_s:.0f} s in {n.names[0]} and {n.names[1]} not '
                   f'compared: {n.reason}')
    return out


def print_many(batch: Batch) -> int:
    """Print a line per recording and the tally; return the exit status."""
    from stiction_ros.app.report_text import batch_row_text, VERDICT_WORDS
    for row in batch.rows:
        print(batch_row_text(row))
    for line in shared_cycle_lines(batch):
        print(line)
    failed, where = batch.failed, batch.workers
    rows, seconds = batch.rows, batch.seconds
    why = ', '.join(f'{n} {w}' for w, n in sorted(batch.why_not().items()))
    # A balanced case wants a travel test, an unjudgeable one what its reason names.
    words = [f'{n} {w}' + (f' ({why})' if w == VERDICT_WORDS[None] and why else '')
             for w, n in sorted(batch.tally().items())]
    words += [f'{failed} failed'] if failed else []
    skipped = batch.skipped
    words += [f'{skipped} workbook{"s" if skipped != 1 else ""} skipped'] if skipped else []
    print(f'{len(rows)} recording{"s" if len(rows) != 1 else ""} in {seconds:.1f} s '
          f'({len(rows) / seconds:.2f}/s on {where}): ' + ', '.join(words))
    # Nothing analysed (only workbooks) is no audit either.
    return EXIT_INPUT if failed or not any(r['ok'] for r in rows) else 0


@pipe_safe
def main(argv: list[str] | None = None) -> int:
    """Entry point of ``stiction-analyze``."""
    args = parser().parse_args(argv)
    from stiction_ros.app.analyze import analyze_file
    from stiction_ros.app.batch import expand
    from stiction_ros.app.progress import terminal_progress, terminal_width
    from stiction_ros.app.report_text import summary_text
    batch = None
    try:
        # The progress display ends before anything goes to stdout: on a terminal both
        # share the screen, and the live status line would cut through the answer.
        with terminal_progress(enabled=not args.quiet) as say:
            options = options_from_args(args)
            paths = expand(options.input)
            if paths is not None:
                batch = run_many(args, options, paths, say)
            else:
                options = one_report_in(options, args.out_dir, args.pages)
                report = analyze_file(options, say).report
    except DetectorFileError as exc:
        print(f'stiction-analyze: error: {exc}', file=sys.stderr)
        return EXIT_DETECTOR
    except (StictionError, OSError) as exc:
        # Only the package's own errors are bad input; anything else is a bug and
        # keeps its traceback.
        print(f'stiction-analyze: error: {exc}', file=sys.stderr)
        return EXIT_INPUT
    if batch is not None:
        return print_many(batch)
    files = [p for p in (options.json_path, options.html_path) if p]
    print(summary_text(report, files, terminal_width() if sys.stdout.isatty() else None))
    return 0


if __name__ == '__main__':
    sys.exit(main())
