"""
Local stamps without an offset across a change of summer time.

A historian that exports local time without an offset writes the hour
clocks skip in spring as a jump of an hour with no row missing, and the
hour they repeat in autumn as a step back of an hour.  Such a jump or step
is taken for a change of clocks only where nothing else fits: it is one
hour beside the record's own step, it crosses a whole hour, and at that
local date and hour some zone of the time zone database (Python's
``zoneinfo``) does change its clocks by an hour in that direction.  The
later stamps are then moved by the hour, so that the rows stay contiguous,
and the record says so.  Anything else stays as it was: a gap, or a
refusal.  Without a zone database nothing is moved.

An outage of less than a day that spans such a change is kept as the stamps
read it, since a zone without summer time writes the same stamps, but the
record says that it may be an hour shorter (spring) or longer (autumn).
"""

from datetime import datetime, timedelta, timezone
import functools

import numpy as np

HOUR = 3600.0
DAY = 86400.0
_ONE_HOUR = timedelta(hours=1)


def clock_changes(t: np.ndarray, start: datetime) -> tuple[np.ndarray, list[str]]:
    """
    Return ``t`` with summer time's jumps taken out, and a note for each.

    ``t`` are seconds from ``start``, a naive local date and time; ``t``
    is returned as is where no step is a change of clocks.
    """
    steps = np.diff(t)
    forward = steps[steps > 0]
    if len(t) < 3 or len(forward) <= len(steps) // 2:
        # Rows that run newest first are turned round before this reads them.
        return t, []
    step = float(np.median(forward))
    # Half a step of slack: a historian's stamps jitter by less.
    slack = 0.5 * step + 1e-6
    out, notes = t.copy(), []
    moved = set()
    for i in np.flatnonzero(np.abs(np.abs(steps - step) - HOUR) <= slack):
        # To the millisecond: Excel's serial days carry a float's error in the seconds.
        before = start + timedelta(seconds=round(float(t[i]), 3))
        after = start + timedelta(seconds=round(float(t[i + 1]), 3))
        shift = -HOUR if steps[i] > step else HOUR
        boundary = _boundary(before, after, shift)
        if boundary is None:
            continue
        out[i + 1:] += shift
        moved.add(int(i))
        went = 'forward' if shift < 0 else 'back'
        notes.append(f'time: clocks went {went} an hour at {boundary:%Y-%m-%d %H:%M} '
                     f'(local stamps without an offset, {before:%H:%M:%S} then '
                     f'{after:%H:%M:%S}): read as contiguous rows, none missing; export '
                     'in UTC to be sure')
    for i in np.flatnonzero((steps > 1.5 * step) & (steps < DAY)):
        if int(i) not in moved:
            notes.extend(_outage_note(start + timedelta(seconds=round(float(t[i]), 3)),
                                      start + timedelta(seconds=round(float(t[i + 1]), 3))))
    return out, notes


def _outage_note(before: datetime, after: datetime) -> list[str]:
    """Return a note where some zone changes its clocks within an outage, else nothing."""
    hour = before.replace(minute=0, second=0, microsecond=0) + _ONE_HOUR
    # Back: ``after`` may lie in the hour the new clock repeats, before ``hour`` on the old.
    while hour <= after + _ONE_HOUR:
        change = _changes(hour.year).get(hour, ())
        if 'forward' in change and hour + _ONE_HOUR <= after:
            how = 'forward: it may be an hour shorter'
        elif 'back' in change:
            how = 'back: it may be an hour longer'
        else:
            hour += _ONE_HOUR
            continue
        return [f'time: the outage from {before:%Y-%m-%d %H:%M:%S} to '
                f'{after:%Y-%m-%d %H:%M:%S} spans {hour:%Y-%m-%d %H:%M}, when clocks go '
                f'{how} than the local stamps without an offset say (kept as read; export '
                'in UTC to be sure)']
    return []


@functools.lru_cache(maxsize=8)
def _changes(year: int) -> dict:
    """
    Return {whole hour on the old clock: {'forward', 'back'}} of ``year``'s changes by an hour.

    Read once a year from every zone whose offset changes that year, so that
    a record with thousands of short outages looks each hour up, not every zone.
    """
    out: dict = {}
    start = datetime(year, 1, 1, tzinfo=timezone.utc)
    for tz in _seasonal_zones(year):
        days = [start + timedelta(days=d) for d in range(367)]
        offsets = [d.astimezone(tz).utcoffset() for d in days]
        for d in range(366):
            if offsets[d] == offsets[d + 1]:
                continue
            # Within the day, to the quarter hour (some zones change at half past).
            t = days[d]
            while t.astimezone(tz).utcoffset() == offsets[d]:
                t += timedelta(minutes=15)
            old, new = offsets[d], t.astimezone(tz).utcoffset()
            local = (t + old).replace(tzinfo=None)
            if local.minute == 0 and local.year == year and abs(new - old) == _ONE_HOUR:
                out.setdefault(local, set()).add('forward' if new > old else 'back')
    return out


def _boundary(before: datetime, after: datetime, shift: float) -> datetime | None:
    """Return the whole hour on the old clock at which the clocks changed, or None."""
    # On the old clock the change happens at the first whole hour after ``before``.
    hour = before.replace(minute=0, second=0, microsecond=0) + _ONE_HOUR
    if shift < 0:
        # Forward: the new clock reads an hour more than the old one from the change on.
        ok, way = hour + _ONE_HOUR <= after, 'forward'
    else:
        # Back: ``after`` falls within the hour the new clock repeats.
        ok, way = hour - _ONE_HOUR <= after < hour, 'back'
    return hour if ok and way in _changes(hour.year).get(hour, ()) else None


@functools.lru_cache(maxsize=1)
def _zones() -> tuple:
    """Return every zone of the time zone database (none where it is missing)."""
    try:
        from zoneinfo import available_timezones, ZoneInfo
        return tuple(ZoneInfo(name) for name in sorted(available_timezones()))
    except Exception:   # pragma: no cover - a Python without a zone database
        return ()


@functools.lru_cache(maxsize=8)
def _seasonal_zones(year: int) -> tuple:
    """Return the zones whose offset from UTC changes within ``year``."""
    # Twice a month: a change for a month of the year (Morocco's, in Ramadan) counts too.
    def offsets(tz) -> set:
        return {datetime(year, month, day, tzinfo=tz).utcoffset()
                for month in range(1, 13) for day in (1, 15)}
    return tuple(tz for tz in _zones() if len(offsets(tz)) > 1)
