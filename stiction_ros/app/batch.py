"""
Many recordings at once: ``stiction-analyze DIR`` or ``stiction-analyze 'plant/*.csv'``.

A plant-wide audit has thousands of recordings, each analysed on its own, so
the work fans out over local processes (``jobs``) or over a Dask cluster
(``scheduler``); both run :func:`analyze_one`, the same code, on a copy of
the one :class:`~stiction_ros.app.analyze.AnalyzeOptions` (it pickles).  A
recording that fails is one row with its error, never the end of the audit.
"""

from __future__ import annotations

from concurrent.futures import as_completed
from dataclasses import dataclass, field, replace
from datetime import datetime, timezone
import glob
import hashlib
from pathlib import Path
import re
import time

from stiction_ros._threads import worker_pool
from stiction_ros.analysis.oscillation import period_sanity
from stiction_ros.analysis.plantwide import CycleMember, PlantWide, shared_cycles
from stiction_ros.analysis.readers.sniff import AS_CSV
from stiction_ros.app.analyze import (
    analyze_file, AnalyzeOptions, default_jobs, print_nothing, Say)
from stiction_ros.app.progress import Step
from stiction_ros.app.report_files import write_html, write_json
from stiction_ros.app.report_text import summary_line, VERDICT_WORDS
from stiction_ros.errors import InputError, StictionError

RECORDING_SUFFIXES = ('.csv', '.txt', '.tsv', '.mcap')
# Not read, but listed: each gets a row saying to save its sheet as CSV, rather
# than a folder's workbook vanishing from the batch without a word.
WORKBOOK_SUFFIXES = ('.xlsx', '.xls', '.ods')
# With MV, the fits' own reasons to answer cannot tell, in a tally's words.
FITS_CANNOT_TELL = {'slip_unresolved': 'slip jump unresolved', 'noisy_mv': 'MV noise',
                    'frictionless_fits': 'frictionless valve fits',
                    'unexplained_mv': 'MV unexplained', 'few_slips': 'too few slips',
                    'reading_fault': 'reading fault', 'noise_unknown': 'MV noise unknown'}


def _is_bag(path):
    # A rosbag2 directory: its metadata.yaml, or (a recorder killed before writing
    # that) files named as rosbag2 names them, <directory>_<n>.mcap, and no other .mcap.
    # A folder of loose .mcap files holds that many recordings, never one merged bag.
    if not path.is_dir():
        return False
    if (path / 'metadata.yaml').is_file():
        return True
    files = list(path.glob('*.mcap'))
    split = re.compile(re.escape(path.resolve().name) + r'_\d+\.mcap')
    return bool(files) and all(split.fullmatch(f.name) for f in files)


def _walk(folder):
    # Bags are directories too: a bag is one recording, any other folder is searched.
    found = []
    for p in sorted(folder.iterdir()):
        # Hidden files, and the lock file Excel keeps beside an open workbook.
        if p.name.startswith(('.', '~$')):
            continue
        if _is_bag(p):
            found.append(p)
        elif p.is_dir():
            found += _walk(p)
        elif p.suffix.lower() in RECORDING_SUFFIXES + WORKBOOK_SUFFIXES:
            found.append(p)
    return found


def expand(source):
    """
    Return the recordings ``source`` names when it names several, else None.

    A glob (``*``, ``?``, ``[``) names what it matches; a directory that is not
    a bag names every bag, CSV, historian export (.txt/.tsv) and .mcap below it,
    and every workbook (.xlsx, .xls, .ods), which its row then refuses with the fix.
    """
    if any(c in source for c in '*?['):
        paths = sorted(glob.glob(source, recursive=True))
        if not paths:
            raise InputError(f'{source}: no file matches')
        return paths
    path = Path(source)
    if path.is_dir() and not _is_bag(path):
        found = _walk(path)
        if not found:
            raise InputError(f'{path}: no recordings here (no bag, .csv, .txt, .tsv or .mcap '
                             'below it)')
        return [str(p) for p in found]
    return None


def report_name(path, root):
    """Return a file name for the report of ``path``: its path below ``root``, flattened."""
    try:
        rel = Path(path).resolve().relative_to(Path(root).resolve())
    except ValueError:
        rel = Path(path)
    return re.sub(r'[^A-Za-z0-9._-]+', '_', str(rel).strip('/')) + '.json'


