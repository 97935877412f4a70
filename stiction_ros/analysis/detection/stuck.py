"""
Stuck periods and slip events: stiction that need not oscillate (read on every record).

Kano, Maruta, Kugemoto and Shimizu (2004), Practical model and detection
algorithm for valve stiction, IFAC DYCOPS, read the valve's stuck periods
straight from the data: stretches where the controller output travels but
the valve position does not.  Without a valve position we read it through
the process: for a self-regulating loop PV itself stands in for MV (a fast
flow loop's PV *is* the flow through the valve); for an integrating loop
(a level) the valve sets the *rate* of PV, so the proxy is PV's smoothed
slope.  A stuck period is then a stretch where the proxy stays inside its
own noise band while OP travels well beyond its own noise; a slip is a jump
of the proxy out of such a period.  Set-point steps are cut out: a PV that
moves right after its set point did is a response, not a slip.

Every threshold is in units of the signal's own noise (robust, from first
differences), so nothing depends on the engineering units.
"""

from dataclasses import dataclass, field
import functools

import numpy as np

from stiction_ros.analysis.detection.resolve import robust_noise

SMOOTH = 5           # samples averaged for the proxy and OP
STILL_SIGMAS = 3.0   # proxy change within this many smoothed-noise sigmas is still
MIN_STUCK = 15       # samples of stillness for a stuck period
OP_SIGMAS = 6.0      # OP travel during a stuck period, in OP-noise sigmas
JUMP_SIGMAS = 6.0    # a slip moves the proxy this many sigmas within SMOOTH samples
SP_QUIET = 30        # samples after a set-point step in which a PV jump is no slip


def record_row(k: int, rows: np.ndarray | None) -> int:
    """
    Return the row of the record as given that sample ``k`` of the read signal came from.

    ``rows`` lists, for each sample read, its row in the record (held rows
    dropped before reading); None when they are the same.  An end index one
    past the last sample maps to the last row.
    """
    return int(k if rows is None else rows[min(k, len(rows) - 1)])


@dataclass
class StuckResult:
    """Stuck periods and slips of one record, with the figures the detector uses."""

    stuck: list = field(default_factory=list)      # (start, stop, op_travel) in samples
    slips: list = field(default_factory=list)      # (sample, proxy jump in sigmas)
    stuck_fraction: float = 0.0    # share of samples inside stuck periods
    stuck_op_share: float = 0.0    # share of OP's total travel made while stuck
    slips_after_stuck: float = 0.0  # share of slips that end a stuck period
    jump_rate: float = 0.0         # slips per 100 samples
    # Travel-weighted over the stuck periods (NaN without one): how straight
    # OP's path is (R^2 of a line) and how far the error's mean sits from zero
    # in standard errors, log10(1 + z).  A stuck valve leaves a constant error
    # that integral action turns into a straight ramp; a healthy loop that
    # holds PV against a wandering load has an error centred on zero and an
    # OP that wanders with the load.
    ramp_r2: float = float('nan')
    log_offset: float = float('nan')

    def to_json(self, sample_time: float, rows: np.ndarray | None = None) -> dict:
        """
        Return the evidence in seconds, for the report.

        ``rows`` maps a sample read to its row in the record (when held rows
        were dropped before reading); None when they are the same.
        """
        def s(k):
            return round(record_row(k, rows) * sample_time, 1)
        return {'stuck_periods_s': [[s(a), s(b), round(float(t), 4)]
                                    for a, b, t in self.stuck[:20]],
                'slips_s': [[s(k), round(float(z), 1)] for k, z in self.slips[:20]],
                'stuck_fraction': round(self.stuck_fraction, 4),
                'stuck_op_share': round(self.stuck_op_share, 4),
                'slips_after_stuck': round(self.slips_after_stuck, 4),
                'ramp_r2': _rounded(self.ramp_r2), 'log_offset': _rounded(self.log_offset)}


def _rounded(v: float) -> float | None:
    return round(float(v), 4) if np.isfinite(v) else None


