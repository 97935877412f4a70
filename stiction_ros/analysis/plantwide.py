"""
Cycles at one period in several loops: which loop is the likely source, which only carry it.

A sticky valve's cycle travels: through a vessel into the next unit, whose
loop cycles at the same period with a good valve.  Read alone, that loop
looks sticky too (docs/DETECTION_LOG.md, "Upstream cycles in the corpus": on
the fresh seeds 4100000- the healthy loops with an upstream cycle were
flagged 50 times in 231, the others 59 in 675).
Read together, loops that cycle at one period over the same hours may share
one oscillation (Thornhill, Huang and Zhang 2003 group loops by period the
same way), and then the source is the loop whose own valve explains it.
Nothing here checks that the loops are coupled (their cross-correlation):
one period over the same hours is the evidence, and the notes say "cycles
at the period of", not "carries", unless a source stands out.

Thornhill (2005, Finding the source of nonlinearity in a process with
plant-wide oscillation, IEEE Trans. Control Systems Technology 13(3))
points to the most non-linear, most distorted cycle, since the plant
filters harmonics away as a cycle travels.  On the simulated pairs of
``sim.coupled_loops`` the carrier's controller takes out the fundamental
and leaves the harmonics, and the more distorted PV was the source's about
as often as not (``make shared-cycles`` counts it), while the learned
detector's probability, which reads the valve path (OP against PV), picked
the source far more often.  So the source is a member whose probability is
at least ``FLOOR`` (it reads sticky on its own) and stands ``GAP`` above
every other member's; where none does, which loop started the cycle cannot
be told from these records, and the result says so.  A member that also
reads sticky on its own is never called a carrier: two sticky valves at
one period are ordinary in a plant.

A cycle that the carrier's controller distorts can show its autocorrelation
period at half the source's (the second harmonic); such loops are not
grouped here.

Pure numpy: the batch analyzer (``app.batch``) builds the members from its
rows; a member is a loop with a resolvable oscillation.
"""

from dataclasses import dataclass, field
import math

import numpy as np

# Periods within this relative distance of each other are one oscillation: the ACF period
# of one record wanders a few per cent.
TOLERANCE = 0.15
# How far the source's probability must stand above every other member's, and how high
# it must be itself (a source whose own reading says "probably not sticky" is no source).
GAP = 0.2
FLOOR = 0.5
# The least common stretch of two records, in periods, for their cycles to be compared.
MIN_OVERLAP_PERIODS = 4.0


@dataclass(frozen=True)
class CycleMember:
    """
    One loop's cycle as the batch read it.

    ``start`` and ``end`` are clock times in seconds of the stretch read, on
    the time base ``clock`` (members on different bases are never compared;
    all without a clock time are taken as recorded together).
    ``probability`` is the detector's, None when it gave none (a record whose
    valve position was measured is judged by its fits).
    """

    name: str
    period_s: float
    probability: float | None = None
    start: float | None = None
    end: float | None = None
    clock: str | None = None

    @property
    def p(self) -> float | None:
        """Return the probability, None when missing or not a number."""
        p = self.probability
        return float(p) if p is not None and math.isfinite(p) else None


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
                             'probability': m.p} for m in self.members]}

    def note_for(self, name: str) -> str:
        """Return one line for member ``name``: what the shared period says about it."""
        me = next(m for m in self.members if m.name == name)
        others = ', '.join(m.name for m in self.members if m.name != name)
        head = f"{others} cycling at this loop's period too ({self.period_s:.0f} s)"
        sticky = me.p is not None and me.p >= FLOOR
        if self.source == name:
            return f'{head}; this loop is the likely source ({self.reason})'
        if me.p is None:
            return f'{head}; not compared: this record has no stiction probability'
        if self.source is None:
            alone = f'; reads sticky on its own ({me.p:.3f})' if sticky else ''
            return f'{head}{alone}; which loop is the source cannot be told ({self.reason})'
        if sticky:
            return (f'{head}; reads sticky on its own as well ({me.p:.3f}): it may be a '
                    f'second source beside {self.source}')
        return (f'{head}; likely carried from {self.source}, whose valve explains the '
                f'cycle better ({self.reason})')


@dataclass(frozen=True)
class NotCompared:
    """Two loops that cycle at one period but whose records cannot be set side by side."""

    names: tuple[str, str]
    period_s: float
    reason: str

    def to_json(self) -> dict:
        """Return plain JSON types."""
        return {'names': list(self.names), 'period_s': round(self.period_s, 3),
                'reason': self.reason}


