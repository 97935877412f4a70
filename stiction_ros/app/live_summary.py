"""
Summarise a recorded live loop and compare it with the offline simulator.

Each node publishes sample ``k`` at ``(k + phase) Ts`` (plant 1/4,
controller 1/2, valve 3/4); the recorder stamps the message with its own
clock on arrival, which may lag or lead that by a quarter sample.  So
``round(t / Ts - phase)`` puts every message on the sample grid; a sample
with no message is a gap and is reported, never filled.  Pure numpy: runs on the bag without ROS.
"""

import math

import numpy as np
from stiction_ros.analysis.measures.limit_cycle import measure_oscillation
from stiction_ros.analysis.readers.bag_signals import EPOCH_LIKE
from stiction_ros.bag.reader import BagReadError
from stiction_ros.sim.closed_loop import simulate_loop
from stiction_ros.sim.ros_params import PHASES

SIGNALS = ('sp', 'op', 'mv', 'pv')
PUBLISHER = {'sp': 'controller', 'op': 'controller', 'mv': 'valve', 'pv': 'plant'}


def on_grid(topic, sample_time, phase=0.5):
    """Return ``(k, values)`` of a Float64 topic: sample numbers and values (last per sample)."""
    k = np.round(topic.times() / sample_time - phase).astype(np.int64)
    values = topic.values()
    keep = np.append(k[1:] != k[:-1], True) if len(k) else np.zeros(0, bool)
    return k[keep], values[keep]


def summarise(bag, cfg):
    """Return a dict: per-signal counts, gaps, live and offline oscillation, sample agreement."""
    ts = float(cfg['sample_time'])
    out = {'sample_time': ts, 'complete': bag.complete, 'warnings': list(bag.warnings),
           'messages': {}, 'signals': {}}
    grids = {}
    for name in SIGNALS:
        try:
            topic = bag.topic(name)
        except BagReadError as err:
            # A loop killed before a node published, or a bag of other topics: the
            # signals that are there are still summarised, and the gap is named.
            out['warnings'].append(f'{name}: {err}')
            continue
        out['messages'][topic.name] = topic.count
        k, v = on_grid(topic, ts, PHASES[PUBLISHER[name]])
        if len(k):
            grids[name] = (k, v)
        else:
            out['warnings'].append(f'{name}: {topic.name} has no message')
    if not grids:
        return out
    first = max(int(k[0]) for k, _ in grids.values())
    last = min(int(k[-1]) for k, _ in grids.values())
    n = max(last - first + 1, 0)
    out['samples'] = {'first': first, 'last': last}
    # On wall time the samples are counted from 1970, and the profiles of the loop
    # file began long before the run: there is no offline run to compare with.
    wall = last * ts > EPOCH_LIKE
    if wall:
        out['offline'] = 'none: a wall-time run'
    offline = simulate_loop(cfg, duration=last * ts) if n and not wall else None
    for name, (k, v) in grids.items():
        sel = (k >= first) & (k <= last)
        kk, vv = k[sel], v[sel]
        gaps = n - len(kk)
        live = measure_oscillation(vv, ts)
        entry = {'gaps': int(gaps), 'live': _osc(live)}
        if offline is not None:
            ref = offline[name][kk]
            off = measure_oscillation(offline[name][first:last + 1], ts)
            entry['offline'] = _osc(off)
            diff = np.abs(vv - ref)
            entry['max_abs_difference'] = float(np.max(diff)) if len(vv) else None
            # Where the live run left its twin: the first sample is the clue to why (a node
            # that acted on a held input there, a message put on the wrong sample).
            off_at = np.flatnonzero(diff > 0)
            entry['first_difference_s'] = float(kk[off_at[0]] * ts) if len(off_at) else None
            if live.oscillating and off.oscillating:
                entry['period_error'] = live.period / off.period - 1.0
                entry['amplitude_error'] = live.amplitude / off.amplitude - 1.0
        out['signals'][name] = entry
    return out


def _osc(o):
    d = o.as_dict()
    return {k: (None if isinstance(v, float) and not math.isfinite(v) else v)
            for k, v in d.items()}


def format_summary(s):
    """Return a short human-readable table of :func:`summarise` output."""
    lines = []
    counts = ', '.join(f'{n} {c}' for n, c in s['messages'].items())
    lines.append(f'messages recorded: {counts}')
    if 'samples' in s:
        lines.append(f'samples {s["samples"]["first"]}..{s["samples"]["last"]} '
                     f'at {s["sample_time"]} s')
    lines.append(f'{"signal":6} {"period live":>12} {"offline":>8} {"error":>7} '
                 f'{"amp live":>9} {"offline":>8} {"error":>7} {"max |diff|":>10} gaps')
    for name, e in s['signals'].items():
        lv, of = e['live'], e.get('offline', {})
        lines.append(
            f'{name:6} {_num(lv["period"] if lv["oscillating"] else None):>12} '
            f'{_num(of.get("period") if of.get("oscillating") else None):>8} '
            f'{_pct(e.get("period_error")):>7} '
            f'{_num(lv["amplitude"]):>9} {_num(of.get("amplitude")):>8} '
            f'{_pct(e.get("amplitude_error")):>7} '
            f'{_num(e.get("max_abs_difference"), 4):>10} {e["gaps"]}')
    departed = [f'{name} at {_seconds(e["first_difference_s"])} s'
                for name, e in s['signals'].items() if e.get('first_difference_s') is not None]
    if departed:
        lines.append(f'first difference from the offline run: {", ".join(departed)}')
    for w in s['warnings']:
        lines.append(f'warning: {w}')
    return '\n'.join(lines)


def _seconds(x):
    # 37, 0.05 or 1234567: never 1.23457e+06 for a long run.
    return f'{x:.3f}'.rstrip('0').rstrip('.')


def _pct(x):
    return '-' if x is None else f'{100 * x:+.1f}%'


def _num(x, digits=2):
    if x is None:
        return '-'
    # A value a stray publisher put on a topic (1e300) in three figures, not 300 digits.
    return f'{x:.3g}' if abs(x) >= 1e6 else f'{x:.{digits}f}'
