"""
A single self-contained HTML page of the analyzer's report, figures embedded.

The page shows the verdict first, with the rule that decides it, then the
evidence an engineer would check by eye: the fits (MSE of eq. 2.8), the
oscillation, each signature against its threshold, the figures, and what was
excluded from the record and why.  Every quantity carries its unit and no
section is a dump of the JSON report (``--json`` has that).
"""

from __future__ import annotations

from datetime import datetime, timezone
from pathlib import Path

from stiction_ros import __version__
from stiction_ros.analysis.detection.detect import BAND as DETECTOR_BAND, probability_text
from stiction_ros.analysis.judged import judged_text
from stiction_ros.analysis.mismatch.sentences import explained_size
from stiction_ros.analysis.signature_vote import THRESHOLD as VOTE_THRESHOLD
from stiction_ros.analysis.verdict import MIN_IMPROVEMENT, MIN_J, MIN_S, MIN_SLIPS
from stiction_ros.viz.html_parts import clean, e, figure, INPUT_META, MSE_UNIT, num, pct, \
    PV_UNITS, rule, span, STYLE, table
from stiction_ros.viz.report_explain import explain_parts
from stiction_ros.viz.signature_words import SIGNATURES


CAPTIONS = {
    'trends': 'Time trends. Top: OP and, where recorded, the measured MV and each '
              f'model&rsquo;s MV, in % of travel. Bottom: PV and SP in {PV_UNITS} (the '
              'recording does not state them). '
              'Grey bands: excluded stretches. Orange bands and dotted red lines: the '
              'stuck periods and slips the detector found (the first 20 of each), at the times '
              'its evidence names.',
    'maps': 'Left: MV against OP (both in %), with each model and the ideal valve (MV = OP). '
            f'Right: PV ({PV_UNITS}) against OP (%).',
    # The same figure with one panel, when the record has MV or PV only.
    'maps_mv': 'MV against OP (both in %), with each model and the ideal valve (MV = OP).',
    'maps_pv': f'PV ({PV_UNITS}) against OP (%).',
    'mismatch': '--explain: the residual MV - model (%) over time with the worst stretches '
                'shaded and the start of the held-out part; the plain model&rsquo;s error '
                'after each breakaway against rest time, position and time (with fewer than '
                'five breakaways, a note instead); the MV-OP map '
                'before and after; and the candidates&rsquo; scores (LR / threshold, see '
                'the rule above the candidates table) or, without friction, the held-out '
                f'MSE ({MSE_UNIT}) of each kind of valve.',
    'signatures': 'One panel per signature that has a picture: in its title what the value '
                  'measures, the value against its threshold, the verdict and, when '
                  'undetermined, why; the signatures without a picture share one text panel. '
                  f'Times count from the record&rsquo;s start. PV is in {PV_UNITS}, OP in %.',
}
LANDSCAPE = ('MSE of eq. 2.8 around the identified (S, J), both in % (red +). Colour: '
             'log10(MSE / MSE<sub>min</sub>), so 0 is the best point and 1 is ten times its '
             'MSE, whatever the size of MSE<sub>min</sub> (given on the colour bar, in '
             f'{MSE_UNIT}); for an exact fit (MSE 0, to 10<sup>-12</sup>) the colours count '
             'from the best cell off it, and the exact cells are 0. White line: the 95 % '
             'region of (S, J). Grey, if any: MSE above '
             'the ceiling named in the title (the larger of 10<sup>4</sup> MSE<sub>min'
             '</sub> and ten times the variance of MV, the MSE of a valve frozen at its mean), '
             'not computed further.')


def _decision(flag: bool | None) -> str:
    if flag is None:
        return '<span class="und">undetermined</span>'
    return '<span class="yes">stiction</span>' if flag else '<span class="no">no stiction</span>'