def report_names(paths, root) -> dict[str, str]:
    """
    Return {path: report file name}, every name different.

    Flattening can give two recordings one name (``a/b/c.csv`` and
    ``a_b/c.csv``); each of those then carries a hash of its own path, so
    that no report overwrites another.
    """
    names = {str(p): report_name(p, root) for p in paths}
    count: dict[str, int] = {}
    for name in names.values():
        count[name.lower()] = count.get(name.lower(), 0) + 1
    for p, name in names.items():
        if count[name.lower()] > 1:
            tag = hashlib.sha1(str(Path(p).resolve()).encode()).hexdigest()[:8]
            names[p] = f'{name[:-len(".json")]}-{tag}.json'
    return names


def analyze_one(path: str | Path, options: AnalyzeOptions, out_dir: str | Path | None = None,
                root: str | Path = '.', name: str | None = None, pages: bool = False) -> dict:
    """
    Analyse one recording with ``options`` (its ``input`` replaced by ``path``).

    Its JSON report goes to ``out_dir`` (if given) as ``name``, by default
    :func:`report_name` of ``path`` below ``root``; with ``pages`` its HTML
    page too, under the same name ending ``.html``.

    Runs in a worker process or on a Dask worker, so it returns plain data and
    never raises for a bad recording.

    Returns
    -------
    dict
        The summary row: ``input``, ``ok``, then ``detected``, ``answer``,
        ``probability`` (OP/PV only), ``score`` (None where the record could not be
        judged), ``fits``, ``summary``, ``warnings`` (what the input's reader
        said, such as a bag that ends early; empty when nothing), ``notes`` (how
        the file was read, as the terminal's ``note:`` lines: a column
        ignored, cells read as missing, a change of clocks) (and
        ``why_not``, ``effect``, ``report``, ``page``) or ``error``; ``seconds``.

    """
    t0 = time.perf_counter()
    row = {'input': str(path), 'ok': False, 'warnings': [], 'notes': []}
    if Path(path).suffix.lower() in WORKBOOK_SUFFIXES:
        # Listed so that it is not lost without a word; not read, so not a failure.
        row.update(skipped=True,
                   error=f'{path}: a workbook, not read: save its sheet {AS_CSV} to include it')
        row['seconds'] = round(time.perf_counter() - t0, 3)
        return row
    try:
        # Each worker is one process already: its --explain runs on one thread.
        one = replace(options, input=str(path), json_path=None, html_path=None, jobs=1)
        analysis = analyze_file(one)
        report = analysis.report
    except (StictionError, OSError) as exc:
        row['error'] = str(exc)
    else:
        st = report['stiction']
        if st['detected'] is None:
            row['why_not'] = _why_not(st)
        judged = st['detected'] is not None or st.get('probability') is not None
        warnings = list((report.get('input') or {}).get('warnings') or [])
        # A record that could not be judged has no score; 0 would sort it with the healthy.
        row.update(ok=True, detected=st['detected'], answer=st.get('answer'),
                   probability=st.get('probability'), score=st['score'] if judged else None,
                   fits=[{k: f[k] for k in ('model', 'S', 'J', 'mse')} for f in report['fits']],
                   summary=summary_line(report),
                   warnings=warnings,
                   notes=[n for n in analysis.record.notes
                          if not n.startswith('excluded ') and n not in warnings])
        if 'mismatch' in report:
            row['effect'] = report['mismatch']['effect']
        # Always there (null when it does not apply): a script reads every row alike.
        row.update(cycle=cycle_of(report), shared_cycle=None)
        if out_dir is not None:
            target = Path(out_dir) / (name or report_name(path, root))
            try:
                write_json(target, report)
            except OSError as exc:
                # One row's error, not the end of the audit.
                why = exc.strerror or exc
                row.update(ok=False, error=f'cannot write its report (--out-dir) {target}: {why}')
            else:
                row['report'] = str(target)
            if pages and row['ok']:
                _write_page(analysis, target, row)
    row['seconds'] = round(time.perf_counter() - t0, 3)
    return row


def _write_page(analysis, report_path: Path, row: dict) -> None:
    """Write the recording's HTML page beside its JSON report, naming it in ``row``."""
    page = report_path.with_name(report_path.name[:-len('.json')] + '.html')
    try:
        write_html(analysis, page, say=print_nothing)
    except OSError as exc:
        row.update(ok=False, error=f'cannot write its page (--pages) {page}: '
                                   f'{exc.strerror or exc}')
    except Exception as exc:
        # A bug in drawing one page must not end an audit of thousands: the row names it.
        row.update(ok=False, error=f'its page (--pages) {page} failed: a bug, please report: '
                                   f'{type(exc).__name__}: {exc}')
    else:
        row['page'] = str(page)


