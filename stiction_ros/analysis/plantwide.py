"""
Cycles shared between loops: which loop is the likely source, which only carry it.

A sticky valve's cycle travels: through a vessel into the next unit, whose
loop cycles at the same period with a good valve.  Read alone, that loop
looks sticky too (DETECTION.md, section 5: healthy loops with an upstream
cycle are the detector's most frequent false alarm).  Read together, the
loops that cycle at one period over the same hours share one oscillation
(Thornhill, Huang and Zhang 2003 group them by period the same way), and
the source is the loop whose own valve explains it best.

Thornhill et al. (2003) point to the most *distorted* cycle (a plant
filters the harmonics away as the cycle travels).  In closed loop that does
not hold: the carrier's controller removes the fundamental and leaves the
harmonics, and on a first draft of the pairs of ``sim.coupled_loops``
(seeds 6100040-6100339) the cycle with more harmonics was the source's 12
times in 25, a coin, while the learned detector's probability, which reads
the valve path (OP against PV), picked it 19 times in 19.  So the source is
the member whose probability stands ``GAP`` above every other's; where none
does, which loop started the cycle cannot be told from these records, and
the result says so.  On the development pairs (seeds 6100000-6100339) the
rule named the sticky loop in 20 of 22 shared cycles and none the healthy
one; ``make shared-cycles`` scores it on pairs it was not set on
(docs/SHARED_CYCLES.md).

Pure numpy: the batch analyzer (``app.batch``) builds the members from its
rows; a member is a loop with a resolvable oscillation.
"""

from dataclasses import dataclass, field
import math

import numpy as np

# Periods within this relative distance of a group's are the same oscillation: the ACF
# period of one record wanders a few per cent (Thornhill et al. use a similar band).
TOLERANCE = 0.15
# How far the source's probability must stand above every other member's.
GAP = 0.2


@dataclass(frozen=True)
class CycleMember:
    """
    One loop's cycle as the batch read it.

    ``start`` and ``end`` are clock times in seconds (POSIX), or None when the
    record has no clock time; ``probability`` is the detector's (None when it
    gave none).
    """

    name: str
    period_s: float
    probability: float | None = None
    start: float | None = None
    end: float | None = None


@dataclass
class SharedCycle:
    """Loops that cycle at one period over the same time, most likely source first."""

    period_s: float
    members: list[CycleMember]
    source: str | None
    reason: str
    clock: bool         # False: no member had a clock time; taken as recorded together

    def to_json(self) -> dict:
        """Return plain JSON types."""
        return {'period_s': round(self.period_s, 3), 'source': self.source,
                'reason': self.reason, 'clock_times': self.clock,
                'members': [{'name': m.name, 'period_s': round(m.period_s, 3),
                             'probability': m.probability} for m in self.members]}

    def note_for(self, name: str) -> str:
        """Return one line for member ``name``: what the shared cycle says about it."""
        others = ', '.join(m.name for m in self.members if m.name != name)
        head = f'cycle of {self.period_s:.0f} s shared with {others}'
        if self.source is None:
            return f'{head}; which loop is its source cannot be told ({self.reason})'
        if self.source == name:
            return f'{head}; this loop is the likely source ({self.reason})'
        return (f'{head}; likely carried from {self.source}, whose valve explains it '
                f'better ({self.reason})')


@dataclass
class PlantWide:
    """The shared cycles of a batch (``members``: the loops with a resolvable cycle)."""

    groups: list[SharedCycle] = field(default_factory=list)
    members: int = 0

    def group_of(self, name: str) -> SharedCycle | None:
        """Return the shared cycle ``name`` belongs to, or None."""
        return next((g for g in self.groups if any(m.name == name for m in g.members)), None)

    def to_json(self) -> list:
        """Return the groups as plain JSON types."""
        return [g.to_json() for g in self.groups]


def _overlap(a: CycleMember, b: CycleMember) -> bool:
    if a.start is None or b.start is None:
        return a.start is None and b.start is None
    return min(a.end or a.start, b.end or b.start) > max(a.start, b.start)


def _together(group: list[CycleMember], m: CycleMember, tolerance: float) -> bool:
    ref = float(np.median([g.period_s for g in group]))
    same = abs(math.log(m.period_s / ref)) <= math.log1p(tolerance)
    return same and any(_overlap(g, m) for g in group)


def _source(members: list[CycleMember], gap: float) -> tuple[str | None, str]:
    known = sorted((m for m in members if m.probability is not None),
                   key=lambda m: -float(m.probability or 0.0))
    if not known:
        return None, 'no member has a stiction probability'
    best = known[0]
    if len(known) == 1:
        return None, f'only {best.name} has a stiction probability'
    second = known[1]
    p1, p2 = float(best.probability or 0.0), float(second.probability or 0.0)
    if p1 - p2 < gap:
        return None, (f'stiction probabilities {p1:.2f} ({best.name}) and {p2:.2f} '
                      f'({second.name}) are within {gap:g}')
    return best.name, f'stiction probability {p1:.2f} against at most {p2:.2f}'


def shared_cycles(members: list[CycleMember], tolerance: float = TOLERANCE,
                  gap: float = GAP) -> PlantWide:
    """
    Return the cycles that two or more loops share, each with its likely source.

    Parameters
    ----------
    members : list of CycleMember
        Loops with a resolvable oscillation (period in seconds, > 0).
    tolerance : float
        Relative distance of periods that count as one oscillation.
    gap : float
        How far the source's stiction probability must stand above every
        other member's; else the group's source is None, with the reason.

    Returns
    -------
    PlantWide
        The groups of two loops or more, in the order of their shortest period.

    """
    bad = [m.name for m in members if not (m.period_s > 0 and math.isfinite(m.period_s))]
    if bad:
        raise ValueError(f'period must be a positive number of seconds: {bad}')
    groups: list[list[CycleMember]] = []
    for m in sorted(members, key=lambda m: m.period_s):
        home = next((g for g in groups if _together(g, m, tolerance)), None)
        if home is None:
            groups.append([m])
        else:
            home.append(m)
    out = []
    for g in groups:
        if len(g) < 2:
            continue
        source, reason = _source(g, gap)
        ordered = sorted(g, key=lambda m: 1.0 if m.probability is None else -m.probability)
        out.append(SharedCycle(float(np.median([m.period_s for m in g])), ordered, source,
                               reason, clock=any(m.start is not None for m in g)))
    return PlantWide(out, len(members))
