"""
MV that runs ahead of OP: a clock's doing, never a valve's.

A valve moves after its command, so a reading that follows OP *before* OP
moves says that the two are stamped on different clocks (or OP is logged
late).  No chain stage can model it (a dead time is at least 0), so a fit
of the early reading reaches for whatever else lowers its error, typically
a positioner calibration, and names it.  Here OP is read ahead by whole
samples, doubling, while the chain refitted to it (the valve without friction,
or the stiction chain where that fits better) beats the one fitted to OP as
recorded on the fitted part and held out; the chain's own dead time then
places the lead to a fraction of a sample.  A screen comes first: the chain
as fitted, a sample ahead, must fit better, so a record without a lead costs
no fit (a chain with a lag is also tried with that lag a sample longer: a lag
fitted to an early reading takes in the lead).
"""

import dataclasses
from typing import Any, Callable

import numpy as np

from stiction_ros.analysis.mismatch import instrument as ins
from stiction_ros.analysis.mismatch.frictionless import fit_frictionless

# The longest lead looked for, in samples.
MAX_LEAD = 16
# A lead under this many samples is within what the fit's dead time places at all; the
# screen below, a whole sample ahead, passes leads of about one sample or more.
MIN_LEAD = 0.5


def find_lead(rec: Any, full: ins.ChainFit, sticky: ins.ChainFit,
              test: Callable[[Any, np.ndarray, np.ndarray, int], dict]) -> dict | None:
    """
    Return the lead of MV over OP (``samples``, ``s``, the ``test`` that found it), or None.

    ``rec`` is the record as the tests see it (``decide.Rec``); ``full`` and
    ``sticky`` the valve without friction and with stiction fitted to OP as
    recorded (the better on the fitted part is the one read ahead: a sticky
    valve's misfit without friction would hide the lead); ``test(rec,
    e_simple, e_rich, extra parameters)`` the comparison every stage passes
    (fitted part and held out).
    """
    e_full, e_sticky = rec.errors(full), rec.errors(sticky)
    f = rec.fit_idx
    use_sticky = np.nansum(e_sticky[f] ** 2) < np.nansum(e_full[f] ** 2)
    ref, e0 = (sticky, e_sticky) if use_sticky else (full, e_full)
    # A screen that costs no fit: a reading that lags OP, or that the same chain fits
    # worse with OP a sample earlier, does not lead it (most records end here).  A whole
    # sample: half of one, interpolated, moves a sticky chain's slips off the data.
    if ref.params['delay'] >= MIN_LEAD:
        return None
    # A lag fitted to an early reading is a shorter one (it takes in the lead), so the
    # same chain a sample ahead lags too little and fits worse: its lag is lengthened by
    # the sample it is read ahead (still no fit).
    longer = 'tau' if ref.params['tau'] >= ref.params['tau2'] else 'tau2'
    screens = [ref]
    if ref.params[longer] >= MIN_LEAD:
        screens.append(dataclasses.replace(
            ref, params={**ref.params, longer: ref.params[longer] + 1.0}))
    op_1 = ins.shift(rec.op, -1.0, rec.segments)
    if not any(np.nansum((rec.read(ins.chain_output(op_1, rec.mv, rec.segments, c))
                          - rec.mv)[f] ** 2) < np.nansum(e0[f] ** 2) for c in screens):
        return None
    tried: dict[int, dict] = {}

    def refit(advance: int) -> tuple[dict, float]:
        # OP read ``advance`` samples ahead, the chain fitted again; the lead it reads.
        op_a = ins.shift(rec.op, -float(advance), rec.segments)
        hint = fit_frictionless(op_a, rec.mv, rec.fit_segs, rec.sample_time)
        fit = (ins.fit_friction(op_a, rec.mv, rec.fit_segs, rec.sample_time, 'stiction',
                                hint=hint) if use_sticky else hint)
        e_a = rec.read(ins.chain_output(op_a, rec.mv, rec.segments, fit)) - rec.mv
        result = test(rec, e0, e_a, 1)
        if result['wins']:
            tried[advance] = {'samples': advance - float(fit.params['delay']), 'test': result,
                              'at_least': False, 'sse': float(np.nansum(e_a[f] ** 2))}
        return result, float(fit.params['delay'])

    advance = 1
    while advance <= MAX_LEAD:
        result, delay = refit(advance)
        if not result['wins']:
            break
        if delay >= MIN_LEAD:
            # Read further ahead than MV runs: the fit put a dead time back.  The lead it
            # reads, in whole samples, is fitted too: a lead of 5 lies between 4 and 8.
            between = int(round(advance - delay))
            if between >= 1 and between not in tried:
                refit(between)
            break
        advance *= 2
    else:
        if tried:
            tried[max(tried)]['at_least'] = True    # still ahead at the longest lead looked for
    # Past the lead the fit worsens, whatever it still gains on OP as recorded: the best
    # fit on the fitted part places it.
    best = min(tried.values(), key=lambda b: b['sse'], default=None)
    if best is None or best['samples'] < MIN_LEAD:
        return None
    del best['sse']
    best['samples'] = round(best['samples'], 2)
    best['s'] = round(best['samples'] * rec.sample_time, 6)
    return best


def lead_effect(lead: dict) -> dict:
    """Return the lead as a named effect of ``--explain``."""
    s, n = lead['s'], lead['samples']
    least = 'at least ' if lead.get('at_least') else ''
    return {'id': 'clock_skew', 'size': s, 'unit': 's', 'uncertainty': None,
            'sentence': (f'The position moves {least}{s:.3g} s ({n:.3g} '
                         f'sample{"" if n == 1 else "s"}) before OP commands it, which no '
                         'valve can: OP and MV are stamped on different clocks or OP is '
                         'logged late, or the OP recorded is not what drove the valve (a '
                         'controller tracking in manual, an override or selector, OP '
                         'compressed by the historian). The rest is read with OP that much '
                         'earlier; check the time stamps of the two tags and what drove the '
                         'valve.'),
            'params': {'mv_lead_s': s}}