def cycle_of(report: dict) -> dict | None:
    """
    Return the record's resolvable cycle for the shared-cycle view, or None.

    ``period_s``; ``start``/``end`` of the stretch the signatures read, in
    seconds on the time base ``clock``: ``UTC`` for a clock time with a zone
    (a bag, Unix seconds), ``no zone`` for one without (a historian export,
    read as written, so that two such exports of one plant compare); all
    None when the record has no clock time.
    """
    osc = (report.get('stiction') or {}).get('oscillation') or {}
    period = osc.get('period_s')
    ts = report.get('sample_time')
    window = report.get('signature_window') or {}
    n = window.get('samples') or report.get('samples')
    if not osc.get('oscillating') or not period or not ts or not n:
        return None
    if period_sanity(period, ts, n):
        return None
    start = end = clock = None
    if report.get('start_time'):
        try:
            t0 = datetime.fromisoformat(report['start_time'])
        except (TypeError, ValueError):
            t0 = None
        if t0 is not None:
            clock = 'no zone' if t0.tzinfo is None else 'UTC'
            base = t0.replace(tzinfo=timezone.utc) if t0.tzinfo is None else t0
            start = base.timestamp() + float(window.get('start_s', 0.0))
            end = base.timestamp() + float(window.get('end_s', (n - 1) * ts))
    return {'period_s': round(float(period), 3), 'start': start, 'end': end, 'clock': clock}


def plant_wide(rows: list[dict]) -> PlantWide:
    """Return the cycles the recordings of ``rows`` share, and note each member's row."""
    members = [CycleMember(r['input'], r['cycle']['period_s'], r.get('probability'),
                           r['cycle'].get('start'), r['cycle'].get('end'),
                           r['cycle'].get('clock'))
               for r in rows if r.get('ok') and r.get('cycle')]
    shared = shared_cycles(members)
    for r in rows:
        group = shared.group_of(r['input'])
        if group is not None:
            r['shared_cycle'] = group.note_for(r['input'])
    return shared


def _analyze_named(path, name, options, out_dir, root, pages=False):
    # For Dask's map, which pairs each path with its name by position.
    return analyze_one(path, options, out_dir, root, name, pages)


def _why_not(st: dict) -> str:
    """Return in a few words why a recording got no answer (the tally's breakdown)."""
    det = st.get('detector') or {}
    if det.get('balanced'):
        return 'evidence balanced'
    code = (det.get('judgeable') or {}).get('code')
    if st.get('cannot_tell') in FITS_CANNOT_TELL:
        return FITS_CANNOT_TELL[st['cannot_tell']]
    if code:
        return code.replace('_', ' ')
    # No check named: the reason's first words say more than a bare "other".
    head = str(st.get('reason') or 'no reason given')
    for mark in ':;(':
        head = head.split(mark, 1)[0]
    return ' '.join(head.split()[:5]) or 'no reason given'


def _results(paths, options, jobs, scheduler, out_dir, root, pages=False):
    # Yields rows as they finish, whichever way the work is spread.
    names = report_names(paths, root)
    if scheduler:
        from distributed import as_completed as dask_completed, Client
        with Client(scheduler) as client:
            # Keywords go to every call alike; each name goes with its own path.
            futures = client.map(_analyze_named, paths, [names[str(p)] for p in paths],
                                 options=options, out_dir=out_dir, root=root, pages=pages,
                                 pure=False)
            for future in dask_completed(futures):
                yield future.result()
    elif jobs > 1 and len(paths) > 1:
        with worker_pool(min(jobs, len(paths))) as pool:
            futures = [pool.submit(analyze_one, p, options, out_dir, root, names[str(p)], pages)
                       for p in paths]
            for future in as_completed(futures):
                yield future.result()
    else:
        for p in paths:
            yield analyze_one(p, options, out_dir, root, names[str(p)], pages)


def progress_step(done: int, total: int, elapsed: float, row: dict) -> Step:
    """Return the progress after ``done`` of ``total`` recordings, the last one's verdict."""
    rate = done / elapsed if elapsed > 0 else 0.0
    eta = (total - done) / rate if rate > 0 else 0.0
    verdict = (VERDICT_WORDS[row['detected']] if row['ok']
               else 'skipped' if row.get('skipped') else 'error')
    return Step('recordings', done, total,
                f'{rate:.2f}/s, ETA {eta:.0f} s; {Path(row["input"]).name}: {verdict}')


