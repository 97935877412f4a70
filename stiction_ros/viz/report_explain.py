"""
The ``--explain`` sections of the HTML report: the answer, then every decision and its rule.

Each test is shown with the rule that decides it, stated from the constants
the analysis itself uses (:mod:`stiction_ros.analysis.mismatch`), so the page
cannot drift from the code: why friction is claimed, why it is stiction,
which candidate is named, and why a candidate that passes its threshold can
still not be the one named.
"""

from __future__ import annotations

from stiction_ros.analysis.mismatch.decide import MIN_J
from stiction_ros.analysis.mismatch.explain import ACF_MARGIN
from stiction_ros.analysis.mismatch.stats import chi2_999, P_HELDOUT
from stiction_ros.viz.html_parts import clean, e, ident, MSE_UNIT, num, param_name, \
    PARAM_UNITS, params, pct, rule, table

# Which chain stage each named effect stands for, to find the chain candidate kept.
STAGE_EFFECTS = {'dead_time': 'delay', 'positioner_calibration': 'offset'}
STAGE_WORDS = {'delay': 'dead time', 'offset': 'offset', 'gain': 'gain'}


def _answer(report: dict) -> list:
    m, b, h = report['mismatch'], report['baseline'], report.get('holdout', {})
    if m['effect'] in ('none', 'unexplained'):
        how = ('1 minus the best candidate&rsquo;s score (LR / threshold, below): how far '
               'the best candidate stayed below its threshold')
    else:
        how = ('1 minus threshold / LR of the named candidate (below): how far its '
               'likelihood ratio passed its threshold')
    out = ['<h2>Why the model misses (--explain)</h2>',
           f'<p class="verdict">{e(m["effect"])} &mdash; confidence '
           f'{num(m["confidence"], 3)} (0 to 1)</p>', f'<p>{clean(m["explanation"])}</p>',
           rule(f'Confidence is {how}.')]
    if m['effect'] == 'unexplained':
        out.append(rule(f'&ldquo;unexplained&rdquo;: no candidate passed, and the plain '
                        f'model&rsquo;s residual has a lag-1 autocorrelation above every '
                        f'effect-free replicate&rsquo;s by more than {num(ACF_MARGIN)}.'))
    if m.get('note'):
        out.append(f'<p>Note: {clean(m["note"])}</p>')
    out.append(table(['model', 'parameters', f'MSE fitted part ({MSE_UNIT})',
                      f'MSE held-out part ({MSE_UNIT})'], [
        [f'{e(b["model"])} (plain)', params({'S': b['S'], 'J': b['J']}),
         num(b['mse_fit']), num(b['mse_holdout'])],
        [e(m['model']['name']), params(m['model']['params']),
         num(m['mse_fit']), num(m['mse_holdout'])]]))
    out.append(f'<p>Held out: samples from {num(h.get("first_sample"))} on (t &ge; '
               f'{num(h.get("t_start"), unit="s")}, {num(h.get("holdout_samples"))} samples, '
               f'{pct(h.get("share"))} of the record), used for nothing but the held-out '
               'MSE and the held-out tests of friction below.</p>')
    return out


def _effects(m: dict) -> list:
    rows = []
    for x in m.get('effects', []):
        unit = x.get('unit') or ''
        # A friction effect's "unit" is the name of its first parameter.
        what = param_name(unit) if unit in PARAM_UNITS or '_' in unit else ''
        unit = PARAM_UNITS.get(unit, unit if unit in ('%', 's', '%/s') else '')
        rows.append([ident(x['id']), e(what) or '-', num(x.get('size'), unit=unit),
                     num(x.get('uncertainty'), unit=unit), clean(x['sentence'])])
    if not rows:
        return []
    return ['<h3>Effects kept</h3>',
            table(['effect', 'size of', 'size', 'standard error', 'what it means'], rows)]


def _chains(report: dict) -> list:
    chains = [('no friction', report.get('frictionless'))] + list(
        report.get('chains', {}).items())
    rows = [[e(name), num(c['S'], unit='%'), num(c['J'], unit='%'),
             num(c['dead_time_s'], unit='s'), num(c['lag_s'], unit='s'),
             num(c['offset'], unit='%'), num(c['gain']), e(', '.join(c['stages']) or '-'),
             num(c['mse_fit']), num(c['mse_holdout'])] for name, c in chains if c]
    if not rows:
        return []
    return ['<h3>The valve through its instruments: best chain of each kind</h3>',
            table(['friction', 'S', 'J', 'dead time', 'lag', 'offset', 'gain (-)',
                   'stages kept', f'MSE fit ({MSE_UNIT})', f'MSE held-out ({MSE_UNIT})'], rows)]


