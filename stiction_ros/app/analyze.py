"""
Analyse one recording as ``stiction-analyze`` does, without the command line.

    from stiction_ros.app.analyze import analyze_file, AnalyzeOptions
    analysis = analyze_file(AnalyzeOptions('loop.csv', explain=True, json_path='r.json'))
    analysis.report['stiction']['detected']

:class:`AnalyzeOptions` holds every option of ``stiction-analyze`` for one
recording, checked when it is made: a bad value raises
:class:`~stiction_ros.errors.InputError` naming the option and the fix, before
any file is read.  The command line, the batch workers (stiction_ros.app.batch)
and the analyzer node all go through :func:`analyze_file`.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from dataclasses import dataclass
import math
import numbers
import os
from pathlib import Path
import time
from typing import Callable, TYPE_CHECKING

from stiction_ros.app.choices import DATE_ORDERS, LOOP_TYPES, MODEL_CHOICES
from stiction_ros.app.progress import print_nothing, Step
from stiction_ros.errors import InputError, ReportWriteError

if TYPE_CHECKING:  # pragma: no cover - for the annotations only
    from stiction_ros.analysis.identify import SearchProgress
    from stiction_ros.analysis.pipeline import Analysis
    from stiction_ros.analysis.record import Record

# LOOP_TYPES and MODEL_CHOICES are the choices of stiction_ros.analysis.pipeline.Options,
# repeated so that making and checking options does not load the analysis (a second).
# explain_record's limit: at least a tenth of the record must stay for the fits.
HOLDOUT_MAX = 0.9
# What --columns may name: the time and the readers' signals (stiction_ros.analysis.record).
COLUMN_KEYS = ('t', 'op', 'mv', 'pv', 'sp', 'mode')
# Files a report must never be written over (the readers' suffixes, and a bag's files).
RECORDING_SUFFIXES = ('.csv', '.txt', '.tsv', '.mcap', '.db3', '.yaml', '.xlsx', '.xls', '.ods')
COLUMNS_FIX = 'write SIGNAL=COLUMN pairs, e.g. --columns op=FIC101.OP,pv=FIC101.PV,t=Timestamp'

Say = Callable[[str], None]
# identify.search's grid: its resolution and coarse points (its defaults, as the pipeline
# calls it); the levels shown as 'level 2/5' follow from them.
SEARCH_RESOLUTION = 0.01
SEARCH_COARSE_POINTS = 96


def default_jobs() -> int:
    """Return the number of cores this process may use."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not Linux
        return os.cpu_count() or 1


def _same_file(a: str, b: str) -> bool:
    """Return whether paths ``a`` and ``b`` name one file (links and ``..`` resolved)."""
    try:
        if os.path.exists(a) and os.path.exists(b):
            return os.path.samefile(a, b)
        return Path(a).resolve() == Path(b).resolve()
    except OSError:
        return False


def _path_or_none(value, name):
    if value is None:
        return None
    if not isinstance(value, (str, os.PathLike)):
        raise InputError(f'{name} must be a path (str or Path), got {value!r}')
    return os.fspath(value)


