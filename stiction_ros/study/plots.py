"""Figures in the style of the chapter's Fig. 2.3: time trends and MV-OP / PV-OP maps."""

# Figure draws without pyplot and needs no backend: importing this module leaves the
# caller's matplotlib as it was, and no figure outlives its function.
from matplotlib.figure import Figure


def loop_figure(data, title, path, window=600.0):
    """Save a 2x2 figure: OP/MV and OP/PV trends of the last ``window`` s, both maps; return it."""
    t = data['t']
    keep = t >= t[-1] - window
    fig = Figure(figsize=(10, 6.5))
    ax = fig.subplots(2, 2, gridspec_kw={'width_ratios': [2.2, 1]})
    for row, (name, label) in enumerate((('mv', 'MV (valve position)'),
                                         ('pv', 'PV (process output)'))):
        a = ax[row, 0]
        a.plot(t[keep], data['op'][keep], lw=0.9, color='tab:blue', label='OP (controller output)')
        a.plot(t[keep], data[name][keep], lw=2.0, color='tab:red', label=label)
        a.set_xlabel('time (s)')
        a.set_ylabel('%' if name == 'mv' else 'PV')
        a.legend(loc='upper right', fontsize=8)
        a.grid(alpha=0.3)
        m = ax[row, 1]
        m.plot(data['op'][keep], data[name][keep], lw=1.0, color='k')
        m.set_xlabel('OP')
        m.set_ylabel(name.upper())
        m.set_title(f'{name.upper()}-OP map', fontsize=9)
        m.grid(alpha=0.3)
    ax[0, 0].set_title('(a) OP and MV', fontsize=9)
    ax[1, 0].set_title('(b) OP and PV', fontsize=9)
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    return path


def mv_op_figure(op, mv, title, path, op_label='OP (%)', mv_label='MV (%)'):
    """Save one MV-OP map (e.g. of the physical valve under a slow sinusoid); return ``path``."""
    fig = Figure(figsize=(5, 4.5))
    a = fig.subplots()
    a.plot(op, mv, lw=1.0, color='k')
    a.set_xlabel(op_label)
    a.set_ylabel(mv_label)
    a.set_title(title, fontsize=10)
    a.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    return path


def shared_cycles_figure(rows, gap, floor, path):
    """
    Save the two loops' stiction probabilities of every pair (``study.shared_cycles``).

    Pairs that share a cycle are coloured by the source the view named; the
    band of width ``gap`` about the diagonal, and below ``floor`` on both
    axes (dotted), is where it names none.
    """
    fig = Figure(figsize=(5.5, 5))
    a = fig.subplots()
    colour = {'up': 'tab:green', 'down': 'tab:red', '': 'tab:orange'}
    word = {'up': 'shared: sticky loop named', 'down': 'shared: healthy loop named',
            '': 'shared: source not told'}
    alone = [r for r in rows if r['source'] == 'none' and None not in (r['up_p'], r['down_p'])]
    a.scatter([r['down_p'] for r in alone], [r['up_p'] for r in alone], s=8, color='0.75',
              label='no shared cycle')
    for key in ('up', 'down', ''):
        got = [r for r in rows if r['source'] == key]
        if got:
            a.scatter([r['down_p'] for r in got], [r['up_p'] for r in got], s=22,
                      color=colour[key], label=f'{word[key]} ({len(got)})')
    a.fill_between([0, 1], [-gap, 1 - gap], [gap, 1 + gap], color='0.9', zorder=0)
    a.axhline(floor, color='0.5', ls=':', lw=1)
    a.axvline(floor, color='0.5', ls=':', lw=1)
    a.set_xlim(-0.02, 1.02)
    a.set_ylim(-0.02, 1.02)
    a.set_xlabel('healthy loop carrying the cycle: stiction probability')
    a.set_ylabel('sticky loop: stiction probability')
    a.legend(fontsize=7, loc='lower right')
    a.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    return path
