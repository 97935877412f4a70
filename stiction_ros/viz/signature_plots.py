"""
One figure of the stiction signatures, a panel each, to check every verdict by eye.

Panels: Horch's CCF with the zero crossings either side of lag 0 (Horch
1999, Control Eng. Practice 7, 1221-1231); He et al.'s sine and triangle
fits per half-cycle (2007, Ind. Eng. Chem. Res. 46, 4549-4560); the squared
bicoherence map (Choudhury, Shah and Thornhill 2004, Automatica 40,
1719-1728); the PV-OP map with its fitted ellipse and apparent stiction
(Choudhury et al. 2006, Control Eng. Practice 14, 1395-1412).  Signatures
without curves get a text panel.  Each title gives value against threshold
and the verdict.
"""

import math

# Figure draws without pyplot and needs no backend: importing this module leaves the
# caller's matplotlib as it was, and no figure outlives its function.
from matplotlib.figure import Figure
import numpy as np

VERDICT = {True: 'stiction', False: 'no stiction', None: 'undetermined'}
PV_UNITS = 'PV units'
COLOUR = {True: 'tab:red', False: 'tab:green', None: 'tab:gray'}


def _fmt(v):
    return 'n/a' if v is None or not math.isfinite(v) else f'{v:.3g}'


def _title(ax, sig):
    extra = ''
    if sig.name == 'bicoherence' and 'ngi' in sig.details:
        # Both indices decide, so both go in the title.
        extra = f", NGI {_fmt(sig.details['ngi'])} vs {sig.details['ngi_min']}"
    ax.set_title(f'{sig.name}: {_fmt(sig.value)} vs {_fmt(sig.threshold)}{extra} -> '
                 f'{VERDICT[sig.stiction]}', fontsize=9, color=COLOUR[sig.stiction])


def _horch(ax, sig):
    c = sig.curves
    ax.plot(c['lag_s'], c['ccf'], color='k', lw=1.0)
    ax.axvline(0.0, color='tab:blue', lw=0.8)
    ax.axhline(0.0, color='0.6', lw=0.6)
    for key in ('tau_l_s', 'tau_r_s'):
        if key in c:
            ax.axvline(c[key], color='tab:red', ls='--', lw=0.9)
    if 'tau_l_s' in c:
        span = 6.0 * (c['tau_r_s'] - c['tau_l_s'])
        ax.set_xlim(-span, span)
    ax.set_xlabel('lag (s), PV after OP')
    ax.set_ylabel('CCF(OP, PV)')


def _he(ax, sig):
    c = sig.curves
    starts = c['starts_s']
    t0 = starts[max(len(starts) - 8, 0)]
    keep = c['t'] >= t0
    fit = c['t_fit'] >= t0
    ax.plot(c['t'][keep], c['x'][keep], color='k', lw=1.6, label=c['signal'].upper())
    ax.plot(c['t_fit'][fit], c['sine'][fit], color='tab:blue', lw=1.0, label='sine fit')
    ax.plot(c['t_fit'][fit], c['triangle'][fit], color='tab:red', lw=1.0, ls='--',
            label='triangle fit')
    ax.legend(fontsize=7, loc='upper right')
    ax.set_xlabel('time (s)')
    ax.set_ylabel(f'{c["signal"].upper()} less its trend '
                  f'({"%" if c["signal"] == "op" else PV_UNITS})')


def _bicoherence(ax, sig):
    c = sig.curves
    f = c['freq_hz']
    im = ax.imshow(np.ma.masked_invalid(c['bic2']).T, origin='lower', aspect='auto',
                   extent=[f[0], f[-1], f[0], f[-1]], vmin=0.0, vmax=1.0, cmap='viridis')
    ax.figure.colorbar(im, ax=ax, label='bic$^2$')
    d = sig.details
    ax.text(0.98, 0.95, f"NGI {_fmt(d.get('ngi'))} (> {d.get('ngi_min')})\n"
            f"NLI {_fmt(d.get('nli'))} (> {_fmt(sig.threshold)})", transform=ax.transAxes,
            ha='right', va='top', fontsize=7, color='w')
    ax.set_xlabel('f1 (Hz)')
    ax.set_ylabel('f2 (Hz)')


def _ellipse(ax, sig, op, pv):
    c = sig.curves
    if sig.details.get('pv_signal') == 'PV':
        ax.plot(op, pv, color='0.8', lw=0.6, label='raw')
    ax.plot(c['op_filtered'], c['pv_filtered'], color='tab:blue', lw=0.8, label='filtered')
    if 'ellipse_op' in c:
        ax.plot(c['ellipse_op'], c['ellipse_pv'], color='tab:red', lw=1.6, label='ellipse')
        x0, y0 = c['centre']
        w = c['width']
        ax.plot([x0 - w / 2, x0 + w / 2], [y0, y0], color='k', lw=2.0, label='apparent stiction')
    ax.legend(fontsize=7, loc='best')
    ax.set_xlabel('OP (%)')
    ax.set_ylabel('dPV/dt (PV units/s)' if sig.details.get('pv_signal') == 'dPV/dt'
                  else f'PV ({PV_UNITS})')


def _slips(ax, sig, op, pv, sample_time):
    t = np.arange(len(pv)) * sample_time
    ax.plot(t, pv, color='tab:red', lw=0.6, label='PV')
    ax.set_xlabel('time (s)')
    ax.set_ylabel(f'PV ({PV_UNITS})')
    right = ax.twinx()
    right.plot(t, op, color='tab:blue', lw=0.8, label='OP')
    right.set_ylabel('OP (%)')
    for k in sig.curves['event_samples']:
        ax.axvline(t[k], color='k', ls='--', lw=0.9)
    ax.text(0.02, 0.95, f'{len(sig.curves["event_samples"])} slip event(s) (dashed); '
            f'{sig.details.get("jumps", 0)} PV jumps tested', transform=ax.transAxes,
            va='top', fontsize=7)


def _text(ax, sig):
    ax.axis('off')
    # Scalars only: a list of events or a nested dict would print as raw Python.
    lines = [sig.reason] + [f'{k}: {_fmt(v) if isinstance(v, float) or v is None else v}'
                            for k, v in sig.details.items()
                            if v is None or isinstance(v, (bool, int, float, str))]
    ax.text(0.02, 0.95, '\n'.join(lines), transform=ax.transAxes, va='top', fontsize=8,
            wrap=True)


def signature_figure(op, pv, sample_time, results, path, title='Stiction signatures'):
    """Save one PNG at ``path`` with a panel per Signature in the dict ``results``; return it."""
    sigs = list(results.values())
    cols = 2
    rows = max(1, math.ceil(len(sigs) / cols))
    fig = Figure(figsize=(11, 3.6 * rows))
    axes = fig.subplots(rows, cols, squeeze=False)
    for ax, sig in zip(axes.flat, sigs):
        c = sig.curves
        if 'ccf' in c:
            _horch(ax, sig)
        elif 'triangle' in c:
            _he(ax, sig)
        elif 'bic2' in c:
            _bicoherence(ax, sig)
        elif 'op_filtered' in c:
            _ellipse(ax, sig, op, pv)
        elif 'event_samples' in c:
            _slips(ax, sig, op, pv, sample_time)
        else:
            _text(ax, sig)
        _title(ax, sig)
        ax.grid(alpha=0.3)
    for ax in list(axes.flat)[len(sigs):]:
        ax.axis('off')
    fig.suptitle(f'{title} (sample time {sample_time:g} s)')
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    return path