def parse_columns(value: object) -> tuple[tuple[str, str], ...] | None:
    """
    Return ``--columns`` as ``((signal, column), ...)`` in the order t, op, mv, pv, sp, mode.

    ``value`` is None, text (``'op=FIC101.OP,pv=FIC101.PV'``), a mapping or
    pairs.  Raises :class:`InputError` naming the fix for an unknown signal,
    an empty column name, a signal given twice or a column given for two.
    """
    if value is None:
        return None
    if isinstance(value, str):
        pairs = []
        for part in (p for p in value.split(',') if p.strip()):
            if '=' not in part:
                raise InputError(f'--columns: {part.strip()!r} is not SIGNAL=COLUMN; '
                                 + COLUMNS_FIX)
            key, name = part.split('=', 1)
            pairs.append((key, name))
    elif isinstance(value, Mapping):
        pairs = list(value.items())
    else:
        try:
            pairs = [(k, v) for k, v in value]
        except (TypeError, ValueError):
            raise InputError(f'--columns must be SIGNAL=COLUMN pairs, got {value!r}; '
                             + COLUMNS_FIX) from None
    out = {}
    for key, name in pairs:
        if not isinstance(key, str) or not isinstance(name, str):
            raise InputError(f'--columns: {key!r}={name!r} is not text; ' + COLUMNS_FIX)
        key, name = key.strip().lower(), name.strip()
        if key not in COLUMN_KEYS:
            raise InputError(f'--columns: {key!r} is no signal; name one of '
                             f'{", ".join(COLUMN_KEYS)} (t: the time)')
        if not name:
            raise InputError(f'--columns {key}=: the column name is empty; ' + COLUMNS_FIX)
        if key in out:
            raise InputError(f'--columns: {key} is given twice ({out[key]!r} and {name!r}); '
                             'give each signal once')
        twice = [k for k, v in out.items() if v.lower() == name.lower()]
        if twice:
            raise InputError(f'--columns: column {name!r} is given for {twice[0]} and {key}; '
                             'each signal needs its own column')
        out[key] = name
    if not out:
        raise InputError('--columns is empty; ' + COLUMNS_FIX)
    return tuple((k, out[k]) for k in COLUMN_KEYS if k in out)


def _whole(value, name, least, fix):
    if isinstance(value, bool) or not isinstance(value, numbers.Integral) or value < least:
        raise InputError(f'{name} must be a whole number, {least} or more, got {value!r}: {fix}')
    return int(value)


