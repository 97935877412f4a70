"""
``--explain`` with a frictionless baseline: timing and instruments before friction.

The order of questions an engineer would ask of a valve that misbehaves:

1. Does a valve with *no friction at all* explain the reading, once dead
   time, lags, offset and gain, a rate limit and travel stops are allowed
   (:func:`frictionless.fit_frictionless`, stages kept by backward
   elimination, :func:`select_stages`)?
2. Does a friction chain (backlash: play without stick; or stiction) beat
   it, on the fitted part by a likelihood ratio on the residual's effective
   sample size *and* on the held-out part by a paired block bootstrap
   (:func:`compare`)?  If not, no friction is claimed.
3. If so, which physics does the friction leave out (:mod:`sticky`: the
   friction effects of EFFECTS.md against dead time and calibration), and is
   it stiction: does the final model need the slip jump J against backlash
   (:func:`j_test`), and does it still beat the frictionless chain held out?

A reading that moves in steps is compared through the same quantiser
(:class:`Rec`).  The answer names every effect kept with its size and
uncertainty.
"""

from dataclasses import dataclass
import time

import numpy as np

from stiction_ros.analysis.mismatch import explain as friction_explain
from stiction_ros.analysis.mismatch import instrument as ins
from stiction_ros.analysis.mismatch import sentences
from stiction_ros.analysis.mismatch.frictionless import fit_frictionless, stage_ok
from stiction_ros.analysis.mismatch.frictionless_report import plain_baseline, without_friction
from stiction_ros.analysis.mismatch.lead import find_lead, lead_effect
from stiction_ros.analysis.mismatch.stats import acf1, chi2_999, earns, heldout_test, \
    lr_eff, P_HELDOUT
from stiction_ros.analysis.mismatch.sticky import explain_sticky
from stiction_ros.analysis.verdict import MIN_J

STICK_SLIP_EFFECTS = ('dwell_time_breakaway', 'stribeck_stick_slip')
PLAUSIBLE = ins.PLAUSIBLE


@dataclass
class Rec:
    """One record as every test sees it: signals, parts, and the reading's resolution."""

    op: np.ndarray
    mv: np.ndarray
    segments: list
    fit_segs: list
    fit_idx: np.ndarray
    hold_idx: np.ndarray
    sample_time: float
    quantum: float = 0.0
    origin: float = 0.0

    def read(self, position: np.ndarray) -> np.ndarray:
        """Return what a transmitter of the record's resolution reads for ``position``."""
        if self.quantum <= 0.0:
            return position
        return self.origin + self.quantum * np.round((position - self.origin) / self.quantum)

    def errors(self, fit) -> np.ndarray:
        """Return the reading ``fit`` predicts minus the measured MV, every sample."""
        return self.read(ins.chain_output(self.op, self.mv, self.segments, fit)) - self.mv

    def mse(self, pred: np.ndarray, idx: np.ndarray) -> float:
        """Return the MSE of a predicted reading on ``idx``."""
        r = self.read(pred)[idx] - self.mv[idx]
        r = r[np.isfinite(r)]
        return float(np.mean(r * r)) if len(r) else float('nan')


def compare(rec: Rec, simple, rich) -> dict:
    """Return the fitted-part and held-out evidence that chain ``rich`` beats ``simple``."""
    e_s, e_r = rec.errors(simple), rec.errors(rich)
    return _test(rec, e_s, e_r, rich.k - simple.k)


def _test(rec, e_s, e_r, dk, strict=True):
    f = rec.fit_idx
    ok = np.isfinite(e_s[f]) & np.isfinite(e_r[f])
    # The richer model's residual: under the claim it is the right one, and a model
    # that leaves physics out has a structured residual that would void any test.
    rho = acf1(e_r[f][ok])
    stat = lr_eff(float(e_s[f][ok] @ e_s[f][ok]), float(e_r[f][ok] @ e_r[f][ok]),
                  int(ok.sum()), rho)
    out = {'lr': round(stat, 3), 'threshold': chi2_999(dk), 'rho': round(rho, 3)}
    wins = stat > out['threshold']
    if len(rec.hold_idx):
        h = heldout_test(e_s[rec.hold_idx], e_r[rec.hold_idx])
        out.update(heldout_gain=round(h['gain'], 4), heldout_p=h['p'])
        if strict:
            wins = wins and h['gain'] > 0 and h['p'] < P_HELDOUT
    out['wins'] = bool(wins)
    return out


