"""
The detector's figures in an engineer's words, for the evidence line.

Each name is kept beside its words (``cnn_logit``, the small network's
reading of the trend) so that the JSON, DETECTION.md section 2 and the
terminal can be read against one another.
"""

from stiction_ros.analysis.detection.features import FEATURE_NAMES

WORDS = {
    'integrating': 'loop is integrating',
    'log_samples': 'record length',
    'osc_regularity': 'regularity of the cycle',
    'osc_log_period_samples': 'cycle period in samples',
    'osc_cycles': 'cycles in the record',
    'osc_resolvable': 'cycle resolvable',
    'horch_deg': "Horch's cross-correlation",
    'he_si': "He's sine-vs-triangle index",
    'bic_ngi': 'bicoherence NGI',
    'bic_nli': 'bicoherence NLI',
    'ellipse_width': 'PV-OP ellipse width',
    'yamashita': "Yamashita's stick pattern",
    'slip_events': 'slip events',
    'stuck_fraction': 'share of samples stuck',
    'stuck_op_share': "share of OP's travel made while stuck",
    'slips_per_100': 'slips per 100 samples',
    'slips_after_stuck': 'share of slips that end a stuck period',
    'stuck_ramp_r2': "straightness of OP's ramp while stuck",
    'stuck_log_offset': 'error held off zero while stuck',
    'pv_jump_kurtosis': "peakedness of PV's jumps",
    'pv_log_max_jump': 'largest PV jump, in noise widths',
    'pv_noise_share': "PV's noise share",
    'op_noise_share': "OP's noise share",
    'error_lag1': "error's sample-to-sample correlation",
    'error_bias': 'error held off zero',
    'op_ramp_share': 'share of OP in straight ramps',
    'op_saturated': 'OP at a limit',
    'sp_steps_per_100': 'set-point steps per 100 samples',
    'ham_variance_ratio': 'sticky valve against linear (Hammerstein residual)',
    'ham_log_lr': 'sticky valve against linear (Hammerstein likelihood)',
    'ham_S_rel': 'Hammerstein band S over OP range',
    'ham_J_over_S': 'Hammerstein slip J/S',
    'ham_reliable': 'Hammerstein fit reliable',
    'ham_log_jump_lr': 'slip against deadband (Hammerstein likelihood)',
    'oe_ratio': 'sticky valve against linear (output-error fit)',
    'oe_S_rel': 'output-error band S over OP range',
    'pe_ratio': 'sticky valve against linear (prediction-error fit)',
    'pe_c': "linear fit's disturbance model",
    'cnn_logit': "small network's reading of the trend",
    'cnn_large_logit': "large network's reading of the trend",
}

assert set(FEATURE_NAMES) <= set(WORDS), sorted(set(FEATURE_NAMES) - set(WORDS))


def words(name: str) -> str:
    """Return the figure ``name`` in words, with its name in brackets ('' names stay)."""
    return f'{WORDS[name]} ({name})' if name in WORDS else name