@dataclass(frozen=True)
class AnalyzeOptions:
    """
    Every option of ``stiction-analyze`` for one recording; checked on creation.

    Attributes
    ----------
    input : str
        Bag directory, .mcap file, CSV or historian export (a ``Path`` is accepted).
    model : str
        Model(s) to fit when MV is present: ``'kano'``, ``'choudhury'`` or ``'both'``.
    S, J : float or None
        Given stiction band and slip jump (% of span); both or neither (then identified).
    fit_filter : bool
        Also identify Kano's air-chamber lag or Choudhury's EWMA weight.
    window : (float, float) or None
        Analyse only ``T0 <= t <= T1``, seconds from the start of the record.
    namespace : str or None
        Namespace of the loop topics in a bag, e.g. ``'/loop1'``.
    columns : tuple of (str, str) pairs, or None
        Which CSV or historian column holds ``t``, ``op``, ``mv``, ``pv``, ``sp``
        and the controller's ``mode`` where the names do not say; given as text
        (``'op=FIC101.OP,t=Zeit'``), a mapping or pairs, kept as
        ``(('t', 'Zeit'), ('op', 'FIC101.OP'))``.
    date_order : str or None
        ``'dmy'`` (day first) or ``'mdy'`` (month first) for a CSV's dates
        where no day over 12 shows the order; None to refuse such dates.
    loop_type : str
        ``'auto'``, ``'self-regulating'`` or ``'integrating'``.
    detector : str or None
        Learned detector model file; None for the shipped one.
    hammerstein : bool
        Quantify S and J from OP and PV (``--no-hammerstein`` sets it False).
    explain : bool
        Locate and name what the plain Kano model misses (needs MV).
    holdout : float
        Share of samples at the end kept out of every ``explain`` fit, in [0, 0.9).
    bootstrap : int
        Effect-free replicates that calibrate the ``explain`` choice, 0 or more.
    jobs : int or None
        Threads of ``explain`` (worker processes for many recordings); None: every core.
    json_path, html_path : str or None
        Where to write the JSON report and the HTML page; None: not written.

    """

    # Named as the command's INPUT and the report's "input"; a field never hides the builtin.
    input: str  # noqa: A003
    model: str = 'both'
    S: float | None = None
    J: float | None = None
    fit_filter: bool = False
    window: tuple[float, float] | None = None
    namespace: str | None = None
    columns: tuple[tuple[str, str], ...] | None = None
    date_order: str | None = None
    loop_type: str = 'auto'
    detector: str | None = None
    hammerstein: bool = True
    explain: bool = False
    holdout: float = 0.3
    bootstrap: int = 3
    jobs: int | None = None
    json_path: str | None = None
    html_path: str | None = None

    def __post_init__(self) -> None:
        # Frozen: the normalised values are set through object.__setattr__.
        def put(name, value):
            object.__setattr__(self, name, value)
        put('input', _path_or_none(self.input, 'input'))
        if not self.input:
            raise InputError('input is empty: name a bag directory, .mcap file, CSV or '
                             'historian export')
        for name in ('detector', 'json_path', 'html_path'):
            put(name, _path_or_none(getattr(self, name), name))
        self._check_reports()
        # The texts of stiction_ros.analysis.pipeline.Options, which checks these too.
        if self.model not in MODEL_CHOICES:
            raise InputError(f'model must be one of {MODEL_CHOICES}, got {self.model!r}')
        if self.loop_type not in LOOP_TYPES:
            raise InputError(f'loop type must be one of {LOOP_TYPES}, got {self.loop_type!r}')
        if (self.S is None) != (self.J is None):
            raise InputError('give both S and J, or neither (then they are identified)')
        for name in ('S', 'J'):
            v = getattr(self, name)
            if v is not None:
                put(name, self._number(name, v))
                if not 0.0 <= getattr(self, name) <= 100.0:
                    raise InputError(f'{name} = {v} is outside [0, 100] % of span')
        self._check_window(put)
        put('columns', parse_columns(self.columns))
        if self.date_order is not None and self.date_order not in DATE_ORDERS:
            raise InputError(f'date order (--date-order) must be one of {DATE_ORDERS} (day or '
                             f'month first), got {self.date_order!r}')
        holdout = self._number('holdout', self.holdout)
        if not 0.0 <= holdout < HOLDOUT_MAX:
            raise InputError(f'holdout (--holdout) must be in [0, {HOLDOUT_MAX:g}), got '
                             f'{self.holdout}: it is the share of samples at the end kept out '
                             'of every fit (default 0.3)')
        put('holdout', holdout)
        put('bootstrap', _whole(
            self.bootstrap, 'bootstrap (--bootstrap)', 0,
            'the effect-free replicates that calibrate --explain (default 3; 0 for none)'))
        if self.jobs is not None:
            put('jobs', _whole(self.jobs, 'jobs (--jobs)', 1,
                               'worker processes, or threads of --explain for one recording; '
                               'leave it out for every core'))

    def _check_reports(self) -> None:
        # A report written over the recording, or over the other report, loses it.
        flags = {'json_path': 'the JSON report (--json)', 'html_path': 'the HTML report (--html)'}
        given = [(n, getattr(self, n)) for n in flags if getattr(self, n)]
        for name, path in given:
            if _same_file(path, self.input):
                raise InputError(f'{flags[name]} {path} is the recording itself: '
                                 'writing the report would overwrite it; name another file')
            if Path(path).suffix.lower() in RECORDING_SUFFIXES and Path(path).exists():
                raise InputError(f'{flags[name]} {path} exists and looks like a '
                                 'recording: the report would overwrite it; name a .json or '
                                 '.html file (a report is never given a recording suffix)')
        if len(given) == 2 and _same_file(given[0][1], given[1][1]):
            raise InputError(f'--json and --html both name {given[0][1]}: the page would '
                             'overwrite the JSON report; give them different files')
        for name, path in given:
            # An HTML page over a JSON report (or the other way) replaced it without a word.
            page = Path(path).suffix.lower() in ('.html', '.htm')
            if (name == 'html_path') != page:
                want = 'an .html' if name == 'html_path' else 'a file not ending in .html'
                raise InputError(f'{flags[name]} {path}: name {want} (a page is written only '
                                 'to .html or .htm, a JSON report never)')
            # Imported here: report_files pulls in the analysis, which --help need not load.
            from stiction_ros.app.report_files import unwritable
            why = unwritable(path)
            if why:
                raise InputError(f'cannot write {flags[name]} {path}: {why} (checked before '
                                 'the recording is read)')

    @staticmethod
    def _number(name, v):
        if isinstance(v, bool) or not isinstance(v, numbers.Real):
            raise InputError(f'{name} must be a number, got {v!r}')
        return float(v)

    def _check_window(self, put):
        if self.window is None:
            return
        try:
            t0, t1 = self.window
        except (TypeError, ValueError):
            raise InputError(f'window (--window T0 T1) must be two times in seconds, got '
                             f'{self.window!r}') from None
        t0, t1 = self._number('window start', t0), self._number('window end', t1)
        if not (math.isfinite(t0) and math.isfinite(t1)):
            raise InputError(f'window (--window T0 T1) must be finite seconds from the start '
                             f'of the record, got {t0:g} to {t1:g}')
        put('window', (t0, t1))