def select_stages(rec: Rec, full):
    """
    Return the frictionless chain with only the stages that earn their place.

    Stages too small to name (:func:`frictionless.stage_ok`) go first, in one
    refit; then backward elimination: the stage whose removal costs least is
    dropped while it does not :func:`stats.earns` its place or is too small.
    """
    current = full
    named = tuple(c for c in full.free if stage_ok(full, c, rec.op, rec.segments))
    if named != full.free:
        current = fit_frictionless(rec.op, rec.mv, rec.fit_segs, rec.sample_time, named)
    while current.free:
        trials = []
        for name in current.free:
            free = tuple(c for c in current.free if c != name and not
                         (name == 'tau' and c == 'tau2'))
            reduced = fit_frictionless(rec.op, rec.mv, rec.fit_segs, rec.sample_time, free)
            c = compare(rec, reduced, current)
            ok = earns(c) and stage_ok(current, name, rec.op, rec.segments)
            trials.append((ok, c['lr'], reduced))
        weakest = min(trials, key=lambda tr: (tr[0], tr[1]))
        if weakest[0]:
            break
        current = weakest[2]
    return current


def select_friction_stages(rec: Rec, fit, full):
    """Drop the lag, dead time or calibration of a friction chain where they do not earn it."""
    current = fit
    for drop in (('tau',), ('delay',), ('offset', 'gain')):
        free = tuple(c for c in current.free if c not in drop)
        if free == current.free:
            continue
        reduced = ins.fit_friction(rec.op, rec.mv, rec.fit_segs, rec.sample_time,
                                   current.friction, free, hint=full,
                                   delay=current.params['delay'] if 'delay' in free else None)
        size_ok = any(abs(current.params[c] - ins.NULL[c]) >= PLAUSIBLE[c] for c in drop)
        if not (size_ok and earns(compare(rec, reduced, current))):
            current = reduced
    return current


def j_test(rec: Rec, e_backlash: np.ndarray, mv_model: np.ndarray, dk: int, J: float,
           stick_slip: bool = False) -> dict:
    """
    Return whether a stiction model's slip jump is real, against the backlash chain.

    Decided like the friction effects, on the fitted part alone: a valve
    whose friction has more physics than Kano's (a drift, pre-sliding creep)
    fits no lag-and-play chain well out of sample, so the held-out part
    cannot tell J from no J.  ``stick_slip``: the model's friction effect
    makes the slip itself (dwell-time or velocity-weakening static friction).
    """
    out = _test(rec, e_backlash, rec.read(mv_model) - rec.mv, dk, strict=False)
    out['J'] = J
    out['wins'] = bool(out['wins'] and (J >= MIN_J or stick_slip))
    return out


def final_test(rec: Rec, frictionless, mv_final: np.ndarray) -> dict:
    """Return whether the final friction model beats the frictionless chain held out."""
    if not len(rec.hold_idx):
        return {'wins': True, 'heldout_p': None, 'heldout_gain': None}
    e_f = rec.errors(frictionless)[rec.hold_idx]
    h = heldout_test(e_f, (rec.read(mv_final) - rec.mv)[rec.hold_idx])
    return {'heldout_gain': round(h['gain'], 4), 'heldout_p': h['p'],
            'wins': bool(h['gain'] > 0 and h['p'] < P_HELDOUT)}


def chain_summary(rec: Rec, fit) -> dict:
    """Return a chain's report entry: friction, S, J, stages in seconds and %, MSEs."""
    pred = ins.chain_output(rec.op, rec.mv, rec.segments, fit)
    p, ts = fit.params, rec.sample_time
    return {'friction': fit.friction, 'S': round(fit.S, 4), 'J': round(fit.J, 4),
            'dead_time_s': round(p['delay'] * ts, 4), 'lag_s': round(p['tau'] * ts, 4),
            'lag_before_friction': bool(p.get('lag_before', 0.0)),
            'lag2_s': round(p['tau2'] * ts, 4),
            'offset': round(p['offset'], 4), 'gain': round(p['gain'], 5),
            'stages': list(fit.free), 'parameters': fit.k,
            'mse_fit': rec.mse(pred, rec.fit_idx), 'mse_holdout': rec.mse(pred, rec.hold_idx)}


