"""
A single self-contained HTML page of the analyzer's report, figures embedded.

The page shows the verdict first, then the evidence an engineer would check
by eye: the fits (MSE of eq. 2.8), each signature against its threshold, the
figures, and what was excluded from the record and why.
"""

import base64
import html
import json
from pathlib import Path

STYLE = """
body { font-family: sans-serif; max-width: 1100px; margin: 1em auto; color: #222; }
table { border-collapse: collapse; margin: 0.5em 0 1em; }
td, th { border: 1px solid #bbb; padding: 3px 8px; text-align: left; font-size: 14px; }
th { background: #eee; }
.yes { color: #b00; font-weight: bold; } .no { color: #070; } .und { color: #a60; }
.verdict { font-size: 20px; padding: 8px; border: 2px solid #888; display: inline-block; }
img { max-width: 100%; border: 1px solid #ddd; margin: 4px 0; }
"""


def _e(x):
    return html.escape(str(x))


def _num(x, digits=4):
    if x is None:
        return '-'
    if isinstance(x, float):
        return f'{x:.{digits}g}'
    return _e(x)


def _decision(flag):
    if flag is None:
        return '<span class="und">undetermined</span>'
    return '<span class="yes">stiction</span>' if flag else '<span class="no">no stiction</span>'


def _table(header, rows):
    head = ''.join(f'<th>{_e(h)}</th>' for h in header)
    body = ''.join('<tr>' + ''.join(f'<td>{c}</td>' for c in row) + '</tr>' for row in rows)
    return f'<table><tr>{head}</tr>{body}</table>'


def _img(path):
    if not path or not Path(path).exists():
        return ''
    data = base64.b64encode(Path(path).read_bytes()).decode('ascii')
    return f'<p><img alt="{_e(Path(path).name)}" src="data:image/png;base64,{data}"></p>'


def _params(values):
    return _e(', '.join(f'{k} {_num(v)}' for k, v in values.items()))


def _chain_parts(report):
    # The frictionless baseline and the friction chains, and the tests between them.
    m = report['mismatch']
    out = []
    if m.get('effects'):
        rows = [[_e(e['id']), _num(e.get('size')), _e(e.get('unit', '')),
                 _num(e.get('uncertainty')), _e(e['sentence'])] for e in m['effects']]
        out += ['<h3>Effects kept</h3>',
                _table(['effect', 'size', 'unit', 'standard error', 'what it means'], rows)]
    chains = [('no friction', report.get('frictionless'))] + [
        (k, v) for k, v in report.get('chains', {}).items()]
    rows = [[_e(name), _num(c['S']), _num(c['J']), _num(c['dead_time_s']), _num(c['lag_s']),
             _num(c['offset']), _num(c['gain']), _e(', '.join(c['stages']) or '-'),
             _num(c['mse_fit']), _num(c['mse_holdout'])] for name, c in chains if c]
    if rows:
        out += ['<h3>The valve through its instruments: best chain of each kind</h3>',
                _table(['friction', 'S (%)', 'J (%)', 'dead time (s)', 'lag (s)',
                        'offset (%)', 'gain', 'stages kept', 'MSE fit', 'MSE held-out'], rows)]
    rows = [[_e(k.replace('_', ' ')), _num(v.get('lr')), _num(v.get('threshold')),
             _num(v.get('rho'), 3),
             _num(v.get('heldout_gain'), 3), _num(v.get('heldout_p'), 3),
             'yes' if v['wins'] else 'no'] for k, v in report.get('friction_tests', {}).items()]
    if rows:
        out += ['<p>Friction is present only where a friction chain beats the best chain '
                'without friction on the fitted part (likelihood ratio on the effective '
                'sample size) and on the held-out part (paired block bootstrap, p &lt; '
                '0.01); it is stiction when the final friction model (its effects included) '
                'needs the slip jump J on the fitted part and beats that chain held out '
                'too.</p>',
                _table(['test', 'LR', 'threshold', 'residual lag-1', 'held-out MSE gain',
                        'held-out p', 'passes'], rows)]
    return out


def _mismatch_parts(report):
    # The --explain sections: the answer first, then what it rests on.
    m, b, h = report['mismatch'], report['baseline'], report.get('holdout', {})
    out = ['<h2>Why the model misses (--explain)</h2>',
           f'<p class="verdict">{_e(m["effect"])} &mdash; confidence '
           f'{_num(m["confidence"], 3)}</p>', f'<p>{_e(m["explanation"])}</p>',
           _table(['model', 'parameters', 'MSE fitted part', 'MSE held-out part'], [
               [f'{_e(b["model"])} (plain)', f'S {_num(b["S"])}, J {_num(b["J"])}',
                _num(b['mse_fit']), _num(b['mse_holdout'])],
               [_e(m['model']['name']), _params(m['model']['params']),
                _num(m['mse_fit']), _num(m['mse_holdout'])]]),
           f'<p>Held out: samples from {_e(h.get("first_sample"))} on (t &ge; '
           f'{_num(h.get("t_start"))} s, {_e(h.get("holdout_samples"))} samples), used for '
           'nothing but the held-out MSE.</p>']
    out += _chain_parts(report)
    rows = [[_e(c['effect']), _params(c['params']),
             _num(c['S']), _num(c['J']), _num(c['mse_fit']), _num(c['mse_holdout']),
             _num(c.get('lr')), _num(c.get('threshold')), _num(c['score'], 3)]
            for c in report.get('candidates', [])]
    out += ['<h3>Candidates side by side (each nests the plain model)</h3>',
            _table(['effect', 'parameters', 'S (%)', 'J (%)', 'MSE fit', 'MSE held-out',
                    'LR', 'threshold', 'score (LR / threshold)'], rows)]
    if m.get('regions'):
        rows = [[_num(r['t_start']), _num(r['t_end']), _e(r['regime']),
                 _num(r['residual_share'], 3)] for r in m['regions']]
        out += ['<h3>Where the plain model misses most (fitted part)</h3>',
                _table(['from (s)', 'to (s)', 'dominant regime', 'share of the residual'],
                       rows)]
    if m.get('regimes'):
        rows = [[_e(r['regime']), _num(r['residual_share'], 3), _num(r['sample_share'], 3),
                 _num(r['lift'], 3)] for r in m['regimes']]
        out += ['<h3>Residual by regime</h3>',
                _table(['regime', 'share of the residual', 'share of the samples',
                        'lift (residual / samples)'], rows)]
    return out