def analyze_file(options: AnalyzeOptions, say: Say = print_nothing) -> Analysis:
    """
    Analyse the recording ``options.input``; write the reports ``options`` asks for.

    Parameters
    ----------
    options : AnalyzeOptions
        What to analyse and how; ``json_path`` and ``html_path`` say what to write.
    say : callable
        Receives each progress line (``stiction-analyze`` prints them on stderr).

    Returns
    -------
    Analysis
        The report dict (``.report``, with ``elapsed_s``) and the arrays behind the figures.

    Raises
    ------
    StictionError
        The input cannot be analysed (InputError, IdentifyError, ...) or the
        detector's model file is unusable (DetectorFileError); the message says why.
    OSError
        A report cannot be written.

    """
    # Imported here: the analysis takes about a second to load, not needed to check options.
    from stiction_ros.analysis.pipeline import analyze, Options
    from stiction_ros.analysis.readers import load_record
    t0 = time.perf_counter()
    pipeline_options = Options(model=options.model, S=options.S, J=options.J,
                               fit_filter=options.fit_filter, loop_type=options.loop_type,
                               hammerstein=options.hammerstein, detector=options.detector)
    say(f'reading {options.input}')
    record = load_record(options.input, namespace=options.namespace, window=options.window,
                         columns=dict(options.columns) if options.columns else None,
                         date_order=options.date_order)
    if not (record.has('pv') or record.has('mv')):
        held = ', '.join(s for s in ('op', 'sp') if record.has(s))
        fix = ('record the pv or mv topic' if record.source.get('format') == 'bag' else
               "name the column with --columns pv=COLUMN (a tag's PV such as FIC101.PV)")
        raise InputError(f'{record.path}: no process value (pv) and no valve position (mv), '
                         f'only {held}: OP alone cannot show what the valve did; {fix}')
    sampling = record.source.get('sampling')
    say(f'{record.samples} samples at {record.sample_time:g} s'
        + (f' ({sampling})' if sampling else '') + ', signals '
        f'{", ".join(s for s in ("op", "mv", "pv", "sp") if record.has(s))}'
        + (', mode' if 'mode' in (record.source.get('columns') or {}) else ''))
    warned = set(record.source.get('warnings') or [])
    for note in record.notes:
        # How the file was read (a column ignored, a word read as missing, a row count
        # that disagrees) decides what was analysed; exclusions and a damaged file's
        # warnings have their own lines.
        if not note.startswith('excluded ') and note not in warned:
            say(f'note: {note}')
    analysis = analyze(record, pipeline_options,
                       progress=SearchSteps(record, say), stage=_stages(say))
    report = analysis.report
    if options.explain:
        run_explain(analysis, options, say)
    report['elapsed_s'] = round(time.perf_counter() - t0, 3)
    from stiction_ros.app.report_files import earlier_input, write_html, write_json
    for target in (options.json_path, options.html_path):
        other = target and earlier_input(target, options.input)
        if other:
            say(f'note: {target} held the report of {other}; it is replaced')
    if options.json_path:
        with _writing('JSON report (--json)', options.json_path):
            write_json(options.json_path, report)
        say(f'wrote {options.json_path}')
    if options.html_path:
        with _writing('HTML report (--html)', options.html_path):
            write_html(analysis, options.html_path, say)
    return analysis


@contextmanager
def _writing(what: str, path: str) -> Iterator[None]:
    """Turn a failed write into an error that names the report and the path."""
    try:
        yield
    except OSError as exc:
        raise ReportWriteError(f'cannot write the {what} {path}: '
                               f'{exc.strerror or exc}') from exc


