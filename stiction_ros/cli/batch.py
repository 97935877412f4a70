"""
Many recordings at once: ``stiction-analyze DIR`` or ``stiction-analyze 'plant/*.csv'``.

A plant-wide audit has thousands of recordings, each analysed on its own, so
the work fans out over local processes (``--jobs``) or over a Dask cluster
(``--scheduler ADDRESS``); both run :func:`analyze_one`, the same code.  A
recording that fails is one row with its error, never the end of the audit.
"""

from concurrent.futures import as_completed, ProcessPoolExecutor
import glob
import os
from pathlib import Path
import re
import sys
import time

from stiction_ros.analysis.record import InputError

RECORDING_SUFFIXES = ('.csv', '.txt', '.tsv', '.mcap')


def _is_bag(path):
    return path.is_dir() and ((path / 'metadata.yaml').is_file() or any(path.glob('*.mcap')))


def _walk(folder):
    # Bags are directories too: a bag is one recording, any other folder is searched.
    found = []
    for p in sorted(folder.iterdir()):
        if p.name.startswith('.'):
            continue
        if _is_bag(p):
            found.append(p)
        elif p.is_dir():
            found += _walk(p)
        elif p.suffix.lower() in RECORDING_SUFFIXES:
            found.append(p)
    return found


def expand(source):
    """
    Return the recordings ``source`` names when it names several, else None.

    A glob (``*``, ``?``, ``[``) names what it matches; a directory that is not
    a bag names every bag, CSV, historian export (.txt/.tsv) and .mcap below it.
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
    """Return a file name for the report of ``path``, unique within ``root``."""
    try:
        rel = Path(path).resolve().relative_to(Path(root).resolve())
    except ValueError:
        rel = Path(path)
    return re.sub(r'[^A-Za-z0-9._-]+', '_', str(rel).strip('/')) + '.json'


def analyze_one(path, argv, out_dir=None, root='.'):
    """
    Analyse one recording as ``stiction-analyze PATH ARGV`` would; return its summary row.

    Runs in a worker process or on a Dask worker, so it returns plain data and
    never raises for a bad recording.
    """
    from stiction_ros.analysis.detection.model_file import DetectorFileError
    from stiction_ros.analysis.identify import IdentifyError
    from stiction_ros.cli.analyze import parser, run, summary_line, to_json_text, write_text
    t0 = time.perf_counter()
    row = {'input': str(path), 'ok': False}
    try:
        args = parser().parse_args([str(path), *argv])
        args.json_path = args.html_path = None
        report = run(args, lambda msg: None)
    except (InputError, IdentifyError, ValueError, OSError, DetectorFileError) as exc:
        row['error'] = str(exc)
    else:
        st = report['stiction']
        row.update(ok=True, detected=st['detected'], score=st['score'],
                   fits=[{k: f[k] for k in ('model', 'S', 'J', 'mse')} for f in report['fits']],
                   summary=summary_line(report))
        if 'mismatch' in report:
            row['effect'] = report['mismatch']['effect']
        if out_dir is not None:
            target = Path(out_dir) / report_name(path, root)
            write_text(target, to_json_text(report))
            row['report'] = str(target)
    row['seconds'] = round(time.perf_counter() - t0, 3)
    return row


def _results(paths, argv, jobs, scheduler, out_dir, root):
    # Yields rows as they finish, whichever way the work is spread.
    if scheduler:
        from distributed import as_completed as dask_completed, Client
        with Client(scheduler) as client:
            futures = client.map(analyze_one, paths, argv=argv, out_dir=out_dir, root=root,
                                 pure=False)
            for future in dask_completed(futures):
                yield future.result()
    elif jobs > 1 and len(paths) > 1:
        with ProcessPoolExecutor(max_workers=min(jobs, len(paths))) as pool:
            futures = [pool.submit(analyze_one, p, argv, out_dir, root) for p in paths]
            for future in as_completed(futures):
                yield future.result()
    else:
        for p in paths:
            yield analyze_one(p, argv, out_dir, root)


def progress_line(done, total, elapsed, row):
    """Return the progress bar after ``done`` of ``total`` recordings."""
    width = 24
    filled = int(width * done / total)
    rate = done / elapsed if elapsed > 0 else 0.0
    eta = (total - done) / rate if rate > 0 else 0.0
    from stiction_ros.cli.analyze import VERDICT_WORDS
    verdict = VERDICT_WORDS[row['detected']] if row['ok'] else 'error'
    return (f'[{"#" * filled}{"." * (width - filled)}] {done}/{total} {rate:.2f}/s '
            f'ETA {eta:.0f} s  {Path(row["input"]).name}: {verdict}')


def run_batch(paths, argv, jobs=1, scheduler=None, out_dir=None, root='.', say=None):
    """Analyse every path; return (rows in the order of ``paths``, seconds)."""
    t0 = time.perf_counter()
    rows = {}
    tty = sys.stderr.isatty()
    for row in _results(paths, argv, jobs, scheduler, out_dir, root):
        rows[row['input']] = row
        if say is not None:
            line = progress_line(len(rows), len(paths), time.perf_counter() - t0, row)
            if tty:
                print('\r' + line, end='' if len(rows) < len(paths) else '\n',
                      file=sys.stderr, flush=True)
            else:
                say(line)
    return [rows[str(p)] for p in paths], time.perf_counter() - t0


def default_jobs():
    """Return the cores this process may use."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not Linux
        return os.cpu_count() or 1
