"""
The index page of a folder's run with ``--pages``: a row per recording, linked to its page.

The rows say what the terminal's lines say (answer, probability or score,
the summary's first lines, the shared cycle) so that a plant-wide audit can
be read, sorted by eye and clicked through in one place.
"""

from __future__ import annotations

import os
from pathlib import Path

from stiction_ros.analysis.detection import BAND, probability_text
from stiction_ros.viz.html_parts import clean, e, num, STYLE, table

ANSWER_CLASS = {'stiction': 'yes', 'no stiction': 'no', 'cannot tell': 'und'}


def _link(row: dict, folder: Path) -> str:
    name = e(row['input'])
    page = row.get('page')
    if not page:
        return name
    return f'<a href="{e(Path(os.path.relpath(page, folder)).as_posix())}">{name}</a>'


def _row(row: dict, folder: Path) -> list:
    if not row.get('ok'):
        what = 'skipped' if row.get('skipped') else 'error'
        return [_link(row, folder), f'<span class="und">{what}</span>', '-',
                clean(row.get('error', ''))]
    answer = row.get('answer') or 'cannot tell'
    # As the terminal and the page print them.
    strength = (probability_text(row['probability'], BAND) if row.get('probability') is not None
                else num(row.get('score'), 3))
    lines = str(row.get('summary', '')).split('\n')
    # The first line repeats the answer; the indented ones are the size and the evidence.
    said = '<br>'.join(clean(line.strip()) for line in lines[1:] if line.strip())
    if row.get('shared_cycle'):
        said += ('<br>' if said else '') + clean(row['shared_cycle'])
    return [_link(row, folder), f'<span class="{ANSWER_CLASS.get(answer, "und")}">'
            f'{e(answer)}</span>', strength, said or '-']


def render_index(summary: dict, folder: str | Path) -> str:
    """Return the index page of a folder's run (the ``--json`` summary) written in ``folder``."""
    folder = Path(folder)
    rows = [_row(r, folder) for r in summary['rows']]
    tally: dict = {}
    for r in summary['rows']:
        key = (r.get('answer') or 'cannot tell') if r.get('ok') else (
            'skipped' if r.get('skipped') else 'failed')
        tally[key] = tally.get(key, 0) + 1
    counts = ', '.join(f'{n} {k}' for k, n in sorted(tally.items()))
    return ''.join([
        f'<!DOCTYPE html><html><head><meta charset="utf-8"><title>stiction audit: '
        f'{e(summary["input"])}</title><style>{STYLE}</style></head><body>',
        f'<h1>Valve stiction audit: {e(summary["input"])}</h1>',
        f'<p>{summary["recordings"]} recording{"s" if summary["recordings"] != 1 else ""} in '
        f'{num(summary["seconds"], 3, "s")} on '
        f'{e(summary["workers"])}: {e(counts)}. Each name opens its page. Probability: the '
        'learned detector&rsquo;s, from OP and PV; score: the fits&rsquo;, with MV (0 = '
        'none, 1 = certain).</p>',
        table(['recording', 'answer', 'probability or score', 'size, evidence, shared cycle'],
              rows),
        '</body></html>'])
