"""
The analyzer's report as files: the JSON report, the HTML page and its PNG figures.

The figures are drawn with matplotlib's object-oriented API (stiction_ros.viz),
so writing a report chooses no matplotlib backend for the caller.
"""

from __future__ import annotations

import html
import json
import os
from pathlib import Path
import re
from typing import Callable, TYPE_CHECKING

from stiction_ros.app.report_text import to_json_text

from stiction_ros.viz.html_parts import INPUT_META

if TYPE_CHECKING:  # pragma: no cover - for the annotations only
    from stiction_ros.analysis.pipeline import Analysis

FIGURE_NAMES = ('trends', 'maps', 'mismatch', 'signatures')


def unwritable(path: str | Path) -> str | None:
    """
    Return why a report cannot be written at ``path``, or None where it can.

    Asked before a recording is read, so that a long analysis is not lost at
    its end to a read-only folder; an HTML page's figure folder counts too.
    """
    p = Path(path)
    targets = [(p, False)]
    if p.suffix.lower() in ('.html', '.htm'):
        targets.append((p.with_name(p.stem + '_figures'), True))
    for target, folder_wanted in targets:
        if target.is_symlink() and not target.exists():
            return f'{target} is a link to nothing'
        if target.exists():
            if target.is_dir() != folder_wanted:
                return f'{target} is {"not " if folder_wanted else ""}a folder'
            if not os.access(target, os.W_OK):
                return f'{target} is read-only'
            continue
        # The nearest folder that exists is where the missing ones would be made.
        folder = target.parent
        while not folder.exists() and folder != folder.parent:
            if folder.is_symlink():
                return f'{folder} is a link to nothing'
            folder = folder.parent
        if not folder.is_dir():
            return f'{folder} is not a folder'
        if not os.access(folder, os.W_OK | os.X_OK):
            return f'the folder {folder} is read-only'
    return None


def earlier_input(path: str | Path, source: str | Path) -> str | None:
    """
    Return the recording whose report ``path`` holds when it is not ``source``, else None.

    Read from an earlier JSON report's ``input.path`` or an earlier page's mark
    (:data:`stiction_ros.viz.html_parts.INPUT_META`); a file that is neither
    is not a report of ours and gives None, as a missing one does.
    """
    p = Path(path)
    if not p.is_file():
        return None
    try:
        with open(p, encoding='utf-8') as f:
            head = f.read(4096) if p.suffix.lower() in ('.html', '.htm') else f.read()
        if p.suffix.lower() in ('.html', '.htm'):
            found = re.search(f'<meta name="{INPUT_META}" content="([^"]*)">', head)
            other = html.unescape(found.group(1)) if found else None
        else:
            other = (json.loads(head).get('input') or {}).get('path')
    except (OSError, ValueError, AttributeError):
        return None
    if not isinstance(other, str) or not other:
        return None
    # A page holds its recording's full path; a JSON report the path as given, which is
    # read from the folder of the run that wrote it: there only the name can be compared.
    if Path(other).is_absolute():
        same = Path(other).resolve() == Path(source).resolve()
    else:
        same = Path(other).name == Path(source).name
    return None if same else other


def write_text(path: str | Path, text: str) -> None:
    """
    Write ``text`` and a final newline to ``path`` (UTF-8), creating its folder.

    Written beside the name and renamed over it, so that a worker stopped by
    Ctrl-C, or a full disk, leaves the earlier report whole, not an empty one.
    """
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    tmp = p.with_name(f'.{p.name}.{os.getpid()}.tmp')
    try:
        tmp.write_text(text + '\n', encoding='utf-8')
        os.replace(tmp, p)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def write_json(path: str | Path, report: dict) -> None:
    """Write ``report`` as the indented JSON of :func:`to_json_text` to ``path``."""
    write_text(path, to_json_text(report))


def landscapes(analysis: Analysis) -> list[dict]:
    """Return the MSE landscape around each identified fit (:func:`identify.mse_landscape`)."""
    # Imported here: the landscape search is needed only for --html.
    from stiction_ros.analysis.identify import mse_landscape
    rec = analysis.record
    return [mse_landscape(rec.signals['op'], rec.signals['mv'], fit,
                          rec.valve_segments(min_samples=2), rec.sample_time)
            for fit in analysis.fits if fit.source == 'identified']


def write_html(analysis: Analysis, path: str | Path, say: Callable[[str], None]) -> Path:
    """
    Write the figures beside ``path`` and the HTML page embedding them.

    Parameters
    ----------
    analysis : Analysis
        What :func:`stiction_ros.app.analyze.analyze_file` returned.
    path : str or Path
        The HTML file; the PNGs go to the folder ``<stem>_figures`` beside it.
    say : callable
        Receives one progress line.

    Returns
    -------
    Path
        The HTML file written.

    """
    # Imported here: matplotlib is needed only for --html.
    from stiction_ros.viz import figures
    from stiction_ros.viz.mismatch_figures import mismatch_figure
    from stiction_ros.viz.report_html import render
    from stiction_ros.viz.signature_plots import signature_figure
    html_path = Path(path)
    fig_dir = html_path.with_name(html_path.stem + '_figures')
    fig_dir.mkdir(parents=True, exist_ok=True)
    rec = analysis.record
    paths = [figures.trends_figure(analysis, fig_dir / 'trends.png'),
             figures.maps_figure(analysis, fig_dir / 'maps.png')]
    if getattr(analysis, 'explain_arrays', None) is not None:
        paths.append(mismatch_figure(analysis.report, analysis.explain_arrays,
                                     fig_dir / 'mismatch.png'))
    if analysis.signatures:
        x = analysis.signature_inputs
        # The signatures read the longest stretch (OP's rows kept after a realignment);
        # their times are the record's.
        win = analysis.report.get('signature_window')
        t0 = float(win['start_s'] - rec.t[0]) if win else 0.0
        paths.append(signature_figure(x['op'], x['pv'], rec.sample_time, analysis.signatures,
                                      fig_dir / 'signatures.png', t0=t0))
    for land in landscapes(analysis):
        paths.append(figures.landscape_figure(land, fig_dir / f'landscape_{land["model"]}.png'))
    drawn = {Path(p).name for p in paths if p}
    # A figure of an earlier run that this one does not draw (mismatch.png, before a run
    # without --explain) would sit beside the page unexplained; only the report's own go.
    for old in fig_dir.glob('*.png'):
        if old.name not in drawn and (old.stem in FIGURE_NAMES
                                      or old.stem.startswith('landscape_')):
            old.unlink()
    write_text(html_path, render(analysis.report, [p for p in paths if p]))
    say(f'wrote {html_path} (figures in {fig_dir})')
    return html_path


def write_index(summary: dict, folder: str | Path) -> Path:
    """Write ``index.html`` in ``folder``: a row per recording of a run, linked to its page."""
    # Imported here: the page is needed only for --pages.
    from stiction_ros.viz.index_html import render_index
    path = Path(folder) / 'index.html'
    write_text(path, render_index(summary, folder))
    return path
