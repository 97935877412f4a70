"""
The detector's view of a record: a fixed vector of scale-free figures.

Every figure is computed from OP, PV and SP alone, in units of the record's
own noise or range, so a simulated loop in % and a plant loop in t/h give
comparable numbers.  A figure that does not apply (no resolvable
oscillation for Horch's test, say) is NaN, which the learned detector
treats as missing rather than as zero.  :data:`FEATURE_NAMES` fixes the
order; the model file stores it and refuses a different one.
"""

import numpy as np

from stiction_ros.analysis.detection.cnn import cnn_logit
from stiction_ros.analysis.detection.output_error import output_error_figures
from stiction_ros.analysis.detection.prediction_error import prediction_error_figures
from stiction_ros.analysis.detection.resolve import lag1, period_sanity, robust_noise
from stiction_ros.analysis.detection.stuck import (
    proxy_change, set_point_steps, SMOOTH, stuck_periods)
from stiction_ros.analysis.signatures.all import compute_signatures

FEATURE_NAMES = (
    'integrating', 'log_samples',
    'osc_regularity', 'osc_log_period_samples', 'osc_cycles', 'osc_resolvable',
    'horch_deg', 'he_si', 'bic_ngi', 'bic_nli', 'ellipse_width', 'yamashita', 'slip_events',
    'stuck_fraction', 'stuck_op_share', 'slips_per_100', 'slips_after_stuck',
    'stuck_ramp_r2', 'stuck_log_offset',
    'pv_jump_kurtosis', 'pv_log_max_jump',
    'pv_noise_share', 'op_noise_share', 'error_lag1', 'error_bias', 'op_ramp_share',
    'op_saturated', 'sp_steps_per_100',
    'ham_variance_ratio', 'ham_log_lr', 'ham_S_rel', 'ham_J_over_S', 'ham_reliable',
    'ham_log_jump_lr', 'oe_ratio', 'oe_S_rel', 'pe_ratio', 'pe_c', 'cnn_logit',
)
# A coarser Hammerstein search than the one that sizes the band in the
# report: the detector needs how much a sticky valve explains, not S to 0.2 %.
HAM_MAX_DELAY = 10
HAM_GRID = 40
NAN = float('nan')


def _value(sig) -> float:
    return NAN if sig is None or sig.value is None else float(sig.value)


def _noise_share(x: np.ndarray) -> float:
    sd = float(np.std(x))
    return min(1.0, robust_noise(x) / sd) if sd > 0 else 1.0


def _error_bias(error: np.ndarray, sigma: float, w: int = 50) -> float:
    """Return the RMS of the error's window means in noise units (integral action not acting)."""
    n = len(error) // w
    if n < 2 or sigma <= 0:
        return NAN
    means = error[:n * w].reshape(n, w).mean(axis=1)
    return float(np.sqrt(np.mean(means ** 2)) / (sigma / np.sqrt(w)))


def _ramp_share(op: np.ndarray, sigma: float, w: int = 30) -> float:
    """Return the share of OP windows that are a straight ramp well above OP's noise."""
    n = len(op) // w
    if n < 2:
        return NAN
    t = np.arange(w) - (w - 1) / 2.0
    hits = 0
    for i in range(n):
        seg = op[i * w:(i + 1) * w]
        slope = float(t @ (seg - seg.mean())) / float(t @ t)
        fit = slope * t
        resid = seg - seg.mean() - fit
        travel = abs(slope) * (w - 1)
        if travel > 6.0 * max(sigma, 1e-12) and resid.std() < 0.25 * travel:
            hits += 1
    return hits / n


def _jump_stats(pv: np.ndarray, integrating: bool) -> tuple[float, float]:
    """Return (log10 kurtosis, log10 largest) of the valve proxy's changes in noise units."""
    change, _, scale = proxy_change(pv, integrating)
    z = change[SMOOTH:len(change) - SMOOTH] / scale
    kurt = float(np.mean(z ** 4) / max(np.mean(z ** 2) ** 2, 1e-300))
    return float(np.log10(max(kurt, 1e-12))), float(np.log10(1.0 + np.max(np.abs(z))))