def smooth(x: np.ndarray, w: int = SMOOTH) -> np.ndarray:
    """Return the centred moving average of ``x`` over ``w`` samples (edges shortened)."""
    k = np.ones(w) / w
    num = np.convolve(x, k, mode='same')
    den = np.convolve(np.ones_like(x), k, mode='same')
    return num / den


def valve_proxy(pv: np.ndarray, integrating: bool) -> np.ndarray:
    """Return what stands in for the valve position: PV, or PV's slope in a level loop."""
    pv = np.asarray(pv, dtype=np.float64)
    if not integrating:
        return pv
    return np.gradient(smooth(pv, SMOOTH))


def set_point_steps(sp: np.ndarray | None, pv_sigma: float) -> np.ndarray:
    """Return the samples where the set point steps by more than the PV noise."""
    if sp is None:
        return np.empty(0, dtype=int)
    d = np.abs(np.diff(np.asarray(sp, dtype=np.float64)))
    return np.flatnonzero(d > max(pv_sigma, 1e-12)) + 1


def _runs(mask: np.ndarray) -> list:
    edges = np.flatnonzero(np.diff(np.concatenate(([0], mask.astype(np.int8), [0]))))
    return list(zip(edges[::2], edges[1::2]))


def _spread(x: np.ndarray) -> float:
    """Return a robust standard deviation (MAD) of ``x``."""
    return float(1.4826 * np.median(np.abs(x - np.median(x))))