def _verdict(report: dict) -> list:
    st = report.get('stiction', {})
    verdict = ('STICTION DETECTED' if st.get('detected')
               else 'no stiction detected' if st.get('detected') is False else 'cannot tell')
    if report.get('fits') and st.get('cannot_tell') == 'mv_still':
        # The fits' score then measures how far OP travelled from a still MV, not friction.
        strength = (f'MV never moved, so the fits cannot decide (their score, '
                    f'{num(st.get("score"), 3)}, measures OP&rsquo;s travel, not friction)')
        how = ''
    elif report.get('fits'):
        strength = f'score {num(st.get("score"), 3)} (0 = none, 1 = certain)'
        how = (f'With the valve position (MV) the fits decide: stiction when the 95 % range '
               f'of the best model&rsquo;s S starts at or above {num(MIN_S)} % and its MSE is '
               f'at least {pct(MIN_IMPROVEMENT)} below that of an ideal valve (MV = OP), or '
               'removes that share of what the ideal valve leaves above MV&rsquo;s noise '
               '(where that excess is larger than the noise estimate&rsquo;s error), and '
               f'the 95 % range of its slip jump J starts at or above {num(MIN_J)} % and at '
               'OP&rsquo;s move in one sample while the valve moves (play taken up between '
               'two samples shows as a jump that size). Such a '
               'band without a jump is play (a deadband or backlash): no stiction where J '
               'stays under that, cannot tell where its range straddles it. Stick-slip '
               'that fits MV to within 1.5 times its own noise variance but removes less '
               'than that share of the MSE (the noise is most of it) is cannot tell too, '
               f'and so is a fit whose valve starts to move fewer than {MIN_SLIPS} times (a '
               'constant identifies no band or jump). '
               'A claim must also beat the best valve without friction (a dead time, a rate '
               'limit, a lag, a travel stop and a calibration within gain 0.8-1.25 and 10 % at '
               'mid-span, fitted to MV): '
               'stick-slip, given such a calibration too, must remove that share of its MSE '
               'or of its part above the noise, else the answer is no stiction where that '
               'valve fits MV to within 1.5 times its noise variance, at least as well as '
               'stick-slip and leaving at most half of what stick-slip leaves above the '
               'noise, and cannot tell where it does not. A band without a clear slip jump '
               '(play, or a jump too small to tell) is no stiction too where that valve fits '
               'MV to within 1.5 times its noise variance and at least as well. '
               'Where the fits find no band and an ideal valve leaves more than '
               '1.5 times the noise variance, no stiction needs that valve to explain MV the '
               'same way, and at least as well as stick-slip with a clear band and jump; else '
               'cannot tell. Where the plain fits show no stiction, stick-slip is fitted '
               'again behind that valve&rsquo;s dead time and calibration: stiction where '
               'that refit clears the same floors of S and J, removes that share of the '
               'valve&rsquo;s MSE or of its part above the noise with a working calibration and '
               'fits MV better than the plain fit (a reading late or off in offset and gain '
               'hides a slip). Sizes the user gave are not weighed against that valve. '
               'The score is the reduction of the MSE (1 - MSE / MSE<sub>ideal</sub>; behind '
               'the reading&rsquo;s timing, of the valve without friction&rsquo;s; of its part '
               'above the noise where that share decided), 0 '
               'for play, for cannot tell and where stiction gave way to the valve without '
               'friction.')
    elif st.get('probability') is not None:
        # As the reason under it and the terminal print it: two decimals, three in the tails.
        shown = probability_text(st['probability'], DETECTOR_BAND)
        strength = f'probability of stiction {shown} (calibrated on simulated loops)'
        how = (f'Without MV a detector trained on simulated loops decides: stiction when its '
               f'calibrated probability is at or above {num(DETECTOR_BAND[1])}, no stiction '
               f'below {num(DETECTOR_BAND[0])}, and cannot tell between, where the evidence '
               'is balanced (an answer needs odds of 3:1).')
    elif st.get('detector') is not None:
        # Not judged: "score 0" would read as "certainly no stiction".
        strength = 'not judged, so no probability'
        how = ''
    else:
        strength = f'score {num(st.get("score"), 3)} (0 = none, 1 = certain)'
        how = ''
    size = ('' if st.get('apparent_S') is None
            else f'; apparent S {num(st["apparent_S"], 3, "%")}')
    out = [f'<p class="verdict">{verdict} &mdash; {strength}{size}</p>',
           f'<p>{clean(st.get("reason", ""))}</p>']
    if st.get('without_friction'):
        out.append(f'<p>A valve without friction ({e(st["without_friction"])}) explains MV: '
                   'the fits&rsquo; S and J below are what a friction model makes of it, not '
                   'a friction size.</p>')
    if st.get('read_behind'):
        out.append(f'<p>Found behind the reading&rsquo;s timing and calibration '
                   f'({e(st["read_behind"])}): the apparent S is that refit&rsquo;s (the row '
                   '&ldquo;read behind&rdquo; below); the plain fits read MV as on time.</p>')
    sized = explained_size(report)
    if sized:
        name, s, j = sized
        out.append(f'<p>The size above is the fits&rsquo;, from valve models without the '
                   f'physics <code>--explain</code> found. With it in place ({e(name)}, '
                   f'below), the valve itself has S {num(s, 4, "%")} and J '
                   f'{num(j, 4, "%")}.</p>')
    dead = report.get('mv_dead')
    if dead:
        out.append(f'<p>MV set aside, so OP and PV decide: {clean(dead["reason"])}. The fits '
                   f'to that reading are kept in the JSON report (<code>mv_dead.fits</code>).'
                   '</p>')
    if how:
        out.append(rule(how))
    if st.get('size_withheld'):
        out.append(f'<p>No size is given: {clean(st["size_withheld"])}</p>')
    if st.get('size_caution'):
        out.append(f'<p>Size caution: {clean(st["size_caution"])}</p>')
    vote = st.get('signature_vote')
    if vote:
        out.append(f'<p>Beside it, the vote of the signatures (each decided signature counts '
                   f'1 for stiction, 0 against; stiction at a share of {num(VOTE_THRESHOLD)} '
                   f'or more): {_decision(vote.get("detected"))}, share '
                   f'{num(vote.get("score"), 3)}; {clean(vote.get("reason", ""))}.</p>')
    return out


