"""
The analyzer's figures: trends, MV-OP and PV-OP maps with the models, the MSE landscape.

Each function saves one PNG and returns its path, so the HTML report can
embed it and an engineer can open it alone.  OP and MV are in % of travel;
PV and SP in "PV units", since no recording states them.
"""

import math

# Figure draws without pyplot and needs no backend: importing this module leaves the
# caller's matplotlib as it was, and no figure outlives its function.
from matplotlib import colormaps
from matplotlib.figure import Figure
import numpy as np

from stiction_ros.analysis.identify import EXACT_MSE

COLORS = {'kano': 'tab:red', 'choudhury': 'tab:green'}
PV_UNITS = 'PV units'


def _shade_excluded(ax, record):
    for ex in record.excluded:
        ax.axvspan(ex['start_s'], ex['end_s'] + record.sample_time, color='0.85', lw=0)


def detector_marks(analysis) -> tuple[list, list]:
    """Return the detector's stuck periods (start, end) and slips, in the record's seconds."""
    details = getattr(getattr(analysis, 'detection', None), 'details', None) or {}
    stuck = details.get('stuck') or {}
    return ([(a, b) for a, b, _ in stuck.get('stuck_periods_s', [])],
            [t for t, _ in stuck.get('slips_s', [])])


def _mark(axes, analysis, t0):
    """Shade the detector's stuck periods and draw its slips, as its evidence lines name them."""
    periods, slips = detector_marks(analysis)
    for ax in axes:
        for k, (a, b) in enumerate(periods):
            ax.axvspan(t0 + a, t0 + b, color='tab:orange', alpha=0.15, lw=0,
                       label='stuck (detector)' if k == 0 else None)
        for k, t in enumerate(slips):
            ax.axvline(t0 + t, color='tab:red', ls=':', lw=1.0,
                       label='slip (detector)' if k == 0 else None)


def trends_figure(analysis, path, window=None):
    """
    Save OP/MV (measured and each model) and PV/SP against time.

    Excluded stretches are grey; the detector's stuck periods orange and its
    slips dotted red, at the times its evidence gives.
    """
    trends_panels(analysis, window).savefig(path, dpi=90)
    return path


def trends_panels(analysis, window=None) -> Figure:
    """Return the figure :func:`trends_figure` saves (the last ``window`` s, or all)."""
    rec = analysis.record
    t = rec.t
    keep = slice(None) if window is None else (t >= t[-1] - window)
    rows = 2 if rec.has('pv') else 1
    fig = Figure(figsize=(11, 3.2 * rows))
    axes = fig.subplots(rows, 1, sharex=True, squeeze=False)
    ax = axes[0, 0]
    ax.plot(t[keep], rec.signals['op'][keep], color='tab:blue', lw=1, label='OP')
    if rec.has('mv'):
        ax.plot(t[keep], rec.signals['mv'][keep], color='k', lw=1, label='MV measured')
    for model, mv_hat in analysis.predictions.items():
        ax.plot(t[keep], mv_hat[keep], color=COLORS[model], lw=1, ls='--',
                label=f'MV {model}')
    ax.set_ylabel('OP, MV (%)' if rec.has('mv') else 'OP (%)')
    _shade_excluded(ax, rec)
    if rows == 2:
        ax = axes[1, 0]
        ax.plot(t[keep], rec.signals['pv'][keep], color='tab:purple', lw=1, label='PV')
        if rec.has('sp'):
            ax.plot(t[keep], rec.signals['sp'][keep], color='tab:green', lw=1, label='SP')
        ax.set_ylabel(f'PV, SP ({PV_UNITS})')
        _shade_excluded(ax, rec)
    # The detector's times count from the record's first sample.
    _mark(axes[:, 0], analysis, float(t[0]))
    for ax in axes[:, 0]:
        ax.legend(loc='upper right', fontsize=8, ncol=4, framealpha=0.6)
    # A mark outside the window shown must not widen it.
    axes[-1, 0].set_xlim(float(t[keep][0]), float(t[keep][-1]))
    axes[-1, 0].set_xlabel('time (s); grey: excluded')
    fig.suptitle(f'{rec.name or rec.path}: time trends')
    fig.tight_layout()
    return fig


