"""
Whether the shared-cycle view names the sticky loop and spares the loop that carries its cycle.

Each seed makes a pair (``sim.coupled_loops``): a sticky loop whose PV,
through a vessel, loads a healthy loop.  The detector reads each loop alone,
as the analyzer does; the pairs in which both loops have a resolvable cycle
at one period form a shared cycle (``analysis.plantwide``), and the study
counts how often its source is the sticky loop, the healthy one, or not
told, and what that does to the healthy loops the detector flagged alone.
"""

from collections.abc import Callable
from dataclasses import asdict, dataclass, field
import time

import numpy as np

from stiction_ros._threads import pool_map
from stiction_ros.analysis.detection.detect import detect
from stiction_ros.analysis.oscillation import detrend, fundamental_amplitude
from stiction_ros.analysis.plantwide import CycleMember, FLOOR, GAP, shared_cycles, TOLERANCE
from stiction_ros.sim.coupled_loops import coupled_pair


@dataclass
class PairRow:
    """What the detector and the shared-cycle view made of one pair."""

    seed: int
    up_p: float | None          # the sticky loop's probability (None: not judged)
    down_p: float | None        # the healthy loop's
    up_period: float | None     # s, when its cycle is resolvable
    down_period: float | None
    source: str = ''            # 'up', 'down', '' (not told) or 'none' (no shared cycle)
    reason: str = ''
    # How distorted each PV's cycle is (harmonics 2-5 over the fundamental), the source
    # pointer of Thornhill (2005), for comparison; None without a resolvable cycle.
    up_harmonics: float | None = None
    down_harmonics: float | None = None


def harmonics(x: np.ndarray, period_samples: float) -> float:
    """Return the RMS of harmonics 2-5 of a cycle over its fundamental (least squares)."""
    x = detrend(x)
    first = fundamental_amplitude(x, period_samples)
    more = [fundamental_amplitude(x, period_samples / k) for k in range(2, 6)
            if period_samples / k >= 2.5]
    return float(np.sqrt(np.sum(np.square(more))) / max(first, 1e-300))


def _read(rec: dict, sc) -> tuple[float | None, float | None]:
    det = detect(rec['op'], rec['pv'], rec['sp'], sc.sample_time, sc.integrating)
    f = det.features or {}
    period = None
    if f.get('osc_resolvable') == 1.0 and np.isfinite(f.get('osc_log_period_samples', np.nan)):
        period = float(10.0 ** f['osc_log_period_samples'] * sc.sample_time)
    return det.probability, period


def pair_row(seed: int) -> PairRow:
    """Return the :class:`PairRow` of the pair of ``seed``."""
    pair = coupled_pair(seed)
    up_p, up_period = _read(pair.up, pair.upstream)
    down_p, down_period = _read(pair.down, pair.downstream)
    row = PairRow(seed, up_p, down_p, up_period, down_period, source='none')
    if up_period is None or down_period is None:
        return row
    ts = pair.upstream.sample_time
    row.up_harmonics = harmonics(pair.up['pv'], up_period / ts)
    row.down_harmonics = harmonics(pair.down['pv'], down_period / ts)
    # Both records cover the same hours: no clock time, taken as recorded together.
    shared = shared_cycles([CycleMember('up', up_period, up_p),
                            CycleMember('down', down_period, down_p)])
    if shared.groups:
        g = shared.groups[0]
        row.source, row.reason = g.source or '', g.reason
    return row


@dataclass
class SharedCycleStudy:
    """Every pair's row and the tallies the page shows."""

    seeds: tuple[int, int]
    rows: list[PairRow] = field(default_factory=list)
    seconds: float = 0.0

    def tally(self) -> dict:
        """Return the counts of the page."""
        rows = self.rows
        both = [r for r in rows if r.up_period is not None and r.down_period is not None]
        grouped = [r for r in both if r.source != 'none']
        flagged = [r for r in grouped if r.down_p is not None and r.down_p >= 0.5]
        # The healthy loops with a resolvable cycle of their own that was not shared: the
        # baseline for how often a cycle alone gets a healthy loop flagged.
        unshared = [r for r in rows if r.source == 'none' and r.down_period is not None
                    and r.down_p is not None]
        return {
            'pairs': len(rows), 'both_cycle': len(both), 'shared': len(grouped),
            'source_up': sum(r.source == 'up' for r in grouped),
            'source_down': sum(r.source == 'down' for r in grouped),
            'source_not_told': sum(r.source == '' for r in grouped),
            'harmonics_point_up': sum((r.up_harmonics or 0.0) > (r.down_harmonics or 0.0)
                                      for r in grouped),
            'carrier_flagged': len(flagged),
            # Flagged alone and at 0.5 or more, a carrier is never called one: its note says
            # that it may be a second source beside the one named.
            'carrier_flagged_source_up': sum(r.source == 'up' for r in flagged),
            'carrier_flagged_source_down': sum(r.source == 'down' for r in flagged),
            'carrier_flagged_not_told': sum(r.source == '' for r in flagged),
            'unshared_cycle_flagged': sum(r.down_p >= 0.5 for r in unshared
                                          if r.down_p is not None),
            'unshared_cycle': len(unshared),
            'up_found': sum(r.up_p is not None and r.up_p >= 0.5 for r in rows),
            'up_judged': sum(r.up_p is not None for r in rows)}

    def to_json(self) -> dict:
        """Return plain JSON types."""
        return {'seeds': list(self.seeds), 'seconds': round(self.seconds, 1),
                'tolerance': TOLERANCE, 'gap': GAP, 'floor': FLOOR, 'tally': self.tally(),
                'rows': [asdict(r) for r in self.rows]}


def run(seeds: range, jobs: int = 1,
        progress: Callable[[int, int, float], None] | None = None) -> SharedCycleStudy:
    """Read the pair of every seed over ``jobs`` processes; return the study."""
    t0 = time.perf_counter()
    study = SharedCycleStudy((seeds.start, seeds.stop))
    for i, row in enumerate(pool_map(pair_row, list(seeds), jobs, chunksize=5), 1):
        study.rows.append(row)
        if progress is not None:
            progress(i, len(seeds), time.perf_counter() - t0)
    study.seconds = time.perf_counter() - t0
    return study