def _operator_gain(n: int, integrating: bool, change: bool = True) -> float:
    """Return the std of the smoothed proxy (or its change) for unit white noise on PV."""
    imp = np.zeros(n)
    imp[n // 2] = 1.0
    ms = smooth(valve_proxy(imp, integrating))
    h = SMOOTH
    return float(np.linalg.norm(ms[2 * h:] - ms[:-2 * h] if change else ms))


def _still_segments(ms: np.ndarray, still: np.ndarray, band: float) -> list:
    """Return the (start, stop) stretches of ``still`` samples whose proxy stays in ``band``."""
    out = []
    for a, b in _runs(still):
        start, lo, hi = a, ms[a], ms[a]
        for k in range(a, b):
            lo, hi = min(lo, ms[k]), max(hi, ms[k])
            if hi - lo > band:
                out.append((start, k))
                start, lo, hi = k, ms[k], ms[k]
        out.append((start, b))
    return out


@functools.cache
def change_reach(integrating: bool) -> int:
    """
    Return how many rows before a step in PV the proxy's change already moves.

    The change at a row is centred: it spans the smoothed proxy ``SMOOTH``
    rows either side, each a mean of ``SMOOTH`` rows (7 rows back for PV
    itself), and a level's proxy, a slope, reaches 3 rows further.  A PV
    answering a set-point step shows that early, and is no slip there.
    """
    n = 16 * SMOOTH      # long enough that the edges never reach the step
    step = np.zeros(n)
    step[n // 2:] = 1.0
    ms = smooth(valve_proxy(step, integrating))
    h = SMOOTH
    moved = np.flatnonzero(np.abs(ms[2 * h:] - ms[:-2 * h]) > 1e-12) + h
    return int(n // 2 - moved[0])


def proxy_change(pv: np.ndarray, integrating: bool) -> tuple[np.ndarray, float, float]:
    """
    Return the proxy's change over 2 ``SMOOTH`` samples, centred, and two noise scales.

    ``still``: what PV's white noise alone gives (exact, through the same
    linear filters), the band a valve at rest stays in.  ``jump``: the
    larger of that and the change's robust spread, so that coloured noise
    and a loop's ordinary movement set the floor a slip must clear.
    """
    ms = smooth(valve_proxy(pv, integrating))
    n, h = len(ms), SMOOTH
    change = np.zeros(n)
    change[h:n - h] = ms[2 * h:] - ms[:n - 2 * h]
    white = max(robust_noise(pv) * _operator_gain(min(n, 64), integrating), 1e-12)
    return change, white, max(white, _spread(change[h:n - h]))


def stuck_periods(op: np.ndarray, pv: np.ndarray, sp: np.ndarray | None,
                  integrating: bool = False) -> StuckResult:
    """Return the :class:`StuckResult` of one record (arrays of equal length)."""
    op = np.asarray(op, dtype=np.float64)
    pv = np.asarray(pv, dtype=np.float64)
    n = len(pv)
    change, scale, jump_scale = proxy_change(pv, integrating)
    ops = smooth(op)
    op_sig = robust_noise(op) or float(np.std(op)) * 1e-3 or 1e-12
    # How far the proxy moves per % of OP over the record (a loop gain seen
    # through the controller): an OP travel that should have moved the proxy
    # by more than its noise, and did not, is a stuck period.
    ms = smooth(valve_proxy(pv, integrating))
    gain = (np.subtract(*np.percentile(ms, [95, 5]))
            / max(np.subtract(*np.percentile(ops, [95, 5])), 1e-12))
    still = np.abs(change) < STILL_SIGMAS * scale
    quiet = np.ones(n, dtype=bool)
    # PV answers at the step's row at the earliest; its centred change shows
    # that many rows before it.
    early = change_reach(integrating)
    for k in set_point_steps(sp, robust_noise(pv)):
        quiet[max(0, k - early):k + SP_QUIET] = False
    res = StuckResult()
    travel_total = float(np.sum(np.abs(np.diff(ops)))) or 1e-12
    stuck_travel = 0.0
    # A valve at rest leaves the proxy inside its noise for the whole stretch,
    # not just from one window to the next (a slow settling passes that test).
    gain0 = _operator_gain(min(n, 64), integrating, change=False)
    band = 2.0 * STILL_SIGMAS * robust_noise(pv) * gain0
    for a, b in _still_segments(ms, still, max(band, 1e-12)):
        if b - a < MIN_STUCK:
            continue
        seg = ops[a:b]
        travel = float(np.max(seg) - np.min(seg))
        if travel > OP_SIGMAS * op_sig and gain * travel > STILL_SIGMAS * scale:
            res.stuck.append((int(a), int(b), travel))
            stuck_travel += float(np.sum(np.abs(np.diff(seg))))
    in_stuck = np.zeros(n, dtype=bool)
    for a, b, _ in res.stuck:
        in_stuck[a:b] = True
    jump = np.abs(change) / jump_scale
    h = SMOOTH
    k = h
    ends = 0
    while k < n - h:
        if jump[k] > JUMP_SIGMAS and quiet[k]:
            top = k + int(np.argmax(jump[k:k + 2 * h]))
            res.slips.append((top, float(jump[top])))
            if np.any(in_stuck[max(0, top - 3 * h):top]):
                ends += 1
            k = top + 2 * h
        else:
            k += 1
    res.ramp_r2, res.log_offset = _ramp_and_offset(res.stuck, op, pv, sp)
    res.stuck_fraction = float(np.mean(in_stuck))
    res.stuck_op_share = min(1.0, stuck_travel / travel_total)
    res.slips_after_stuck = ends / len(res.slips) if res.slips else 0.0
    res.jump_rate = 100.0 * len(res.slips) / n
    return res


def _ramp_and_offset(stuck: list, op: np.ndarray, pv: np.ndarray,
                     sp: np.ndarray | None) -> tuple[float, float]:
    """Return the travel-weighted ramp R^2 of OP and log10(1 + z) of the error's offset."""
    if not stuck:
        return float('nan'), float('nan')
    sigma = robust_noise(pv) or 1e-12
    error = (np.full(len(pv), float(np.mean(pv))) if sp is None
             else np.asarray(sp, dtype=np.float64)) - pv
    r2, z, w = [], [], []
    for a, b, travel in stuck:
        seg = op[a:b]
        t = np.arange(b - a) - (b - a - 1) / 2.0
        slope = float(t @ (seg - seg.mean())) / float(t @ t)
        var = float(np.var(seg))
        r2.append(1.0 - float(np.var(seg - seg.mean() - slope * t)) / var if var > 0 else 0.0)
        z.append(abs(float(np.mean(error[a:b]))) / (sigma / np.sqrt(b - a)))
        w.append(travel)
    weights = np.asarray(w) / float(np.sum(w))
    return float(weights @ np.asarray(r2)), float(np.log10(1.0 + weights @ np.asarray(z)))
