"""The ``--explain`` figure: where the plain model misses, and what the explained model changes."""

# Figure draws without pyplot and needs no backend: importing this module leaves the
# caller's matplotlib as it was, and no figure outlives its function.
from matplotlib.figure import Figure
import numpy as np

COLOURS = {'opening': 'tab:red', 'closing': 'tab:blue'}
# Fewer breakaways than this show no pattern against rest time, position or time.
FEW_BREAKAWAYS = 5


def mismatch_figure(report, arrays, path):
    """Save the residual, breakaway, map and candidate panels to ``path``; return it."""
    mismatch_panels(report, arrays).savefig(path, dpi=100)
    return path


def mismatch_panels(report, arrays) -> Figure:
    """Return the figure :func:`mismatch_figure` saves."""
    a = arrays
    t, op, mv = a['t'], a['op'], a['mv']
    rows = a['breakaways']
    few = len(rows) < FEW_BREAKAWAYS
    fig = Figure(figsize=(12, 7.5 if few else 11))
    ax = fig.subplots(2 if few else 3, 2)
    # The samples each model is scored on, less the first: the start state, no prediction.
    scored = a['fit_mask'] | a['hold_mask']
    scored[np.argmax(scored)] = False
    r0 = np.where(scored, mv - a['mv_baseline'], np.nan)
    r1 = np.where(scored, mv - a['mv_explained'], np.nan)
    m = report['mismatch']
    ax[0, 0].plot(t, r0, color='0.3', lw=0.7, label='plain model')
    if 'mv_frictionless' in a:
        ax[0, 0].plot(t, np.where(scored, mv - a['mv_frictionless'], np.nan),
                      color='tab:purple', lw=0.8, ls='--',
                      label='best valve without friction')
    if m['effect'] not in ('none', 'unexplained'):
        ax[0, 0].plot(t, r1, color='tab:green', lw=0.7, alpha=0.8, label=m['model']['name'])
    for k, reg in enumerate(m['regions']):
        ax[0, 0].axvspan(reg['t_start'], reg['t_end'], color='tab:orange', alpha=0.25,
                         label='where the plain model misses most' if k == 0 else None)
    h = report['holdout']
    if h['t_start'] is not None:
        ax[0, 0].axvline(h['t_start'], color='k', ls='--', lw=1.0, label='held out from here')
    ax[0, 0].set_title('residual MV - model (regions shaded)', fontsize=10)
    ax[0, 0].set_ylabel('MV - model (%)')
    ax[0, 0].set_xlabel('time (s)')
    ax[0, 0].legend(fontsize=8)
    if few:
        _too_few(ax[0, 1], len(rows))
    else:
        _breakaway_panels(ax, rows)
    mp = ax[-1, 0]
    # Measured drawn wide and light under the models, so it shows where they cover it.
    mp.plot(op, mv, color='0.8', lw=2.5, label='measured')
    mp.plot(op, a['mv_baseline'], color='k', lw=0.7, label='plain')
    if 'mv_frictionless' in a:
        mp.plot(op, a['mv_frictionless'], color='tab:purple', lw=0.6, alpha=0.7,
                label='without friction')
    if m['effect'] not in ('none', 'unexplained'):
        mp.plot(op, a['mv_explained'], color='tab:green', lw=0.7, label='explained')
    mp.set_xlabel('OP (%)')
    mp.set_ylabel('MV (%)')
    mp.set_title('MV-OP map before and after', fontsize=10)
    mp.legend(fontsize=8)
    if report['candidates']:
        _candidate_panel(ax[-1, 1], report)
    else:
        _chain_panel(ax[-1, 1], report)
    b = report['baseline']
    names = ', '.join(e['id'] for e in m.get('effects', [])) or m['effect']
    fig.suptitle(f'{names}: held-out MSE {b["mse_holdout"]:.4g} %² (plain) -> '
                 f'{m["mse_holdout"]:.4g} %²\n{m["explanation"]}', fontsize=9, wrap=True)
    fig.tight_layout()
    return fig


def _breakaway_panels(ax, rows):
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
        axis.legend(fontsize=8)
    # A rest lasts at least one sample: a log axis, without a negative side.
    if all(r['rest_s'] > 0 for r in rows):
        ax[0, 1].set_xscale('log')
    ax[0, 1].set_title('breakaway events of the plain model', fontsize=10)


def _too_few(axis, n):
    axis.axis('off')
    axis.text(0.0, 0.9, f'{n} breakaway(s) of the plain model: too few to show a '
              f'pattern\nagainst rest time, position or time (at least {FEW_BREAKAWAYS}).',
              transform=axis.transAxes, va='top', fontsize=10)


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
    if all(c['score'] <= 0 for c in cands):
        axis.text(0.5, 0.5, 'every candidate scores 0: the plain model leaves\nnothing a '
                  'candidate explains better', transform=axis.transAxes, ha='center',
                  va='center', fontsize=9, bbox={'facecolor': 'w', 'alpha': 0.8, 'lw': 0})
    axis.set_title('friction candidates: green named (highest passing score),\n'
                   'orange passes, not named; grey below its threshold', fontsize=8)


def _chain_panel(axis, report):
    # No friction claimed, so no friction candidates: the chains' held-out fits instead.
    rows = [('plain Kano', report['baseline']['mse_holdout'])]
    if report.get('frictionless'):
        rows.append(('no friction', report['frictionless']['mse_holdout']))
    rows += [(k, v['mse_holdout']) for k, v in report.get('chains', {}).items()]
    rows = [(k, v) for k, v in rows if v is not None and np.isfinite(v)]
    positive = [v for _, v in rows if v > 0]
    axis.set_title('best valve of each kind, held-out part', fontsize=10)
    if not positive:
        axis.axis('off')
        axis.text(0.0, 0.9, 'every kind of valve fits the held-out part exactly (MSE 0):\n'
                  + ', '.join(k for k, _ in rows), transform=axis.transAxes, va='top',
                  fontsize=9)
        return
    # An exact fit (MSE 0) cannot sit on a log axis: it is drawn at a floor, marked "0".
    floor = min(positive) / 10.0
    y = np.arange(len(rows))
    axis.barh(y, [v if v > 0 else floor for _, v in rows],
              color=['tab:green' if v <= 0 else '0.6' for _, v in rows])
    for k, (_, v) in enumerate(rows):
        axis.text(v if v > 0 else floor, k, f' {v:.3g}' if v > 0 else ' 0 (exact)',
                  va='center', fontsize=8)
    axis.set_yticks(y, [k for k, _ in rows], fontsize=8)
    axis.set_xscale('log')
    axis.set_xlim(floor / 2.0, max(positive) * 30.0)
    axis.invert_yaxis()
    axis.set_xlabel('held-out MSE (%²)')
