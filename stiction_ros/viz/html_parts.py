"""
The pieces the HTML report is built from: escaped text, rounded numbers with units, tables.

Every number reaches the page through :func:`num` (or :func:`clean`, for the
analysis's own sentences), so none shows more digits than it means; every
quantity is named with its unit: % of OP or of travel, s, %² for an MSE, and
"PV units" for the process variable, whose unit no recording states.
"""

from __future__ import annotations

import base64
import html
import math
from pathlib import Path
import re

PV_UNITS = 'PV units'
MSE_UNIT = '%²'

STYLE = """
body { font-family: sans-serif; max-width: 1100px; margin: 1em auto; color: #222; }
table { border-collapse: collapse; margin: 0.5em 0 1em; }
td, th { border: 1px solid #bbb; padding: 3px 8px; text-align: left; font-size: 14px; }
th { background: #eee; }
.yes { color: #b00; font-weight: bold; } .no { color: #070; } .und { color: #a60; }
.verdict { font-size: 20px; padding: 8px; border: 2px solid #888; display: inline-block; }
.rule { background: #f4f4f8; border-left: 4px solid #88a; padding: 4px 10px; }
.id { white-space: nowrap; }
figure { margin: 1em 0; } figcaption { font-size: 14px; color: #444; max-width: 900px; }
img { max-width: 100%; border: 1px solid #ddd; margin: 4px 0; }
"""

# The units of the parameters the --explain models report, by name; a name not
# listed is a dimensionless ratio.
PARAM_UNITS = {'S': '%', 'J': '%', 'offset': '%', 'time_constant_s': 's', 'dead_time_s': 's',
               'lag_s': 's', 'lag2_s': 's', 'min_speed_pct_s': '%/s'}
PARAM_WORDS = {'time_constant_s': 'time constant', 'dead_time_s': 'dead time',
               'gain_per_50pct': 'change per 50 % of travel', 'min_speed_pct_s': 'min. speed',
               'change_over_fit': 'change over the fitted part', 'lag_s': 'lag',
               'lag2_s': 'second lag'}

# A decimal number in running text, with its exponent: the analysis's sentences
# carry a few unrounded floats (a Hammerstein interval, a note's time).
_NUMBER = re.compile(r'(?<![\w.])(-?)(\d+\.\d+|\d+)([eE][-+]?\d+)?(?![\w.])')

# The name of the page's meta tag that holds its recording's full path (a later run
# that writes over the page says whose it was).
INPUT_META = 'stiction-ros-input'


def e(x: object) -> str:
    """Return ``x`` as HTML-escaped text."""
    return html.escape(str(x))


def ident(name: str) -> str:
    """Return an identifier (``position_dependent_friction``) kept on one line, as one word."""
    return f'<span class="id">{e(name)}</span>'


def num(x: object, digits: int = 4, unit: str = '') -> str:
    """Return ``x`` rounded to ``digits`` significant digits (integers whole), with ``unit``."""
    if x is None or x == '':
        return '-'
    if isinstance(x, bool):
        return 'yes' if x else 'no'
    if isinstance(x, int):
        text = str(x)
    elif isinstance(x, float):
        if not math.isfinite(x):
            return '-'
        text = f'{x + 0.0:.{digits}g}'  # + 0.0: -0.0 shows as 0
        if 'e' in text:
            mant, exp = text.split('e')
            text = f'{mant}×10<sup>{int(exp)}</sup>'
            return text + (f'\u00a0{e(unit)}' if unit else '')
    else:
        return e(x)
    # A no-break space: a narrow table cell never puts the unit under its number.
    return e(text + (f'\u00a0{unit}' if unit else ''))


def pct(share: float | None) -> str:
    """Return a share (0..1) as a percentage with at most three significant digits."""
    return '-' if share is None else num(100.0 * share, 3, '%')


def span(pair: object, unit: str = '%') -> str:
    """Return an interval ``[lo, hi]`` as ``lo to hi unit``."""
    if not isinstance(pair, (list, tuple)) or len(pair) != 2:
        return '-'
    return f'{num(pair[0])} to {num(pair[1], unit=unit)}'


def _round_match(m: re.Match) -> str:
    body = m.group(2)
    if '.' not in body and not m.group(3):
        return m.group(0)  # an integer: a count, a sample number or a year
    if len(body.replace('.', '').lstrip('0')) <= 6:
        return m.group(0)
    return f'{float(m.group(0)):.4g}'


def clean(text: object) -> str:
    """Return a sentence escaped, any number in it with more than 6 digits rounded to 4."""
    return e(_NUMBER.sub(_round_match, str(text)))


def table(header: list, rows: list) -> str:
    """Return an HTML table; ``header`` is plain text, the cells of ``rows`` are HTML."""
    head = ''.join(f'<th>{e(h)}</th>' for h in header)
    body = ''.join('<tr>' + ''.join(f'<td>{c}</td>' for c in row) + '</tr>' for row in rows)
    return f'<table><tr>{head}</tr>{body}</table>'


def rule(text: str) -> str:
    """Return ``text`` (HTML) as the paragraph that states a decision rule."""
    return f'<p class="rule">{text}</p>'


def param_name(name: str) -> str:
    """Return a model parameter's name in words."""
    return PARAM_WORDS.get(name, name.replace('_', ' '))


def param(name: str, value: object) -> str:
    """Return ``name value unit`` of one model parameter, e.g. ``time constant 3.1 s``."""
    return f'{e(param_name(name))} {num(value, unit=PARAM_UNITS.get(name, ""))}'


def params(values: dict) -> str:
    """Return every parameter of ``values`` as ``name value unit``, comma separated."""
    return ', '.join(param(k, v) for k, v in values.items()) or '-'


def figure(path: str | Path, caption: str) -> str:
    """Return ``path`` (a PNG) embedded as a data URI with ``caption`` (HTML) below it."""
    p = Path(path)
    data = base64.b64encode(p.read_bytes()).decode('ascii')
    return (f'<figure><img alt="{e(p.name)}" src="data:image/png;base64,{data}">'
            f'<figcaption>{caption}</figcaption></figure>')