def run_explain(analysis: Analysis, options: AnalyzeOptions, say: Say = print_nothing) -> None:
    """
    Add the ``--explain`` sections to ``analysis.report`` and their arrays to ``analysis``.

    Without MV the report gets a ``mismatch`` section that says why nothing can
    be explained; the rest of the report stands.
    """
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
    from stiction_ros.analysis.without_friction import still_reading
    fits = analysis.report.get('fits') or [{}]
    still, _ = still_reading(rec.signals['op'], rec.signals['mv'],
                             rec.valve_segments(min_samples=2), rec.sample_time, fits[0])
    if still is not None:
        # A fit to a valve that never moved reads MV's noise: a calibration of gain 0 or a
        # dead time would be named with full confidence.
        # PV may have ruled the dead reading in or out (the verdict's set-point test).
        st = analysis.report.get('mv_dead') or analysis.report['stiction']
        pv_says = f' From PV: {st["reason"]}.' if 'set_point_test' in st else ''
        analysis.report['mismatch'] = {
            'effect': 'cannot_tell', 'effects': [], 'friction': None,
            'reason': ('mv_dead' if 'mv_dead' in analysis.report
                       else st.get('cannot_tell', 'mv_still')),
            'explanation': f'Cannot explain a mismatch: {still.sentence()}.{pv_says}'}
        return
    from stiction_ros.analysis.mismatch.decide import explain_record
    jobs = options.jobs if options.jobs is not None else default_jobs()
    sections, arrays = explain_record(rec.t, rec.signals['op'], rec.signals['mv'],
                                      rec.valve_segments(min_samples=2), rec.sample_time,
                                      holdout=options.holdout, reps=options.bootstrap,
                                      progress=lambda msg: say(explain_step(msg)), jobs=jobs)
    analysis.report.update(sections)
    analysis.explain_arrays = arrays


def explain_step(msg: str) -> str | Step:
    """Return an ``--explain`` progress line, its candidate fits as one counted :class:`Step`."""
    from stiction_ros.analysis.mismatch.explain import Fitted
    if not isinstance(msg, Fitted):
        return msg
    detail = '' if msg.done >= msg.total else msg.effect + (
        f' (bootstrap replicate {msg.replicate}/{msg.replicates})' if msg.replicate else '')
    return Step('candidate fits', msg.done, msg.total, detail)


def search_levels(record: Record) -> int:
    """Return how many refinement levels identify's search runs on ``record`` (0: none)."""
    import numpy as np

    from stiction_ros.analysis.identify import plausible_box
    from stiction_ros.errors import StictionError
    op, mv = record.signals['op'], record.signals['mv']
    segments = record.valve_segments(min_samples=2)
    if not segments:
        return 0
    used = np.concatenate([np.arange(a, b) for a, b in segments])
    try:
        s_max, j_max = plausible_box(op[used], mv[used])
    except StictionError:
        return 0
    res = SEARCH_RESOLUTION
    step = res * max(1, round(max(res, max(s_max, j_max) / SEARCH_COARSE_POINTS) / res))
    levels = 0
    while step > res:
        levels += 1
        step = res * max(1, round(step / 5 / res))
    return levels


def _stages(say: Say) -> Callable[[str, tuple], None]:
    """Return the pipeline's ``stage`` callback: each part as a step of a bar."""
    def stage(name: str, plan: tuple) -> None:
        # Never the last step: a finished step stays on screen, and the verdict follows.
        say(Step('analysing', plan.index(name), len(plan), name))
    return stage


class SearchSteps:
    """The pipeline's :class:`SearchProgress` as steps naming the model searched."""

    def __init__(self, record: Record, say: Say) -> None:
        self.say = say
        self.levels = search_levels(record) if record.has('mv') else 0

    def __call__(self, p: SearchProgress) -> None:
        """Say which model's search reached which level after how many evaluations."""
        self.levels = max(self.levels, p.level)
        # With --fit-filter one bar runs over the levels of every filter value's search.
        which = f'filter {p.search}/{p.searches}, ' if p.searches > 1 else ''
        self.say(Step(f'{p.model}: search level', (p.search - 1) * self.levels + p.level,
                      p.searches * self.levels, f'{which}{p.evaluations} evaluations'))