def _friction_tests(report: dict) -> list:
    tests = report.get('friction_tests', {})
    if not tests:
        return []
    rows = [[e(k.replace('_', ' ')), num(v.get('lr')), num(v.get('threshold')),
             num(v.get('rho'), 3), pct(v.get('heldout_gain')), num(v.get('heldout_p'), 3),
             num(v.get('J'), unit='%'), 'yes' if v['wins'] else 'no']
            for k, v in tests.items()]
    return [rule(
        'Friction is claimed only when a friction chain beats the best chain without '
        'friction twice: on the fitted part its likelihood ratio LR (counted on the '
        'residual&rsquo;s effective sample size n (1 - r1) / (1 + r1), r1 its lag-1 '
        'autocorrelation) exceeds the chi-square 99.9 % point for the parameters it adds '
        '(the threshold), and on the held-out part its MSE is lower with p &lt; '
        f'{num(P_HELDOUT)} (paired block bootstrap of the squared errors). It is '
        'stiction when, in addition, the slip jump J earns its place against the backlash '
        f'chain on the fitted part (LR above the threshold and J &ge; {num(MIN_J)} %, or '
        'an effect that makes the slip itself; its held-out columns are shown but do not '
        'decide) and the final model still beats the chain without friction held out.'),
        table(['test', 'LR', 'threshold', 'residual lag-1 r1', 'held-out MSE reduction',
               'held-out p', 'J', 'passes'], rows)]


def _named(m: dict) -> set:
    return {x['id'] for x in m.get('effects', [])}


def _penalised(c: dict, k: int) -> float:
    # The scale candidates of different sizes compete on: LR less its chi-square point.
    return c['lr'] - chi2_999(k)


def _chain_decisions(report: dict) -> list:
    cands = report['chain_candidates']
    named = _named(report['mismatch'])
    kept = {STAGE_EFFECTS[i] for i in named if i in STAGE_EFFECTS}
    passing = [c for c in cands if c['score'] > 1.0]
    best = max(passing, key=lambda c: _penalised(c, len(c['stages'])), default=None)
    # Without a stage kept the candidates are those of the one search, so the friction
    # effect the stages lost to is in the report.
    effects = [c for c in report.get('candidates', []) if c['score'] > 1.0]
    rival = max(effects, key=lambda c: _penalised(c, len(c['params'])), default=None)
    out = []
    for c in cands:
        k = len(c['stages'])
        if c['score'] > 1.0 and set(c['stages']) - {'gain'} == kept:
            why = ('kept: passes, and its LR less the chi-square point of its parameters '
                   'beats every passing friction effect&rsquo;s; the friction effects were '
                   'then searched again with it undone')
        elif c['score'] > 1.0 and c is not best:
            why = (f'passes, not kept: {e(", ".join(STAGE_WORDS[s] for s in best["stages"]))} '
                   'has the larger LR less chi-square point')
        elif c['score'] > 1.0 and rival is not None and not kept:
            why = (f'passes, not kept: its LR less chi-square point '
                   f'({num(_penalised(c, k))}) is below that of {e(rival["effect"])} '
                   f'({num(_penalised(rival, len(rival["params"])))})')
        elif c['score'] > 1.0:
            why = 'passes, not kept: a friction effect has the larger LR less chi-square point'
        elif c['lr'] > c['threshold']:
            why = 'too small to name (a dead time under a sample, a tiny offset): score 0'
        else:
            why = 'below its threshold'
        out.append(why)
    return out


def _chain_candidates(report: dict) -> list:
    cands = report.get('chain_candidates') or []
    if not cands:
        return []
    rows = [[e(', '.join(STAGE_WORDS[s] for s in c['stages'])),
             num(c['dead_time_s'], unit='s'), num(c['offset'], unit='%'), num(c['gain']),
             num(c['S'], unit='%'), num(c['J'], unit='%'), num(c['lr']), num(c['threshold']),
             num(c['score'], 3), why] for c, why in zip(cands, _chain_decisions(report))]
    return ['<h3>Dead time and calibration against the friction effects</h3>',
            rule('A dead time or a positioner calibration can explain what looks like '
                 'friction physics. Each is scored like the friction effects below (LR / '
                 'threshold); its threshold takes the effect-free replicates&rsquo; LR of the '
                 'friction effects it resembles (the lags for a dead time; asymmetric and '
                 'position-dependent friction for a calibration). Among all candidates that '
                 'pass, the one with the largest LR less the chi-square 99.9 % point of the '
                 'parameters it adds is taken first.'),
            table(['stages', 'dead time', 'offset', 'gain (-)', 'S', 'J', 'LR', 'threshold',
                   'score', 'decision'], rows)]


def _top(cands: list) -> dict | None:
    return max((c for c in cands if c['score'] > 1.0), key=lambda c: c['score'], default=None)


def candidate_decisions(report: dict) -> dict:
    """Return, per friction candidate, why it was or was not named (HTML)."""
    m, cands = report['mismatch'], report.get('candidates', [])
    top = _top(cands)
    out = {}
    # Beside a dead time or calibration the answer names that; the friction search's own
    # answer is what decides its candidates.
    friction_answer = m.get('friction_effect', m['effect'])
    for c in cands:
        if c['score'] > 1.0 and friction_answer in ('none', 'unexplained'):
            # Passing is not enough where the plain fit leaves nothing to explain; the
            # answer's sentence says why.
            why = 'passes, not named: nothing is named (the answer above says why)'
        elif c is top and c['effect'] in _named(m):
            why = 'named: the highest score of those that pass'
        elif c is top:
            why = ('highest score, but a lag under one sample beside the dead time kept is '
                   'that dead time&rsquo;s fraction of a sample: not a second effect')
        elif c['score'] > 1.0:
            why = f'passes, not named: {e(top["effect"])} scores higher'
        else:
            why = 'below its threshold'
        out[c['effect']] = why
    return out


