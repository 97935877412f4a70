"""
Every OP/PV-only stiction signature of one record, in one call.

The oscillation is detected on the control error SP - PV (Thornhill, Huang
and Zhang 2003, J. Process Control 13, 91-100); its period feeds the
signatures that need one.  Without a regular oscillation, or with one the
sampling cannot resolve (shorter than 10 samples, longer than a quarter of
the record: ``oscillation.period_sanity``), those return stiction=None with
the reason; the bicoherence test
(Choudhury, Shah and Thornhill 2004, Automatica 40, 1719-1728), Yamashita's
index and the slip-event test need none and always run.  See each module
for its paper and thresholds.
"""

import numpy as np

from stiction_ros.analysis.oscillation import as_signal, detect_oscillation, period_sanity
from stiction_ros.analysis.signatures import bicoherence as bic
from stiction_ros.analysis.signatures import ellipse as ell
from stiction_ros.analysis.signatures import he_curve_fit as he
from stiction_ros.analysis.signatures import horch as hor
from stiction_ros.analysis.signatures import slip_events as slip
from stiction_ros.analysis.signatures import yamashita as yam
from stiction_ros.analysis.signatures.result import Signature

# name: (threshold, reference) of the signatures that need an oscillation
NEED_OSCILLATION = {
    'horch': (hor.STICTION_DEG, hor.REFERENCE),
    'he_curve_fit': (he.STICTION_SI, he.REFERENCE),
    'ellipse': (None, ell.REFERENCE),
    'hos_pv_op': (None, bic.REFERENCE + '; ' + ell.REFERENCE),
}


def compute_signatures(op, pv, sp, sample_time, integrating=False):
    """
    Return ``(oscillation, signatures)`` for one record.

    ``oscillation`` is the :class:`OscillationResult` of SP - PV;
    ``signatures`` maps 'horch', 'he_curve_fit', 'bicoherence', 'ellipse' and
    'hos_pv_op' (bicoherence combined with the PV-OP ellipse), 'yamashita' and
    'slip_events' to their :class:`Signature`.  ``sp`` may be a scalar.
    ``integrating`` is True for a process with an integrator (e.g. a level loop).
    """
    op, pv = as_signal(op), as_signal(pv)
    if sp is None:
        # Without a set point the deviation from the mean stands in for the error.
        sp = float(np.mean(pv))
    sp = np.broadcast_to(as_signal(sp), pv.shape) if np.ndim(sp) else np.full(pv.shape, sp)
    if len(op) != len(pv):
        raise ValueError(f'op has {len(op)} samples but pv has {len(pv)}')
    error = sp - pv
    osc = detect_oscillation(error, sample_time)
    sigs = {}
    unresolvable = period_sanity(osc.period_s, sample_time, len(pv)) if osc.oscillating else ''
    if osc.oscillating and not unresolvable:
        period = osc.period_s
        sigs['horch'] = hor.horch(op, pv, sample_time, integrating=integrating)
        sigs['he_curve_fit'] = he.he_curve_fit(op, pv, sample_time, integrating=integrating,
                                               period_s=period)
        sigs['ellipse'] = ell.ellipse(op, pv, sample_time, period_s=period,
                                      integrating=integrating)
    resolved = osc.oscillating and not unresolvable
    sigs['bicoherence'] = bic.bicoherence(error, sample_time,
                                          period_s=osc.period_s if resolved else None)
    if resolved:
        sigs['hos_pv_op'] = bic.hos_with_pv_op(sigs['bicoherence'], sigs['ellipse'])
    else:
        why = (f'oscillation not resolvable: {unresolvable}' if unresolvable
               else f'no regular oscillation ({osc.reason})')
        for name, (threshold, reference) in NEED_OSCILLATION.items():
            sigs[name] = Signature(name, None, threshold, None, why, reference)
    # Yamashita's index needs no oscillation: slow stick-slip events suffice.
    sigs['yamashita'] = yam.yamashita(op, pv, sample_time, integrating=integrating)
    sigs['slip_events'] = slip.slip_events(op, pv, sp, sample_time, integrating=integrating)
    order = ('horch', 'he_curve_fit', 'bicoherence', 'ellipse', 'hos_pv_op', 'yamashita',
             'slip_events')
    return osc, {name: sigs[name] for name in order}