def _fits(report: dict) -> list:
    rows = [[e(f['model']), num(f['S'], unit='%'), num(f['J'], unit='%'), num(f['mse']),
             num(f.get('ideal_valve_mse')), e(f['source']), span(f.get('S_interval')),
             span(f.get('J_interval'))] for f in report['fits']]
    rows += [[e(f'{b["model"]}, read behind'), num(b['S'], unit='%'), num(b['J'], unit='%'),
              num(b['mse']), '-', 'refitted behind the dead time and calibration (its MSE '
              'after its calibration)',
              span(b.get('S_interval')), span(b.get('J_interval'))]
             for b in (f.get('behind') for f in report['fits']) if b]
    return ['<h2>Model fits (MSE of eq. 2.8 against the measured MV)</h2>',
            table(['model', 'S', 'J', f'MSE ({MSE_UNIT})', f'MSE of an ideal valve ({MSE_UNIT})',
                   'source', 'S 95 % range', 'J 95 % range'], rows)]


def _oscillation(osc: dict) -> list:
    rows = [['oscillating', 'yes' if osc.get('oscillating') else 'no',
             'a regular cycle in the control error SP - PV']]
    if not osc.get('oscillating') and not osc.get('period_s'):
        # No cycle found: an amplitude or a count of 0 would read as measured.
        rows.append(['why', clean(osc.get('reason', '')), ''])
        return ['<h2>Oscillation</h2>', table(['quantity', 'value', 'meaning'], rows)]
    # A period measured where no regular cycle was found belongs to a candidate that
    # failed the test (the 'why' row says which); it must not read as the loop's cycle.
    cand = '' if osc.get('oscillating') else 'candidate '
    if osc.get('period_s') is not None:
        rows.append([f'{cand}period', num(osc['period_s'], unit='s'),
                     'from the zero crossings of its autocorrelation'
                     + ('; not a cycle of the loop: see why' if cand else '')])
    if osc.get('amplitude') is not None:
        rows.append(['amplitude', num(osc['amplitude'], unit=PV_UNITS),
                     'of the fundamental sinusoid of SP - PV'])
    if osc.get('regularity') is not None:
        rows.append(['regularity', num(osc['regularity'], 3),
                     'mean period / (3 x its standard deviation); regular above 1'])
    if osc.get('n_cycles') is not None:
        rows.append([f'{cand}cycles in the record', num(osc['n_cycles'], 3),
                     'record length / period'])
    rows.append(['why', clean(osc.get('reason', '')), ''])
    return ['<h2>Oscillation</h2>', table(['quantity', 'value', 'meaning'], rows)]


