"""
Describing-function prediction of stiction limit cycles: an independent check.

The valve's describing function ``N(A)`` is the fundamental of its steady
response to ``A sin(wt)`` divided by ``A``; the two-parameter models are
rate-independent, so it depends on A only and is computed here numerically
from the model itself, over a finely sampled sinusoid.  The linear part is the
*sampled* loop as the simulator runs it: the controller's and the plant's
exact z-domain responses at ``z = exp(j w Ts)``, so the prediction shares no
time-stepping with the simulation.  A limit cycle satisfies
``1 + N(A) L(e^{j w Ts}) = 0``.
"""

import math

import numpy as np

from stiction_ros.sim.closed_loop import build_plant


def valve_describing_function(model, amplitude, offset=50.0, points=1000, cycles=3):
    """Return complex N(A) of ``model`` (a ValveModel) about ``offset``."""
    th = 2 * np.pi * np.arange(points * cycles) / points
    # A first cycle of large amplitude leaves the valve in the state it has
    # inside a sustained oscillation (last moved, friction loaded) instead of
    # the neutral rest state, which would need A > fs rather than A > S/2.
    amp = np.full(th.size, float(amplitude))
    amp[:points] = max(amplitude, 2.0 * sum(model.params.get(k, 0.0) for k in ('S', 'J')))
    y = model.simulate(offset + amp * np.sin(th), y0=offset)
    th, y = th[-points:], y[-points:] - offset
    b1 = 2.0 / points * float(np.sum(y * np.sin(th)))
    a1 = 2.0 / points * float(np.sum(y * np.cos(th)))
    return complex(b1, a1) / amplitude


def controller_response(cfg, z):
    """Return the sampled PID's response C(z) from error to OP (see controller.py)."""
    z = np.asarray(z, dtype=complex)
    c = cfg['controller']
    ts = cfg['sample_time']
    kc, ti, td, n = c.get('Kc', 1.0), c.get('Ti', 0.0), c.get('Td', 0.0), c.get('N', 10.0)
    out = kc * np.ones_like(z)
    if ti > 0:
        out = out + kc * ts / (ti * (z - 1.0))
    if td > 0:
        a = td / (td + n * ts)
        out = out + kc * n * a * (1 - 1 / z) / (1 - a / z)
    return out


def plant_response(cfg, z):
    """Return the discretised plant's response P(z) from MV to PV, dead time included."""
    return build_plant(cfg).frequency_response(z)


def loop_response(cfg, w):
    """Return the linear loop L = C P at angular frequencies ``w`` (rad/s)."""
    z = np.exp(1j * np.asarray(w, dtype=float) * cfg['sample_time'])
    return controller_response(cfg, z) * plant_response(cfg, z)


def _crossings(p, q):
    """Return (i, s, j, t) where segment p[i]->p[i+1] at s meets q[j]->q[j+1] at t."""
    a, b = p[:-1, None], p[1:, None]
    c, d = q[None, :-1], q[None, 1:]
    r, e = b - a, d - c
    den = r.real * e.imag - r.imag * e.real
    ca = c - a
    with np.errstate(divide='ignore', invalid='ignore'):
        s = (ca.real * e.imag - ca.imag * e.real) / den
        t = (ca.real * r.imag - ca.imag * r.real) / den
    ok = (den != 0) & (s >= 0) & (s <= 1) & (t >= 0) & (t <= 1)
    i, j = np.nonzero(ok)
    return [(int(ii), float(s[ii, jj]), int(jj), float(t[ii, jj])) for ii, jj in zip(i, j)]


def predict_limit_cycle(cfg, model, a_max=50.0, n_amplitudes=200):
    """
    Solve the harmonic balance; return a list of dicts {period, amplitude, ...}.

    Each solution is an oscillation of OP (the valve input) with the given
    amplitude; ``mv_amplitude`` and ``pv_amplitude`` are the fundamentals'
    amplitudes at the valve output and the process output.  The curves
    ``-1/N(A)`` and ``L(e^{j w Ts})`` are intersected as polylines, which is
    robust to the tiny steps a sampled N(A) has.  Empty: none predicted.
    """
    ts = cfg['sample_time']
    w_nyq = math.pi / ts
    ws = np.geomspace(1e-4 * w_nyq, 0.999 * w_nyq, 3000)
    loop = loop_response(cfg, ws)
    s_band = float(model.params.get('S', 0.0))
    amps = np.geomspace(max(s_band / 2.0, 1e-3) * 1.0005, a_max, n_amplitudes)
    nas = np.array([valve_describing_function(model, a) for a in amps])
    keep = np.abs(nas) > 1e-9
    amps, nas = amps[keep], nas[keep]
    found = []
    for i, s, j, t in _crossings(-1.0 / nas, loop):
        a = amps[i] + s * (amps[i + 1] - amps[i])
        w = ws[j] + t * (ws[j + 1] - ws[j])
        na = valve_describing_function(model, a)
        pz = plant_response(cfg, [np.exp(1j * w * ts)])[0]
        found.append({'w': w, 'period': 2 * math.pi / w, 'amplitude': a,
                      'mv_amplitude': abs(na) * a, 'pv_amplitude': float(abs(na * pz) * a)})
    return sorted(found, key=lambda f: f['amplitude'])