def _listed(cands: list) -> str:
    return ', '.join(f'{e(c["effect"])} ({num(c["score"], 3)})' for c in cands)


def _passed_over(cands: list, m: dict) -> str:
    # The sentence a reader of "> 1 passes" needs where a candidate passed, unnamed.
    top = _top(cands)
    if top is not None and m['effect'] in ('none', 'unexplained'):
        passing = [c for c in cands if c['score'] > 1.0]
        return (f' Here {_listed(passing)} {"pass" if len(passing) > 1 else "passes"}, yet '
                f'nothing is named: {clean(m["explanation"])}')
    others = [c for c in cands if c['score'] > 1.0 and c is not top]
    if not others:
        return ''
    listed = _listed(others)
    return (f' Here {listed} {"pass" if len(others) > 1 else "passes"} as well, but '
            f'{e(top["effect"])} scores higher ({num(top["score"], 3)}). Every candidate was '
            'fitted alone on the plain model, as an alternative to the one named, and none '
            'was tested on top of it: one friction effect is named per search (greedy '
            'forward selection), so a second passing score does not show a second effect.')


def _candidates(report: dict) -> list:
    cands = report.get('candidates', [])
    if not cands:
        return ['<h3>Friction candidates</h3><p>None were fitted: no stiction is claimed, so '
                'there is no friction model to extend; the figure compares the held-out MSE '
                'of each kind of valve instead.</p>']
    m = report['mismatch']
    boot = m.get('bootstrap', {})
    worst = boot.get('largest_lr', {})
    margin = boot.get('margin', 2.0)
    why = candidate_decisions(report)
    rows = [[ident(c['effect']), params(c['params']),
             f'{num(c["S"], unit="%")}, {num(c["J"], unit="%")}', num(c['mse_fit']),
             num(c['mse_holdout']), num(c.get('lr')), num(worst.get(c['effect'])),
             num(c.get('threshold')), num(c['score'], 3), why[c['effect']]] for c in cands]
    n = report.get('holdout', {}).get('fit_samples')
    replicates = boot.get('replicates')
    reps = (f'{num(replicates)} effect-free bootstrap replicates' if replicates
            else 'the effect-free bootstrap replicates of the first search')
    return [
        '<h3>Candidates side by side (friction effects, each nesting the plain model)</h3>',
        rule(
            'Each candidate adds one effect to the plain Kano model and is refitted on the '
            f'fitted part ({num(n)} samples). Its likelihood ratio is LR = N ln(MSE<sub>plain'
            '</sub> / MSE<sub>candidate</sub>). Its threshold is the larger of the '
            f'chi-square 99.9 % point for the parameters it adds ({num(chi2_999(1))} for one, '
            f'{num(chi2_999(2))} for two) and {num(margin)} times the largest LR that '
            f'candidate reached on {reps} (the plain model run on the recorded OP with noise '
            'of the fitted size, everything refitted). Score = LR / threshold: a candidate '
            'passes when its score is above 1, and of those that pass only the one with the '
            f'highest score is named.{_passed_over(cands, m)} The held-out part decides '
            'nothing here; its MSE only shows whether the named model also predicts '
            'better.'),
        table(['effect', 'parameters', 'S, J', f'MSE fit ({MSE_UNIT})',
               f'MSE held-out ({MSE_UNIT})', 'LR', 'largest LR, effect-free',
               'threshold', 'score (LR / threshold)', 'decision'], rows)]


def _where(m: dict) -> list:
    out = []
    if m.get('regions'):
        rows = [[num(r['t_start'], unit='s'), num(r['t_end'], unit='s'), e(r['regime']),
                 pct(r['residual_share'])] for r in m['regions']]
        out += ['<h3>Where the plain model misses most (fitted part)</h3>',
                table(['from', 'to', 'dominant regime', 'share of the squared residual'],
                      rows)]
    if m.get('regimes'):
        rows = [[e(r['regime']), pct(r['residual_share']), pct(r['sample_share']),
                 num(r['lift'], 3)] for r in m['regimes']]
        out += ['<h3>Residual by regime</h3>',
                table(['regime', 'share of the squared residual', 'share of the samples',
                       'lift (residual share / sample share)'], rows)]
    return out


def explain_parts(report: dict) -> list:
    """Return the HTML pieces of the ``--explain`` sections of ``report``."""
    if 'baseline' not in report:
        return ['<h2>Why the model misses (--explain)</h2>',
                f'<p class="verdict">cannot tell</p><p>'
                f'{clean(report["mismatch"]["explanation"])}</p>']
    return (_answer(report) + _effects(report['mismatch']) + _chains(report)
            + _friction_tests(report) + _chain_candidates(report) + _candidates(report)
            + _where(report['mismatch']))