def _signatures(sigs: dict, held_rows: int = 0) -> list:
    rows = []
    for name, s in sigs.items():
        what, unit, op = SIGNATURES.get(name, ('value', '', ''))
        rule_text = ('-' if s.get('threshold') is None
                     else f'{op} {num(s["threshold"], unit=unit)}')
        rows.append([e(name), e(what), num(s.get('value'), unit=unit), rule_text,
                     _decision(s.get('stiction')), clean(s.get('reason', ''))])
    out = ['<h2>Signatures (OP and PV only)</h2>',
           rule('A signature says stiction when its value passes its threshold in the '
                'direction shown; bicoherence only finds the loop non-linear, which the PV-OP '
                'ellipse then sizes (hos_pv_op). Undetermined: the record cannot tell (too '
                'short, no oscillation, between the two thresholds of the paper).'),
           table(['signature', 'measures', 'value', 'stiction when', 'decision', 'why'], rows)]
    if held_rows:
        held = 'the held row' if held_rows == 1 else f'the {held_rows} held rows'
        out.append(rule(f'This table reads every row of the stretch, {held} included; the '
                        'detector and its evidence lines read the fresh rows only, so their '
                        'counts and times can differ from these.'))
    return out


def _hammerstein(ham: dict) -> list:
    rows = [['S', num(ham.get('S'), unit='%'), span(ham.get('S_interval'))],
            ['J', num(ham.get('J'), unit='%'), span(ham.get('J_interval'))],
            ['residual variance / that of a linear valve', num(ham.get('fit_improvement'), 3),
             'below 1: the sticky valve explains PV better'],
            ['reliable', 'yes' if ham.get('reliable') else 'no', clean(ham.get('reason', ''))]]
    lin = ham.get('linear_model') or {}
    if lin:
        rows.append(['plant (ARX)', f'{e(lin.get("structure", ""))} na {num(lin.get("na"))}, '
                     f'nb {num(lin.get("nb"))}',
                     f'dead time {num(lin.get("delay_s"), unit="s")}, time constant '
                     f'{num(lin.get("time_constant_s"), unit="s")}, gain '
                     f'{num(lin.get("gain"), 3, PV_UNITS + " per % of OP")}'
                     + (', integrating' if lin.get('integrating') else '')])
    d = ham.get('details') or {}
    if d.get('likelihood_ratio') is not None:
        rows.append(['likelihood ratio, sticky vs linear valve',
                     num(d['likelihood_ratio']),
                     f'on {num(d.get("effective_samples"), 4)} effective samples'])
    if d.get('jump_likelihood_ratio') is not None:
        rows.append(['likelihood ratio, slip jump vs deadband (J = 0)',
                     num(d['jump_likelihood_ratio']),
                     'a figure, not a test: on simulated loops its median is 1.5 with a '
                     'backlash valve (90th percentile 15), 3 with a linear one and 18 with a '
                     'sticky one (25th percentile 3.6)'])
    se = d.get('jackknife_se') or {}
    if se:
        rows.append(['jackknife standard error', f'S {num(se.get("S"), 3, "%")}, '
                     f'J {num(se.get("J"), 3, "%")}', ''])
    out = ['<h2>Hammerstein quantification (S and J from OP and PV)</h2>',
           table(['quantity', 'value', 'range or meaning'], rows)]
    if ham.get('reference'):
        out.append(f'<p>After {clean(ham["reference"])}.</p>')
    return out


def _leaned(leaned: dict) -> list:
    rows = [[e(c['feature']), 'missing' if c['value'] is None else num(c['value']),
             f'{c["log_odds"]:+.2f}'] for c in leaned.get('contributions', [])]
    return ["<h2>What the detector's score rests on</h2>",
            f'<p>The detector&rsquo;s score starts from {leaned["start"]:+.2f} (log-odds of '
            f'stiction, before it reads any figure of the record) and reaches '
            f'{leaned["score"]:+.2f}; these parts moved it most (docs/DETECTION.md, section 2, '
            f'says what each figure measures; <code>cnn_large_logit</code> is the large '
            f'network&rsquo;s).</p>',
            table(['figure', 'value', 'moved the score by'], rows)]


