"""
Slip events: the valve's stick-slip seen in OP and PV without any oscillation.

Most sticky valves in plant data do not limit-cycle: in two hours they
stick once or twice, the integral action winds OP while PV stays off the set
point, and then the valve slips.  The signatures that need a regular
oscillation cannot see that.  A slip leaves marks that a healthy valve
does not make together, and this test asks for all of them:

1. **PV jumps out of rest** (a step of the ``W``-sample mean at least
   ``Z_MIN`` robust standard deviations of all such steps in the record,
   after PV drifted less than ``MIN_OFFSET`` of the jump over the ``L``
   samples before) while the set point held still over those ``L`` samples;
2. **toward the set point**: PV was off the set point, on the side the jump
   closes, by at least ``MIN_OFFSET`` of the jump, just before it.  A load
   disturbance on a loop at its set point moves PV *away* from it;
3. **while OP turns back**: OP had been travelling (at least ``MIN_TRAVEL``
   noise standard deviations over the ``L`` samples before) and moves the
   other way right after the jump.  In a healthy loop PV follows OP's
   travel; at a slip the stored travel is released at once and the
   proportional action pulls OP back.

One such event calls stiction.  The test is our own formulation of the
stick-slip mechanism of Choudhury, Thornhill and Shah (2005, Control
Engineering Practice 13, 641-658, Sect. 2); every setting below was fixed
from that mechanism and from simulated loops before it was run on the
plant records.  It applies to self-regulating loops only: through an
integrator a slip changes PV's slope, not its level.
"""

from dataclasses import replace

import numpy as np

from stiction_ros.analysis.signatures.result import Signature

REFERENCE = ('stick-slip mechanism after Choudhury, Thornhill and Shah (2005), Control '
             'Engineering Practice 13, 641-658; test formulated in stiction_ros')
W = 6
L = 30
Z_MIN = 6.0
MIN_OFFSET = 0.25
MIN_TRAVEL = 3.0
SP_STILL = 0.1
THRESHOLD = 1


def _window_means(x, w):
    c = np.concatenate(([0.0], np.cumsum(x)))
    return (c[w:] - c[:-w]) / w


def _robust_std(x):
    return 1.4826 * float(np.median(np.abs(x - np.median(x))))


def candidate_jumps(pv, w=W, z_min=Z_MIN):
    """
    Return [(k, z, step)] of PV jumps, strongest first, at most one per 2 ``w`` samples.

    ``step`` is mean(pv[k:k+w]) - mean(pv[k-w:k]); ``z`` divides it by the
    robust spread of that statistic over the record, so coloured noise and
    slow drifts set their own scale.  Empty when PV does not vary.
    """
    m = _window_means(pv, w)
    ks = np.arange(w, len(pv) - w + 1)
    step = m[ks] - m[ks - w]
    scale = _robust_std(step)
    if not np.isfinite(scale) or scale <= 0.0:
        return []
    z = step / scale
    taken = np.zeros(len(pv), dtype=bool)
    out = []
    for i in np.argsort(-np.abs(z)):
        if abs(z[i]) < z_min:
            break
        k = int(ks[i])
        if taken[k]:
            continue
        taken[max(0, k - 2 * w):k + 2 * w] = True
        out.append((k, float(z[i]), float(step[i])))
    return out


def classify(op, pv, sp, k, step, op_noise, w=W, span=L):
    """Return (is_slip, facts) for the jump of PV at sample ``k``."""
    error = sp - pv
    e_near = float(np.mean(error[k - w:k]))
    sp_moved = float(np.ptp(sp[max(0, k - span):k + w]))
    travel = float(op[k - 1] - op[max(0, k - span)])
    back = float(np.mean(op[k:k + w]) - op[k - 1])
    start = max(0, k - span)
    pv_drift = float(np.mean(pv[k - w:k]) - np.mean(pv[start:start + w]))
    facts = {'set_point_still': sp_moved <= SP_STILL * abs(step),
             'toward_set_point': (np.sign(e_near) == np.sign(step)
                                  and abs(e_near) >= MIN_OFFSET * abs(step)),
             'op_travelled': abs(travel) >= MIN_TRAVEL * op_noise,
             'op_turned_back': travel * back < 0.0,
             'pv_held_before': abs(pv_drift) <= MIN_OFFSET * abs(step)}
    numbers = {'offset_before': e_near, 'pv_drift_before': pv_drift, 'op_travel': travel,
               'op_after': back, 'set_point_change': sp_moved}
    return all(facts.values()), {**{k_: bool(v) for k_, v in facts.items()}, **numbers}


def found_text(n: int, first: dict, t: float | None = None) -> str:
    """Return the reason for ``n`` slip events, the first at ``t`` s (its own time if None)."""
    t = first['t'] if t is None else t
    return (f'{n} slip event(s): e.g. at t = {t:.0f} s PV jumped {first["pv_step"]:+.3g} '
            f'toward the set point while OP, after travelling {first["op_travel"]:+.3g}, '
            'turned back')


def on_record_clock(sig: Signature, offset: float) -> Signature:
    """Return ``sig`` with its events' times, and its reason's, ``offset`` s later."""
    events = sig.details.get('events') or []
    if not offset or not events:
        return sig
    events = [{**e, 't': e['t'] + offset} for e in events]
    reason = found_text(int(sig.value or 0), events[0]) if sig.stiction else sig.reason
    return replace(sig, reason=reason, details={**sig.details, 'events': events})


def slip_events(op, pv, sp, sample_time, integrating=False):
    """Return the :class:`Signature` counting slip events in one record."""
    op = np.asarray(op, dtype=np.float64)
    pv = np.asarray(pv, dtype=np.float64)
    sp = np.broadcast_to(np.asarray(sp, dtype=np.float64), pv.shape)
    if integrating:
        return Signature('slip_events', None, THRESHOLD, None,
                         'integrating loop: a slip changes the slope of PV, not its level',
                         REFERENCE)
    if len(pv) < 2 * L:
        return Signature('slip_events', None, THRESHOLD, None,
                         f'too short: needs at least {2 * L} samples', REFERENCE)
    if _robust_std(np.diff(pv)) <= 0.0:
        return Signature('slip_events', None, THRESHOLD, None,
                         'PV does not vary: nothing to see a slip in', REFERENCE)
    jumps = candidate_jumps(pv)
    op_noise = _robust_std(np.diff(op)) / np.sqrt(2.0)
    events, rejected = [], 0
    for k, z, step in jumps:
        ok, facts = classify(op, pv, sp, k, step, op_noise)
        if ok:
            events.append({'t': float(k * sample_time), 'z': round(z, 2),
                           'pv_step': step, **facts})
        else:
            rejected += 1
    n = len(events)
    flag = n >= THRESHOLD
    if flag:
        why = found_text(n, events[0])
    else:
        why = (f'no slip event among {len(jumps)} PV jumps'
               + (' (each was a set-point response, moved away from the set point, or '
                  'followed OP)' if jumps else ''))
    return Signature('slip_events', float(n), THRESHOLD, bool(flag), why, REFERENCE,
                     {'events': events[:10], 'jumps': len(jumps), 'rejected_jumps': rejected,
                      'window': W, 'span': L, 'z_min': Z_MIN},
                     {'event_samples': np.array([int(round(e['t'] / sample_time))
                                                 for e in events], dtype=int)})
