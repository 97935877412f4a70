"""The ``--explain`` figure: where the plain model misses, and what the explained model changes."""

# Figure draws without pyplot and needs no backend: importing this module leaves the
# caller's matplotlib as it was, and no figure outlives its function.
from matplotlib.figure import Figure
import numpy as np

COLOURS = {'opening': 'tab:red', 'closing': 'tab:blue'}


def mismatch_figure(report, arrays, path):
    """Save the residual, breakaway, map and candidate panels to ``path``; return it."""
    a = arrays
    t, op, mv = a['t'], a['op'], a['mv']
    fig = Figure(figsize=(12, 11))
    ax = fig.subplots(3, 2)
    r0 = mv - a['mv_baseline']
    r1 = mv - a['mv_explained']
    m = report['mismatch']
    ax[0, 0].plot(t, r0, color='0.5', lw=0.5, label='plain model')
    if 'mv_frictionless' in a:
        ax[0, 0].plot(t, mv - a['mv_frictionless'], color='tab:purple', lw=0.5, alpha=0.6,
                      label='best valve without friction')
    if m['effect'] not in ('none', 'unexplained'):
        ax[0, 0].plot(t, r1, color='tab:green', lw=0.5, alpha=0.8, label=m['model']['name'])
    for reg in m['regions']:
        ax[0, 0].axvspan(reg['t_start'], reg['t_end'], color='tab:orange', alpha=0.25)
    h = report['holdout']
    if h['t_start'] is not None:
        ax[0, 0].axvline(h['t_start'], color='k', ls='--', lw=1.0, label='held out from here')
    ax[0, 0].set_title('residual MV - model (regions shaded)', fontsize=9)
    ax[0, 0].set_ylabel('MV - model (%)')
    ax[0, 0].set_xlabel('time (s)')
    ax[0, 0].legend(fontsize=7)
    rows = a['breakaways']
    for key, axis, label in (('rest_s', ax[0, 1], 'rest time before breakaway (s)'),
                             ('position', ax[1, 0], 'position at breakaway (%)'),
                             ('t', ax[1, 1], 'time (s)')):
        for d, c in COLOURS.items():
            xs = [r[key] for r in rows if r['direction'] == d]
            ys = [r['residual'] for r in rows if r['direction'] == d]
            axis.plot(xs, ys, '.', color=c, ms=4, label=d)
        axis.axhline(0.0, color='0.6', lw=0.6)
        axis.set_xlabel(label)
        axis.set_ylabel('MV - model after breakaway (%)')
        axis.legend(fontsize=7)
    ax[0, 1].set_xscale('symlog', linthresh=1.0)
    ax[0, 1].set_title('breakaway events of the plain model', fontsize=9)
    ax[2, 0].plot(op, mv, color='0.75', lw=0.4, label='measured')
    ax[2, 0].plot(op, a['mv_baseline'], color='k', lw=0.7, label='plain')
    if 'mv_frictionless' in a:
        ax[2, 0].plot(op, a['mv_frictionless'], color='tab:purple', lw=0.6, alpha=0.7,
                      label='without friction')
    if m['effect'] not in ('none', 'unexplained'):
        ax[2, 0].plot(op, a['mv_explained'], color='tab:green', lw=0.7, label='explained')
    ax[2, 0].set_xlabel('OP (%)')
    ax[2, 0].set_ylabel('MV (%)')
    ax[2, 0].set_title('MV-OP map before and after', fontsize=9)
    ax[2, 0].legend(fontsize=7)
    if report['candidates']:
        _candidate_panel(ax[2, 1], report)
    else:
        _chain_panel(ax[2, 1], report)
    b = report['baseline']
    names = ', '.join(e['id'] for e in m.get('effects', [])) or m['effect']
    fig.suptitle(f'{names}: held-out MSE {b["mse_holdout"]:.4g} %² (plain) -> '
                 f'{m["mse_holdout"]:.4g} %²\n{m["explanation"]}', fontsize=9, wrap=True)
    fig.tight_layout()
    fig.savefig(path, dpi=80)
    return path


def _candidate_panel(axis, report):
    cands = report['candidates']
    top = max((c for c in cands if c['score'] > 1.0), key=lambda c: c['score'], default=None)
    if report['mismatch']['effect'] in ('none', 'unexplained'):
        top = None  # passing, but nothing named: the plain fit left nothing to explain
    colours = ['tab:green' if c is top else 'tab:orange' if c['score'] > 1.0 else '0.6'
               for c in cands]
    y = np.arange(len(cands))
    # A log axis shows scores from far below to far above 1; a score of 0 sits at its left.
    floor = 1e-2
    axis.barh(y, [max(c['score'], floor) for c in cands], color=colours)
    for k, c in enumerate(cands):
        axis.text(max(c['score'], floor), k, f' {c["score"]:.3g}', va='center', fontsize=7)
    axis.axvline(1.0, color='k', ls='--', lw=0.8)
    axis.set_yticks(y, [c['effect'] for c in cands], fontsize=7)
    axis.set_xscale('log')
    axis.set_xlim(floor, max([10.0] + [c['score'] * 30 for c in cands]))
    axis.invert_yaxis()
    axis.set_xlabel('score = LR / threshold (dashed: 1; above it a candidate passes)',
                    fontsize=8)
    axis.set_title('friction candidates: green named (highest passing score),\n'
                   'orange passes, not named; grey below its threshold', fontsize=8)


def _chain_panel(axis, report):
    # No friction claimed, so no friction candidates: the chains' held-out fits instead.
    rows = [('plain Kano', report['baseline']['mse_holdout'])]
    if report.get('frictionless'):
        rows.append(('no friction', report['frictionless']['mse_holdout']))
    rows += [(k, v['mse_holdout']) for k, v in report.get('chains', {}).items()]
    rows = [(k, v) for k, v in rows if v is not None and np.isfinite(v) and v > 0]
    y = np.arange(len(rows))
    axis.barh(y, [v for _, v in rows], color='0.6')
    axis.set_yticks(y, [k for k, _ in rows], fontsize=7)
    axis.set_xscale('log')
    axis.invert_yaxis()
    axis.set_xlabel('held-out MSE (%²)')
    axis.set_title('best valve of each kind, held-out part', fontsize=9)