@dataclass
class PlantWide:
    """
    The shared cycles of a batch.

    ``not_compared`` lists the pairs at one period that no group holds
    together because their clock times do not allow it, with the reason, so
    that a missing group is never read as "not coupled".
    """

    groups: list[SharedCycle] = field(default_factory=list)
    not_compared: list[NotCompared] = field(default_factory=list)

    def group_of(self, name: str) -> SharedCycle | None:
        """Return the shared cycle ``name`` belongs to, or None."""
        return next((g for g in self.groups if any(m.name == name for m in g.members)), None)

    def to_json(self) -> list:
        """Return the groups as plain JSON types."""
        return [g.to_json() for g in self.groups]

    def not_compared_json(self) -> list:
        """Return the pairs at one period that could not be compared, as plain JSON types."""
        return [n.to_json() for n in self.not_compared]


def _apart_in_time(a: CycleMember, b: CycleMember, period_s: float) -> str:
    """Return why the records of ``a`` and ``b`` cannot be compared, or '' if they can."""
    if a.start is None and b.start is None:
        return ''
    if a.start is None or b.start is None:
        return 'one has clock times, the other none'
    if a.clock != b.clock:
        return f'clock times on different bases ({a.clock}, {b.clock})'
    end_a = a.end if a.end is not None else math.inf
    end_b = b.end if b.end is not None else math.inf
    common = min(end_a, end_b) - max(a.start, b.start)
    if common < MIN_OVERLAP_PERIODS * period_s:
        return (f'recorded {max(common, 0.0):.0f} s together, under '
                f'{MIN_OVERLAP_PERIODS:g} periods')
    return ''


def _same_period(a: CycleMember, b: CycleMember, tolerance: float) -> bool:
    return max(a.period_s, b.period_s) / min(a.period_s, b.period_s) <= 1.0 + tolerance


def _fits(group: list[CycleMember], m: CycleMember, tolerance: float) -> bool:
    # Complete linkage: within the tolerance of, and recorded with, every member.
    return all(_same_period(g, m, tolerance)
               and not _apart_in_time(g, m, max(g.period_s, m.period_s)) for g in group)


def _source(members: list[CycleMember], gap: float) -> tuple[str | None, str]:
    known = sorted((m for m in members if m.p is not None), key=lambda m: -(m.p or 0.0))
    if len(known) < 2:
        return None, 'fewer than two members have a stiction probability'
    best, second = known[0], known[1]
    p1, p2 = best.p or 0.0, second.p or 0.0
    if p1 < FLOOR:
        return None, f'no member reads sticky on its own (the highest, {best.name}, {p1:.3f})'
    if p1 - p2 < gap:
        return None, (f'stiction probabilities {p1:.3f} ({best.name}) and {p2:.3f} '
                      f'({second.name}) are within {gap:g}')
    return best.name, f'stiction probability {p1:.3f} against at most {p2:.3f}'


def shared_cycles(members: list[CycleMember], tolerance: float = TOLERANCE,
                  gap: float = GAP) -> PlantWide:
    """
    Return the cycles that two or more loops share, each with its likely source.

    Parameters
    ----------
    members : list of CycleMember
        Loops with a resolvable oscillation (period in seconds, > 0), with
        distinct names.
    tolerance : float
        How far apart (relative) the periods of one group may be, all pairs.
    gap : float
        How far the source's stiction probability must stand above every
        other member's; else the group's source is None, with the reason.

    Returns
    -------
    PlantWide
        The groups of two loops or more, in the order of their shortest
        period; the same whatever the order of ``members``.

    """
    bad = [m.name for m in members if not (m.period_s > 0 and math.isfinite(m.period_s))]
    if bad:
        raise ValueError(f'period must be a positive number of seconds: {bad}')
    names = [m.name for m in members]
    if len(set(names)) != len(names):
        raise ValueError('member names must be distinct')
    groups: list[list[CycleMember]] = []
    for m in sorted(members, key=lambda m: (m.period_s, m.name)):
        home = next((g for g in groups if _fits(g, m, tolerance)), None)
        if home is None:
            groups.append([m])
        else:
            home.append(m)
    out = []
    for g in groups:
        if len(g) < 2:
            continue
        source, reason = _source(g, gap)
        ordered = sorted(g, key=lambda m: (1.0 if m.p is None else -m.p, m.name))
        out.append(SharedCycle(float(np.median([m.period_s for m in g])), ordered, source,
                               reason, clock=any(m.start is not None for m in g)))
    home = {m.name: i for i, g in enumerate(groups) for m in g}
    apart = []
    ordered_members = sorted(members, key=lambda m: (m.period_s, m.name))
    for i, a in enumerate(ordered_members):
        for b in ordered_members[i + 1:]:
            if not _same_period(a, b, tolerance):
                break
            why = _apart_in_time(a, b, max(a.period_s, b.period_s))
            if why and home[a.name] != home[b.name]:
                apart.append(NotCompared((a.name, b.name), (a.period_s + b.period_s) / 2, why))
    return PlantWide(out, apart)