def hammerstein_features(op: np.ndarray, pv: np.ndarray, sample_time: float,
                         integrating: bool) -> dict:
    """
    Return the figures of a coarse Hammerstein fit: a sticky valve before a linear plant.

    The residual variance against a linear valve (``variance_ratio``, below
    1 when stiction explains PV better) and the likelihood ratio of the two
    (Jelali 2008; Srinivasan et al. 2005) were the strongest single
    separators on simulated loops; S is relative to OP's range.  The jump's
    likelihood ratio (J free against J = 0) is there for backlash, the
    look-alike the detector confused most with stiction (half the simulated
    backlash valves of the calibration seeds were flagged).
    """
    from stiction_ros.analysis.hammerstein import quantify
    span = float(np.ptp(op)) or 1.0
    h = quantify(op, pv, sample_time, integrating=integrating, max_delay=HAM_MAX_DELAY,
                 resolution=span / HAM_GRID)
    d = h.details if isinstance(h.details, dict) else {}
    lr, jump_lr = d.get('likelihood_ratio'), d.get('jump_likelihood_ratio')
    ratio = h.fit_improvement
    s_val, j_val = h.S, h.J
    return {'ham_variance_ratio': NAN if ratio is None else float(ratio),
            'ham_log_lr': NAN if lr is None else float(np.log10(1.0 + max(float(lr), 0.0))),
            'ham_S_rel': NAN if s_val is None else float(s_val) / span,
            'ham_J_over_S': (NAN if s_val is None or j_val is None or s_val <= 0
                             else float(j_val) / float(s_val)),
            'ham_reliable': float(bool(h.reliable)),
            'ham_log_jump_lr': (NAN if jump_lr is None
                                else float(np.log10(1.0 + max(float(jump_lr), 0.0))))}


def extract(op: np.ndarray, pv: np.ndarray, sp: np.ndarray | None, sample_time: float,
            integrating: bool = False) -> tuple[np.ndarray, dict]:
    """
    Return ``(features, evidence)`` for one contiguous record.

    ``features`` follows :data:`FEATURE_NAMES`; ``evidence`` holds the
    oscillation, the signatures and the stuck periods behind them, for the
    report.
    """
    op = np.asarray(op, dtype=np.float64)
    pv = np.asarray(pv, dtype=np.float64)
    n = len(pv)
    sp_arr = (np.full(n, float(np.mean(pv))) if sp is None
              else np.broadcast_to(np.asarray(sp, dtype=np.float64), pv.shape))
    osc, sigs = compute_signatures(op, pv, sp_arr, sample_time, integrating=integrating)
    insane = period_sanity(osc.period_s, sample_time, n) if osc.oscillating else ''
    resolvable = osc.oscillating and not insane
    st = stuck_periods(op, pv, sp_arr, integrating)
    kurt, max_jump = _jump_stats(pv, integrating)
    bic = sigs.get('bicoherence')
    oe_ratio, oe_s = output_error_figures(op, pv, integrating)
    pe_ratio, pe_c = prediction_error_figures(op, pv, integrating)
    error = sp_arr - pv
    pv_sig = robust_noise(pv)
    osc_only = (lambda v: v if resolvable else NAN)
    f = {
        'integrating': float(integrating), 'log_samples': float(np.log10(n)),
        'osc_regularity': float(min(osc.regularity, 10.0)),
        'osc_log_period_samples': (float(np.log10(osc.period_s / sample_time))
                                   if osc.oscillating else NAN),
        'osc_cycles': float(osc.n_cycles) if osc.oscillating else NAN,
        'osc_resolvable': float(resolvable),
        'horch_deg': osc_only(_value(sigs.get('horch'))),
        'he_si': osc_only(_value(sigs.get('he_curve_fit'))),
        'bic_ngi': float(bic.details.get('ngi', NAN)) if bic is not None else NAN,
        'bic_nli': _value(bic),
        'ellipse_width': osc_only(_value(sigs.get('ellipse'))),
        'yamashita': _value(sigs.get('yamashita')),
        'slip_events': _value(sigs.get('slip_events')),
        'stuck_fraction': st.stuck_fraction, 'stuck_op_share': st.stuck_op_share,
        'slips_per_100': st.jump_rate, 'slips_after_stuck': st.slips_after_stuck,
        'stuck_ramp_r2': st.ramp_r2, 'stuck_log_offset': st.log_offset,
        'pv_jump_kurtosis': kurt, 'pv_log_max_jump': max_jump,
        'pv_noise_share': _noise_share(pv), 'op_noise_share': _noise_share(op),
        'error_lag1': lag1(error), 'error_bias': _error_bias(error, pv_sig),
        'op_ramp_share': _ramp_share(op, robust_noise(op)),
        'op_saturated': float(np.mean((op <= 0.5) | (op >= 99.5))),
        'sp_steps_per_100': 100.0 * len(set_point_steps(sp_arr, pv_sig)) / n,
        **hammerstein_features(op, pv, sample_time, integrating),
        'oe_ratio': oe_ratio, 'oe_S_rel': oe_s, 'pe_ratio': pe_ratio, 'pe_c': pe_c,
        'cnn_logit': cnn_logit(op, pv, sp_arr, integrating),
    }
    vec = np.array([f[k] for k in FEATURE_NAMES], dtype=np.float64)
    vec[~np.isfinite(vec)] = NAN
    evidence = {'oscillation': osc, 'signatures': sigs, 'stuck': st,
                'period_problem': insane, 'features': f}
    return vec, evidence
