"""
A controller's mode column in a CSV: which rows the loop was closed.

Rows in manual (or tracking, out of service, an output set from outside)
are excluded, as a historian export's rows in manual are: the controller
was not acting, so the loop's verdict cannot use them.  Words are matched
whole, in any case; a number is 1 for automatic and 0 for manual, as the
plant's historian writes it (other systems code modes as bits, where 1 may
mean something else: a column of other numbers or words is not used, and a
note names them, rather than guessed at).  A mode written only when it
changes holds until the next one; an empty cell or a historian's word for
a bad value before any mode excludes nothing.
"""

import numpy as np
from stiction_ros.analysis.readers.bad_words import BAD_WORDS

# The controller acts on its own error (cascade and remote cascade: on a set
# point given from outside).
AUTOMATIC = frozenset(['1', 'auto', 'aut', 'automatic', 'a', 'cas', 'cascade', 'casc', 'rcas',
                       'bcas'])
# The controller does not act: OP is set by hand, tracked or set from outside.
MANUAL = frozenset(['0', 'man', 'manual', 'm', 'hand', 'lo', 'iman', 'oos', 'o/s',
                    'out of service', 'trk', 'track', 'tracking', 'rout'])
EXCLUDED = 'MODE not automatic (manual, tracking or out of service)'


def _word(cell: str) -> str:
    text = ' '.join(cell.strip().lower().split())
    try:
        value = float(text)
    except ValueError:
        return text
    return f'{value:g}' if value in (0.0, 1.0) else text


def read_modes(name: str, cells: list[str]) -> tuple[np.ndarray | None, list[str]]:
    """
    Return each row's mode (1 automatic, 0 not, NaN empty) and notes, or None and why not.

    None when a value is neither an automatic nor a manual word: the column
    is then not used, and the note says which values and what to do.
    """
    words = [_word(c) for c in cells]
    # A historian's word for a value it does not have says nothing of the mode.
    words = ['' if w in BAD_WORDS else w for w in words]
    unknown = sorted({w for w in words if w and w not in AUTOMATIC and w not in MANUAL})
    if unknown:
        shown = ', '.join(repr(w) for w in unknown[:6])
        return None, [f'{name}: mode values {shown} are neither automatic (AUTO, CAS, 1) nor '
                      'manual (MAN, 0): the column is not used, so every row is taken as '
                      'automatic; export the mode as AUTO/MAN or 1/0 to exclude manual rows']
    mode = np.array([np.nan if not w else 1.0 if w in AUTOMATIC else 0.0 for w in words])
    # Written on change: each value holds until the next.
    known = np.flatnonzero(np.isfinite(mode))
    if len(known):
        last = np.maximum.accumulate(np.where(np.isfinite(mode), np.arange(len(mode)), -1))
        mode = np.where(last >= 0, mode[np.maximum(last, 0)], np.nan)
    return mode, []


def held(rel: np.ndarray, mode: np.ndarray, grid: np.ndarray) -> np.ndarray:
    """Return the mode at each ``grid`` time: the last row's at or before it (NaN before any)."""
    i = np.searchsorted(rel, grid, side='right') - 1
    out = np.full(len(grid), np.nan)
    ok = i >= 0
    out[ok] = mode[i[ok]]
    return out