def render(report, figures):
    """Return the HTML text of ``report`` (the JSON dict) with the PNG ``figures`` embedded."""
    st = report.get('stiction', {})
    verdict = ('STICTION DETECTED' if st.get('detected')
               else 'no stiction detected' if st.get('detected') is False else 'cannot tell')
    if st.get('probability') is not None:
        strength = (f'probability of stiction {_num(st["probability"], 3)} (calibrated on '
                    f'simulated loops)')
    else:
        strength = f'score {_num(st.get("score"), 3)} (0 = none, 1 = certain)'
    parts = [f'<!DOCTYPE html><html><head><meta charset="utf-8"><title>stiction report: '
             f'{_e(report.get("name") or report["input"].get("path"))}</title>'
             f'<style>{STYLE}</style></head><body>',
             f'<h1>Valve stiction report: {_e(report.get("name") or "")}</h1>',
             f'<p>Input: <code>{_e(report["input"].get("path"))}</code> '
             f'({_e(report["input"].get("format"))}); {report["samples"]} samples at '
             f'{_num(report["sample_time"])} s, {report["valid_samples"]} valid; signals: '
             f'{_e(", ".join(report["signals"]))}; {_e(report.get("loop_type", ""))} loop.</p>',
             f'<p class="verdict">{verdict} &mdash; {strength}; apparent S '
             f'{_num(st.get("apparent_S"), 3)} %</p>',
             f'<p>{_e(st.get("reason", ""))}</p>']
    if st.get('size_withheld'):
        parts.append(f'<p>No size is given: {_e(st["size_withheld"])}</p>')
    if st.get('evidence'):
        parts += ['<h2>Evidence (which test saw what, and when)</h2><ul>',
                  *[f'<li>{_e(ev)}</li>' for ev in st['evidence']], '</ul>']
    if report.get('fits'):
        rows = [[_e(f['model']), _num(f['S']), _num(f['J']), _num(f['mse']), _e(f['source']),
                 _e(f.get('S_interval', '-')), _e(f.get('J_interval', '-'))]
                for f in report['fits']]
        parts += ['<h2>Model fits (MSE of eq. 2.8 against the measured MV)</h2>',
                  _table(['model', 'S (%)', 'J (%)', 'MSE', 'source', 'S 95 % range',
                          'J 95 % range'], rows)]
    osc = st.get('oscillation')
    if osc:
        parts.append(f'<h2>Oscillation</h2><p>{_e(json.dumps(osc))}</p>')
    sigs = st.get('signatures', {})
    if sigs:
        rows = [[_e(name), _num(s.get('value')), _num(s.get('threshold')),
                 _decision(s.get('stiction')), _e(s.get('reason', ''))]
                for name, s in sigs.items()]
        parts += ['<h2>Signatures (OP and PV only)</h2>',
                  _table(['signature', 'value', 'threshold', 'decision', 'why'], rows)]
    if report.get('mismatch') and 'baseline' not in report:
        parts += ['<h2>Why the model misses (--explain)</h2>',
                  f'<p class="verdict">cannot tell</p><p>{_e(report["mismatch"]["explanation"])}'
                  '</p>']
    elif report.get('mismatch'):
        parts += _mismatch_parts(report)
    ham = st.get('hammerstein')
    if ham:
        parts.append(f'<h2>Hammerstein quantification</h2><p>{_e(json.dumps(ham))}</p>')
    parts.append('<h2>Figures</h2>')
    parts += [_img(p) for p in figures]
    if report.get('excluded'):
        rows = [[_num(x.get('start_s')), _num(x.get('end_s')), _e(x.get('samples')),
                 _e(x.get('reason'))] for x in report['excluded']]
        parts += ['<h2>Excluded from the analysis</h2>',
                  _table(['from (s)', 'to (s)', 'samples', 'reason'], rows)]
    if report.get('notes'):
        parts.append('<h2>Notes</h2><ul>' + ''.join(f'<li>{_e(n)}</li>' for n in report['notes'])
                     + '</ul>')
    parts.append('</body></html>')
    return '\n'.join(parts)
