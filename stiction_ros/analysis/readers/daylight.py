"""
Local stamps without an offset across a change of summer time.

A historian that exports local time without an offset writes the hour
clocks skip in spring as a jump of an hour with no row missing, and the
hour they repeat in autumn as a step back of an hour.  Both are taken for
a change of clocks only where nothing else fits: the jump or step back is
one hour beside the record's own step, it crosses a whole hour from
midnight to 04:00 (where every zone with summer time changes its clocks),
and that hour falls on a Sunday (a Friday in Israel's spring).  The later
stamps are then moved by the hour, so that the rows stay contiguous, and
the record says so.  Anything else stays as it was: a gap, or a refusal.
"""

from datetime import datetime, timedelta

import numpy as np

HOUR = 3600.0
# The clocks change at a whole hour from 00:00 (Chile) to 04:00 (the end of
# summer time in eastern Europe, on the summer clock).
FIRST_HOUR, LAST_HOUR = 0, 4
SUNDAY, FRIDAY = 6, 4


def clock_changes(t: np.ndarray, start: datetime) -> tuple[np.ndarray, list[str]]:
    """
    Return ``t`` with summer time's jumps taken out, and a note for each.

    ``t`` are seconds from ``start``, a naive local date and time; ``t``
    is returned as is where no step is a change of clocks.
    """
    steps = np.diff(t)
    forward = steps[steps > 0]
    if len(t) < 3 or not len(forward):
        return t, []
    step = float(np.median(forward))
    # Half a step of slack: a historian's stamps jitter by less.
    slack = 0.5 * step + 1e-6
    out, notes = t.copy(), []
    for i in np.flatnonzero(np.abs(np.abs(steps - step) - HOUR) <= slack):
        before = start + timedelta(seconds=float(t[i]))
        after = start + timedelta(seconds=float(t[i + 1]))
        shift = -HOUR if steps[i] > step else HOUR
        boundary = _boundary(before, after, shift)
        if boundary is None:
            continue
        out[i + 1:] += shift
        went = 'forward' if shift < 0 else 'back'
        notes.append(f'time: clocks went {went} an hour at {boundary:%Y-%m-%d %H:%M} '
                     f'(local stamps without an offset, {before:%H:%M:%S} then '
                     f'{after:%H:%M:%S}): read as contiguous rows, none missing; export '
                     'in UTC to be sure')
    return out, notes


def _boundary(before: datetime, after: datetime, shift: float) -> datetime | None:
    """Return the whole hour on the old clock at which the clocks changed, or None."""
    # On the old clock the change happens at the first whole hour after ``before``;
    # ``after`` (on the new clock) must lie within one step of it.
    hour = before.replace(minute=0, second=0, microsecond=0) + timedelta(hours=1)
    if shift < 0:
        # Forward: the new clock reads an hour more than the old one at the change.
        ok = hour + timedelta(hours=1) <= after
    else:
        # Back: the new clock reads an hour less; ``after`` falls within the repeated hour.
        ok = hour - timedelta(hours=1) <= after < hour
    if not ok or not FIRST_HOUR <= hour.hour <= LAST_HOUR:
        return None
    if hour.weekday() == SUNDAY or (shift < 0 and hour.weekday() == FRIDAY):
        return hour
    return None