def explain_record(t, op, mv, segments, sample_time, holdout=friction_explain.HOLDOUT,
                   reps=friction_explain.BOOTSTRAP, seed=0, progress=None, jobs=1):
    """Return the ``--explain`` report sections and figure arrays, frictionless baseline first."""
    t0 = time.perf_counter()
    op = np.asarray(op, dtype=np.float64)
    mv = np.asarray(mv, dtype=np.float64)
    if not 0.0 <= holdout < 0.9:
        raise ValueError(f'--holdout must be in [0, 0.9), got {holdout}')
    n_fit = int(round(len(op) * (1.0 - holdout)))
    fit_segs = friction_explain.split_segments(segments, n_fit)
    if not fit_segs:
        raise ValueError('no valid samples before the held-out part to fit on')
    say = progress or (lambda msg: None)
    all_idx = ins.indices(segments)
    rec = Rec(op, mv, segments, fit_segs, ins.indices(fit_segs), all_idx[all_idx >= n_fit],
              sample_time)
    rec.quantum = ins.quantum(mv, rec.fit_idx)
    if rec.quantum > 0.0:
        rec.origin = float(np.median(np.mod(mv[rec.fit_idx], rec.quantum)))
    say('fitting the best valve without friction (dead time, lags, offset, gain, rate '
        'limit, travel stops)')
    full = fit_frictionless(op, mv, fit_segs, sample_time)
    say('fitting backlash and stiction with dead time, lag and calibration')
    sticky = ins.fit_friction(op, mv, fit_segs, sample_time, 'stiction', hint=full)
    lead = find_lead(rec, full, sticky, _test)
    op_recorded = op
    if lead is not None:
        say(f'MV runs {lead["s"]:.3g} s ahead of OP: reading OP that much earlier')
        op = ins.shift(op, -lead['samples'], segments)
        rec.op = op
        full = fit_frictionless(op, mv, fit_segs, sample_time)
        sticky = ins.fit_friction(op, mv, fit_segs, sample_time, 'stiction', hint=full)
    frictionless = select_stages(rec, full)
    backlash = ins.fit_friction(op, mv, fit_segs, sample_time, 'backlash', hint=full)
    tests = {'stiction_vs_frictionless': compare(rec, frictionless, sticky),
             'backlash_vs_frictionless': compare(rec, frictionless, backlash)}
    sections = {'frictionless': chain_summary(rec, frictionless),
                'chains': {c.friction: chain_summary(rec, c) for c in (backlash, sticky)},
                'friction_tests': tests}
    report, winner = None, frictionless
    if tests['stiction_vs_frictionless']['wins'] or tests['backlash_vs_frictionless']['wins']:
        # Friction of some kind: its physics first, then whether it is stiction.
        report, arrays, effects = explain_sticky(t, op, mv, segments, sample_time, holdout,
                                                 reps, seed, say, jobs, full)
        if _is_stiction(rec, report, arrays, effects, backlash, sticky, frictionless, tests):
            winner = sticky
            _name_what_was_found(report['mismatch'], report.get('chain_kept'))
        else:
            report = None
            if tests['backlash_vs_frictionless']['wins'] and backlash.S >= PLAUSIBLE['offset']:
                say('backlash found; keeping the dead time, lag and calibration it needs')
                winner = select_friction_stages(rec, backlash, full)
    if report is None:
        report, arrays = _chain_answer(t, rec, winner, n_fit, holdout)
    report.update(sections)
    arrays['mv_frictionless'] = ins.chain_output(op, mv, segments, frictionless)
    m = report['mismatch']
    m['friction'] = winner.friction == 'stiction'
    m['friction_kind'] = winner.friction
    if lead is not None:
        # Every section reads OP a lead earlier (the plain model, where it misses, the
        # chains); what the plain model makes of OP as recorded is the lead's own figure.
        as_recorded, _, _ = plain_baseline(op_recorded, mv, segments, sample_time, n_fit)
        _put_lead_first(report, lead, as_recorded)
        report['series']['op_recorded'] = friction_explain._json(op_recorded)
    f_hold = sections['frictionless']['mse_holdout']
    if m['friction'] and len(rec.hold_idx) and m['mse_holdout'] > f_hold:
        m['note'] = (f'the friction model is worse on held-out data ({m["mse_holdout"]:.4g}) '
                     f'than the best valve without friction ({f_hold:.4g})')
    report['explain_seconds'] = round(time.perf_counter() - t0, 3)
    return report, arrays