def maps_figure(analysis, path):
    """Save the MV-OP map with the models overlaid and the PV-OP map."""
    rec = analysis.record
    op = rec.signals['op']
    panels = [p for p in ('mv', 'pv') if rec.has(p)]
    if not panels:
        return None
    fig = Figure(figsize=(5.5 * len(panels), 4.6))
    axes = fig.subplots(1, len(panels), squeeze=False)
    for ax, name in zip(axes[0], panels):
        ok = rec.valid
        ax.plot(op[ok], rec.signals[name][ok], '.', ms=2, color='0.3', label=f'{name} measured')
        if name == 'mv':
            for model, mv_hat in analysis.predictions.items():
                ax.plot(op[ok], mv_hat[ok], '-', lw=0.8, color=COLORS[model],
                        label=f'{model}', alpha=0.8)
            lo, hi = np.nanmin(op[ok]), np.nanmax(op[ok])
            ax.plot([lo, hi], [lo, hi], ':', color='0.5', lw=0.8, label='ideal valve')
        ax.set_xlabel('OP (%)')
        ax.set_ylabel('MV (%)' if name == 'mv' else f'PV ({PV_UNITS})')
        ax.set_title(f'{name.upper()}-OP map')
        ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    return path


def landscape_colours(landscape: dict) -> dict:
    """
    Return what the landscape's colours show: log10(MSE / MSE_min) and its limits.

    Relative to the minimum, so a fit whose MSE is near 0 is coloured as
    clearly as a noisy one; cells at the ceiling (not computed further) are
    flagged ``over``.
    """
    mse = np.asarray(landscape['mse'], dtype=float)
    least = float(np.min(mse))
    # An exact fit sits at the floor (EXACT_MSE): relative to it, every other cell is
    # ten decades up, one colour.  Such cells are then coloured 0, the rest relative
    # to the best cell off the floor.
    exact = mse <= EXACT_MSE * (1 + 1e-9)
    if exact.any() and not exact.all():
        least = float(np.min(mse[~exact]))
    ceiling = landscape.get('ceiling')
    over = np.zeros(mse.shape, dtype=bool) if ceiling is None else mse >= ceiling * (1 - 1e-9)
    value = np.log10(np.maximum(mse, least) / least)
    top = (math.log10(ceiling / least) if over.any()
           else float(np.max(value)) if value.size else 1.0)
    return {'value': value, 'over': over, 'mse_min': least, 'vmax': max(top, 1e-3),
            'ceiling': ceiling, 'exact': int(np.sum(exact)) if not exact.all() else 0}


def landscape_figure(landscape, path):
    """Save the MSE over (S, J) around the optimum, relative to its minimum; 95 % region."""
    s, j, mse = landscape['S'], landscape['J'], landscape['mse']
    c = landscape_colours(landscape)
    fig = Figure(figsize=(6.4, 5.0))
    ax = fig.subplots()
    cmap = colormaps['viridis'].with_extremes(over='0.8')
    # Above vmax, not inf: an infinite cell counts as missing and would be left blank.
    shown = np.where(c['over'], c['vmax'] + 1.0, c['value'])
    im = ax.pcolormesh(j, s, shown, shading='nearest',
                       cmap=cmap, vmin=0.0, vmax=c['vmax'])
    ref = 'MSE_ref' if c['exact'] else 'MSE_min'
    fig.colorbar(im, ax=ax, extend='max' if c['over'].any() else 'neither',
                 label=f'log10(MSE / {ref}), {ref} = {c["mse_min"]:.3g} %²')
    if not c['exact']:
        # An exact fit's bound is 0: its 95 % region is the exact cells, named in the title.
        ax.contour(j, s, mse, levels=[landscape['bound']], colors='w', linewidths=1)
    ax.plot(landscape['best'][1], landscape['best'][0], 'r+', ms=10, mew=1.2)
    ax.set_xlabel('J (%)')
    ax.set_ylabel('S (%)')
    title = f'{landscape["model"]}: MSE around the fit'
    title += (f'\nexact fit: {c["exact"]} cell(s) at MSE 0 (to {EXACT_MSE:g} %²), coloured '
              '0:\nthe 95 % region; MSE_ref: the best cell off them' if c['exact']
              else ' (white: 95 % region)')
    if c['over'].any():
        title += f'\ngrey: MSE above {c["ceiling"]:.3g} %², not computed further'
    ax.set_title(title, fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    return path