def _figures(figures: list, signals: list) -> list:
    out = ['<h2>Figures</h2>']
    for p in figures:
        stem = Path(p).stem
        if stem == 'maps' and not {'mv', 'pv'} <= set(signals):
            stem = 'maps_mv' if 'mv' in signals else 'maps_pv'
        caption = CAPTIONS.get(stem, LANDSCAPE if stem.startswith('landscape') else '')
        out.append(figure(p, caption))
    return out


def _provenance(report: dict) -> str:
    """Return when the record starts (its times count from there), and what wrote the page."""
    start = report.get('start_time')
    when = (f'The record starts at {e(start)}; every time on this page (s) counts from '
            'there. ' if start else 'The record gives no clock time; every time on this '
            'page (s) counts from its first sample. ')
    model = ((report.get('stiction') or {}).get('detector') or {}).get('model') or {}
    version = f' version {e(model["version"])}' if model.get('version') is not None else ''
    detector = f'; detector {e(model["file"])}{version}' if model.get('file') else ''
    written = datetime.now(timezone.utc).strftime('%Y-%m-%d %H:%M UTC')
    return (f'<p>{when}Written {written} by stiction_ros {e(__version__)}'
            f'{detector}.</p>')


def render(report: dict, figures: list) -> str:
    """Return the HTML text of ``report`` (the JSON dict) with the PNG ``figures`` embedded."""
    st = report.get('stiction', {})
    name = report.get('name') or report['input'].get('path')
    source = report['input'].get('path')
    # Which recording the page is of, for a later run that would write over it.
    mark = (f'<meta name="{INPUT_META}" content="{e(Path(source).resolve())}">'
            if source else '')
    parts = [f'<!DOCTYPE html><html><head><meta charset="utf-8">{mark}<title>stiction report: '
             f'{e(name)}</title><style>{STYLE}</style></head><body>',
             f'<h1>Valve stiction report: {e(report.get("name") or "")}</h1>',
             f'<p>Input: <code>{e(report["input"].get("path"))}</code> '
             f'({e(report["input"].get("format"))}); {num(report["samples"])} samples at '
             f'{num(report["sample_time"], unit="s")}, {num(report["valid_samples"])} valid; '
             f'signals: {e(", ".join(report["signals"]))}; '
             f'{e(report.get("loop_type", ""))} loop. '
             f'{"OP and MV are" if "mv" in report["signals"] else "OP is"} in % of travel; PV '
             f'and SP in {PV_UNITS}.</p>', _provenance(report)]
    judged = judged_text(report)
    if judged:
        # What the terminal's judged: line says: gaps left part of the record unread.
        parts.append(f'<p>Judged on: {clean(judged)}.</p>')
    parts += _verdict(report)
    if st.get('evidence'):
        parts += ['<h2>Evidence (which test saw what, and when)</h2><ul>',
                  *[f'<li>{clean(ev)}</li>' for ev in st['evidence']], '</ul>']
    if (st.get('detector') or {}).get('leaned_on'):
        parts += _leaned(st['detector']['leaned_on'])
    if report.get('fits'):
        parts += _fits(report)
    if st.get('oscillation'):
        parts += _oscillation(st['oscillation'])
    if st.get('signatures'):
        # The signatures read the longest stretch: its held rows, where the answer pools several.
        det = st.get('detector') or {}
        parts += _signatures(st['signatures'], (det.get('stretches') or [det])[0].get(
            'held_rows', 0))
    if report.get('mismatch'):
        parts += explain_parts(report)
    if st.get('hammerstein'):
        parts += _hammerstein(st['hammerstein'])
    parts += _figures([p for p in figures if p and Path(p).exists()], report.get('signals', []))
    if report.get('excluded'):
        rows = [[num(x.get('start_s'), unit='s'), num(x.get('end_s'), unit='s'),
                 num(x.get('samples')), clean(x.get('reason'))] for x in report['excluded']]
        parts += ['<h2>Excluded from the analysis</h2>',
                  table(['from', 'to', 'samples', 'reason'], rows)]
    if report.get('notes'):
        notes = ''.join(f'<li>{clean(n)}</li>' for n in report['notes'])
        parts.append(f'<h2>Notes</h2><ul>{notes}</ul>')
    parts.append('</body></html>')
    return '\n'.join(parts)