def _is_stiction(rec, report, arrays, effects, backlash, sticky, frictionless, tests):
    """Test the slip jump and the final model held out; complete the report's effects."""
    m = report['mismatch']
    m['effects'] = effects + sentences.chain_effects(
        ins.ChainFit('stiction', dict(ins.NULL), 0.0, 0.0, 0.0, 1, ()), {}, rec.sample_time,
        rec.quantum)
    e_back = rec.errors(backlash)
    # The slip jump, twice: the stiction chain against the backlash chain (the same
    # stages), and the final model (its friction effect in) against that chain.
    k_final = len(m['model']['params']) + sum(len(e['params']) for e in effects
                                              if e['id'] in sentences.INSTRUMENT_IDS)
    j_chain = j_test(rec, e_back, ins.chain_output(rec.op, rec.mv, rec.segments, sticky),
                     sticky.k - backlash.k, sticky.J)
    # Static friction that grows with rest time, or falls with speed, is itself a
    # stick-slip mechanism: the slip it makes needs no J in Kano's sense.
    j_final = j_test(rec, e_back, arrays['mv_explained'], k_final - backlash.k,
                     float(m['model']['params'].get('J', 0.0)),
                     stick_slip=m['effect'] in STICK_SLIP_EFFECTS)
    tests['stiction_vs_backlash'] = max((j_chain, j_final), key=lambda j: (j['wins'], j['lr']))
    tests['final_vs_frictionless'] = final_test(rec, frictionless, arrays['mv_explained'])
    return tests['stiction_vs_backlash']['wins'] and tests['final_vs_frictionless']['wins']


def _put_lead_first(report, lead, as_recorded):
    # Everything after was fitted to OP read ahead: the lead is the first thing found.
    m = report['mismatch']
    effect = lead_effect(lead)
    m['effects'] = [effect] + m['effects']
    test = lead['test']
    # 1 - threshold/LR, as a stage's; beside another effect, the less sure of the two.
    sure = round(max(0.0, 1.0 - test['threshold'] / test['lr']), 3) if test['lr'] > 0 else 0.0
    alone = m['effect'] in ('none', 'unexplained')
    m['confidence'] = sure if alone else min(sure, m['confidence'])
    m['explanation'] = (effect['sentence'] if alone
                        else f'{effect["sentence"]} {m["explanation"]}')
    m['effect'] = m['effects'][0]['id']
    m['model']['params']['mv_lead_s'] = lead['s']
    m['model']['name'] = f'{m["model"]["name"]}+clock_skew'
    report['clock_skew'] = {'mv_lead_s': lead['s'], 'samples': lead['samples'],
                            'at_least': lead['at_least'],
                            'plain_mse_holdout_as_recorded': as_recorded['mse_holdout'],
                            'plain_mse_fit_as_recorded': as_recorded['mse_fit'],
                            **{k: test[k] for k in ('lr', 'threshold', 'heldout_gain',
                                                    'heldout_p') if k in test}}


def _name_what_was_found(m, kept):
    # The friction physics was searched after the dead time or calibration the valve
    # needs was put in; that search's 'none' means no friction effect is missing, not
    # that nothing is: the answer names what was found, as the frictionless one does,
    # with the confidence of the stages kept (1 - threshold/LR, as a friction effect's).
    m['friction_effect'] = m['effect']
    if m['effect'] in ('none', 'unexplained') and m['effects']:
        m['effect'] = m['effects'][0]['id']
        m['explanation'] = ' '.join(e['sentence'] for e in m['effects'])
        if kept and kept.get('score'):
            m['confidence'] = round(min(max(1.0 - 1.0 / kept['score'], 0.0), 1.0), 3)
        elif m['effect'] == 'quantisation':
            # Read from the reading's grid of values, not a test: as the answer without
            # friction gives it.
            m['confidence'] = 1.0


def _chain_answer(t, rec, winner, n_fit, holdout):
    """Return the report of a frictionless or backlash answer, with sizes and errors."""
    rho = acf1(rec.errors(winner)[rec.fit_idx])
    se = ins.standard_errors(rec.op, rec.mv, rec.fit_segs, winner, rho)
    effects = sentences.chain_effects(winner, se, rec.sample_time, rec.quantum)
    # The prediction is what the transmitter would read, steps included.
    mv_chain = rec.read(ins.chain_output(rec.op, rec.mv, rec.segments, winner))
    report, arrays = without_friction(t, rec.op, rec.mv, rec.segments, rec.sample_time, winner,
                                      mv_chain, n_fit, holdout, effects)
    return report, arrays


__all__ = ['compare', 'explain_record', 'final_test', 'j_test', 'Rec',
           'select_friction_stages', 'select_stages']
