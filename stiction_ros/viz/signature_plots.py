"""
One figure of the stiction signatures, a panel each, to check every verdict by eye.

Panels: Horch's CCF with the zero crossings either side of lag 0 (Horch
1999, Control Eng. Practice 7, 1221-1231); He et al.'s sine and triangle
fits per half-cycle (2007, Ind. Eng. Chem. Res. 46, 4549-4560); the squared
bicoherence map (Choudhury, Shah and Thornhill 2004, Automatica 40,
1719-1728); the PV-OP map with its fitted ellipse and apparent stiction
(Choudhury et al. 2006, Control Eng. Practice 14, 1395-1412).  Signatures
without curves share one text panel.  Each title says in words what the
value measures, the value against its threshold, the verdict, and, when
undetermined, why.  Times are the record's, from its start.
"""

import math
import textwrap

# Figure draws without pyplot and needs no backend: importing this module leaves the
# caller's matplotlib as it was, and no figure outlives its function.
from matplotlib.figure import Figure
import numpy as np

from stiction_ros.viz.signature_words import SIGNATURES

VERDICT = {True: 'stiction', False: 'no stiction', None: 'undetermined'}
PV_UNITS = 'PV units'
COLOUR = {True: 'tab:red', False: 'tab:green', None: 'tab:gray'}


def _fmt(v):
    return 'n/a' if v is None or not math.isfinite(v) else f'{v:.3g}'


def _with_unit(v, unit):
    return _fmt(v) + ('' if not unit or _fmt(v) == 'n/a' else
                      '\u00b0' if unit == 'deg' else f' {unit}')


def headline(sig) -> str:
    """Return one line: what the value is, value against threshold, and the verdict."""
    what, unit, way = SIGNATURES.get(sig.name, ('value', '', 'vs'))
    rule = '' if sig.threshold is None else f' (stiction {way} {_with_unit(sig.threshold, unit)})'
    extra = ''
    if sig.name == 'bicoherence' and 'ngi' in sig.details:
        # Both indices decide, so both go in the title.
        extra = f", NGI {_fmt(sig.details['ngi'])} (> {sig.details['ngi_min']})"
    return (f'{sig.name}: {what} {_with_unit(sig.value, unit)}{rule}{extra} \u2192 '
            f'{VERDICT[sig.stiction]}')


def _title(ax, sig):
    text = textwrap.fill(headline(sig), 70)
    if sig.stiction is None and sig.reason:
        # An undetermined panel still draws its curves; the title says why they do not decide.
        text += '\n' + textwrap.fill(sig.reason, 70, max_lines=2, placeholder=' ...')
    ax.set_title(text, fontsize=8, color=COLOUR[sig.stiction])


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


def _broken(t, *ys, step):
    """Return ``t`` and ``ys`` with NaN between pieces more than a sample and a half apart."""
    cut = np.flatnonzero(np.diff(t) > 1.5 * step) + 1
    return [np.insert(np.asarray(v, dtype=float), cut, np.nan) for v in (t, *ys)]


def _he(ax, sig, t0, sample_time):
    c = sig.curves
    starts = c['starts_s']
    first = starts[max(len(starts) - 8, 0)]
    keep = c['t'] >= first
    fit = c['t_fit'] >= first
    ax.plot(t0 + c['t'][keep], c['x'][keep], color='k', lw=1.6, label=c['signal'].upper())
    # Half-cycles the fit skipped are left open, not bridged by a straight chord.
    tf, sine, tri = _broken(t0 + c['t_fit'][fit], c['sine'][fit], c['triangle'][fit],
                            step=sample_time)
    ax.plot(tf, sine, color='tab:blue', lw=1.0, label='sine fit')
    ax.plot(tf, tri, color='tab:red', lw=1.0, ls='--', label='triangle fit')
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
            ha='right', va='top', fontsize=7, color='k',
            bbox={'facecolor': 'w', 'alpha': 0.8, 'lw': 0})
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
    ax.legend(fontsize=7, loc='best', framealpha=0.5)
    ax.set_xlabel('OP (%)')
    ax.set_ylabel('dPV/dt (PV units/s)' if sig.details.get('pv_signal') == 'dPV/dt'
                  else f'PV ({PV_UNITS})')


def _slips(ax, sig, op, pv, sample_time, t0):
    t = t0 + np.arange(len(pv)) * sample_time
    lines = ax.plot(t, pv, color='tab:red', lw=0.6, label='PV')
    ax.set_ylabel(f'PV ({PV_UNITS})')
    right = ax.twinx()
    lines += right.plot(t, op, color='tab:blue', lw=0.8, label='OP')
    right.set_ylabel('OP (%)')
    events = sig.curves['event_samples']
    for k in events:
        ax.axvline(t[k], color='k', ls='--', lw=0.9)
    ax.set_xlabel(f'time (s); dashed: {len(events)} slip event(s) of '
                  f'{sig.details.get("jumps", 0)} PV jumps tested')
    ax.legend(lines, [ln.get_label() for ln in lines], fontsize=7, loc='upper right',
              framealpha=0.5)


def _text(ax, sigs):
    ax.axis('off')
    lines = []
    for sig in sigs:
        lines.append(textwrap.fill(headline(sig), 80, subsequent_indent='    '))
        if sig.reason:
            lines.append(textwrap.fill(sig.reason, 80, initial_indent='  ',
                                       subsequent_indent='  '))
    ax.set_title('signatures without a picture', fontsize=8)
    ax.text(0.0, 1.0, '\n'.join(lines), transform=ax.transAxes, va='top', fontsize=7)


def _drawn(sig) -> bool:
    drawn = ('ccf', 'triangle', 'bic2', 'op_filtered', 'event_samples')
    return any(k in sig.curves for k in drawn)


def signature_figure(op, pv, sample_time, results, path, title='Stiction signatures',
                     t0: float = 0.0):
    """
    Save one PNG at ``path`` with a panel per Signature in the dict ``results``; return it.

    ``op`` and ``pv`` are the stretch the signatures read, which starts ``t0``
    seconds into the record.
    """
    fig = signature_panels(op, pv, sample_time, results, title, t0)
    fig.savefig(path, dpi=90)
    return path


def signature_panels(op, pv, sample_time, results, title='Stiction signatures',
                     t0: float = 0.0) -> Figure:
    """Return the figure :func:`signature_figure` saves."""
    drawn = [s for s in results.values() if _drawn(s)]
    rest = [s for s in results.values() if not _drawn(s)]
    cols = 2
    panels = len(drawn) + (1 if rest else 0)
    rows = max(1, math.ceil(panels / cols))
    fig = Figure(figsize=(11, 3.8 * rows))
    axes = fig.subplots(rows, cols, squeeze=False)
    for ax, sig in zip(axes.flat, drawn):
        c = sig.curves
        if 'ccf' in c:
            _horch(ax, sig)
        elif 'triangle' in c:
            _he(ax, sig, t0, sample_time)
        elif 'bic2' in c:
            _bicoherence(ax, sig)
        elif 'op_filtered' in c:
            _ellipse(ax, sig, op, pv)
        else:
            _slips(ax, sig, op, pv, sample_time, t0)
        _title(ax, sig)
        ax.grid(alpha=0.3)
    if rest:
        _text(list(axes.flat)[len(drawn)], rest)
    for ax in list(axes.flat)[panels:]:
        ax.axis('off')
    fig.suptitle(f'{title} (sample time {sample_time:g} s)')
    fig.tight_layout()
    return fig