def run_batch(paths: list[str], options: AnalyzeOptions, jobs: int = 1,
              scheduler: str | None = None, out_dir: str | Path | None = None,
              root: str | Path = '.', say: Say | None = None,
              pages: bool = False) -> tuple[list[dict], float]:
    """
    Analyse every path with ``options``; return (rows in the order of ``paths``, seconds).

    ``say`` receives a counted :class:`~stiction_ros.app.progress.Step` per
    finished recording (a terminal draws them as one bar); None: no progress.
    """
    t0 = time.perf_counter()
    rows = {}
    for row in _results(paths, options, jobs, scheduler, out_dir, root, pages):
        rows[row['input']] = row
        if say is not None:
            say(progress_step(len(rows), len(paths), time.perf_counter() - t0, row))
    return [rows[str(p)] for p in paths], time.perf_counter() - t0


@dataclass
class Batch:
    """The rows of a batch run and what its summary says about them."""

    source: str
    rows: list[dict]
    seconds: float
    workers: str
    shared: PlantWide = field(default_factory=PlantWide)

    @property
    def failed(self) -> int:
        """Return the number of recordings that could not be analysed (workbooks aside)."""
        return sum(not r['ok'] and not r.get('skipped') for r in self.rows)

    @property
    def skipped(self) -> int:
        """Return the number of workbooks listed but not read."""
        return sum(bool(r.get('skipped')) for r in self.rows)

    def tally(self) -> dict[str, int]:
        """Return {verdict word: recordings} over the recordings analysed."""
        tally: dict[str, int] = {}
        for r in self.rows:
            if r['ok']:
                word = VERDICT_WORDS[r['detected']]
                tally[word] = tally.get(word, 0) + 1
        return tally

    def why_not(self) -> dict[str, int]:
        """Return {reason: recordings} over the recordings answered ``cannot tell``."""
        out: dict[str, int] = {}
        for r in self.rows:
            if r['ok'] and r['detected'] is None:
                # A row from an older worker (a Dask cluster's) may lack it.
                why = r.get('why_not', 'reason not given')
                out[why] = out.get(why, 0) + 1
        return out

    def summary(self) -> dict:
        """Return the batch report (``--json``): counts, time, workers and every row."""
        return {'input': self.source, 'recordings': len(self.rows), 'failed': self.failed,
                'skipped': self.skipped,
                'seconds': round(self.seconds, 3), 'workers': self.workers,
                'shared_cycles': self.shared.to_json(),
                'not_compared': self.shared.not_compared_json(), 'rows': self.rows}


def analyze_many(options: AnalyzeOptions, paths: list[str], scheduler: str | None = None,
                 out_dir: str | Path | None = None, say: Say | None = None,
                 pages: bool = False) -> Batch:
    """
    Analyse every recording in ``paths`` on its own with ``options``.

    Parameters
    ----------
    options : AnalyzeOptions
        The options of each recording; ``input`` is the folder or glob that
        :func:`expand` turned into ``paths``, ``jobs`` the worker processes
        (None: every core) and ``json_path`` is left to the caller.
    paths : list of str
        The recordings.
    scheduler : str, optional
        Address of a Dask scheduler (``tcp://host:8786``) to run on instead of
        local processes.
    out_dir : str or Path, optional
        Where to write a JSON report per recording.
    pages : bool
        Also write each recording's HTML page there (``out_dir`` needed).
    say : callable, optional
        Receives the start line and a progress line per recording.

    Returns
    -------
    Batch
        The rows in the order of ``paths``, the seconds and the workers used.

    """
    if options.html_path:
        raise InputError('--html takes one recording; for many use --out-dir (JSON reports) '
                         'with --pages (a page each)')
    if pages and out_dir is None:
        raise InputError('--pages writes each page beside its JSON report: give --out-dir')
    jobs = options.jobs if options.jobs is not None else default_jobs()
    where = f'Dask cluster {scheduler}' if scheduler else f'{jobs} process(es)'
    (say or print_nothing)(f'{len(paths)} recordings from {options.input} on {where}')
    root = options.input if Path(options.input).is_dir() else '.'
    rows, seconds = run_batch(paths, options, jobs, scheduler, out_dir, root, say, pages)
    return Batch(options.input, rows, seconds, where, plant_wide(rows))
