"""
Closed-loop recordings with one concealed valve effect, for proving ``--explain``.

A random plant (self-regulating first order plus dead time, or integrating
with dead time) under a SIMC-tuned PI controller, set-point steps and load
steps sized to move the valve by several percent, noise on PV and MV, and a
valve carrying one effect of docs/EFFECTS.md at a size chosen to stay below
what an engineer would notice in the MV-OP map.  Two valve families: the
``kano_effects`` model (every effect, as the analyzer's own parameter), and
the force-balance ``physical`` model with the effect written as a force law
(Stribeck curve, rest-time dependent static friction, direction-dependent
friction), driven with a first-order hold so that its plain form is Kano's
model far below the MV noise (MSE 0.0005 against 0.01).
"""

import numpy as np

from stiction_ros.models.physical import Physical
from stiction_ros.resources import config_file
from stiction_ros.sim.closed_loop import simulate_loop
from stiction_ros.sim.loop_config import load_loop

# Effect sizes: (parameter, low, high) drawn uniformly.
SIZES = {
    'none': {},
    'asymmetric_friction': {'asymmetry': (0.12, 0.25)},
    'dwell_time_breakaway': {'dwell_gain': (0.25, 0.5), 'dwell_time': (30.0, 120.0)},
    'actuator_lag': {'lag_time': (2.0, 5.0)},
    'measurement_lag': {'lag_time': (2.0, 5.0)},
    'position_dependent_friction': {'position_gain': (0.25, 0.45)},
    'friction_drift': {'drift': (0.25, 0.45)},
    'stribeck_stick_slip': {'min_speed': (0.02, 0.05)},
    'presliding_creep': {'creep': (0.1, 0.2)},
}
# The effects each valve family can hide: the physical model carries three as physics.
FAMILIES = {
    'kano': tuple(SIZES),
    'physical': ('none', 'stribeck_stick_slip', 'dwell_time_breakaway', 'asymmetric_friction'),
}


def concealed_case(effect, seed, duration=8640.0, noise=1.0, integrating=None, family='kano'):
    """
    Return (record dict of simulate_loop, truth dict) for one concealed case.

    ``noise`` scales the PV and MV noise (1 = PV 1 % of a typical move, MV 0.1 %).
    """
    if family not in FAMILIES:
        raise ValueError(f'unknown valve family {family!r}; choose one of {sorted(FAMILIES)}')
    if effect not in FAMILIES[family]:
        raise ValueError(f'unknown effect {effect!r} for the {family} family; choose one of '
                         f'{sorted(FAMILIES[family])}')
    rng = np.random.default_rng(seed)
    integrating = bool(rng.integers(2)) if integrating is None else integrating
    delay = float(rng.uniform(2.0, 6.0))
    if integrating:
        K = float(rng.uniform(0.01, 0.03))
        num, den = [K], [1.0, 0.0]
        tc = 3.0 * delay
        Kc, Ti = 1.0 / (K * (tc + delay)), 4.0 * (tc + delay)
    else:
        K, tau = float(rng.uniform(0.8, 2.0)), float(rng.uniform(20.0, 60.0))
        num, den = [K], [tau, 1.0]
        tc = delay
        Kc, Ti = 0.5 * tau / (K * (tc + delay)), min(tau, 4.0 * (tc + delay))
    # Set-point steps that ask the valve for 4-12 % moves, both ways.
    move = K if not integrating else 1.0 / Kc
    t, sp, steps = 0.0, 0.0, [[0.0, 0.0]]
    while t < duration - 400.0:
        t += float(rng.uniform(300.0, 900.0))
        sp += float(rng.choice([-1, 1]) * rng.uniform(4.0, 12.0) * move)
        sp = float(np.clip(sp, -25 * move, 25 * move))
        steps.append([t, sp])
    loads = [(float(x), float(rng.choice([-1, 1]) * rng.uniform(2.0, 6.0) * move))
             for x in sorted(rng.uniform(300.0, duration - 300.0, 6))]
    S = float(rng.uniform(2.0, 5.0))
    J = float(rng.uniform(0.2, 0.6) * S)
    if family == 'physical':
        valve = physical_valve(effect, S, J, rng)
    else:
        valve = kano_valve(effect, S, J, rng, duration)
    cfg = load_loop(config_file('concentration_loop.yaml'), overrides={
        'plant.num': num, 'plant.den': den, 'plant.delay': delay,
        'controller.Kc': Kc, 'controller.Ti': Ti,
        'controller.setpoint': {'type': 'steps', 'steps': steps},
        'plant.disturbance_steps': loads, 'valve': valve,
        'noise': {'pv_std': 0.01 * 8.0 * move * noise, 'mv_std': 0.1 * noise, 'seed': seed}})
    record = simulate_loop(cfg, duration)
    truth = {'effect': effect, 'family': family, 'valve': valve, 'integrating': integrating,
             'Kc': Kc, 'Ti': Ti, 'noise': noise, 'seed': seed}
    return record, truth


def kano_valve(effect, S, J, rng, duration):
    """Return the valve settings of a ``kano_effects`` valve hiding ``effect``."""
    valve = {'model': 'kano_effects', 'S': S, 'J': J, 'effect': effect}
    for name, (lo, hi) in SIZES[effect].items():
        value = float(rng.uniform(lo, hi))
        if name in ('asymmetry', 'position_gain', 'drift'):
            value *= float(rng.choice([-1, 1]))
        valve[name] = value
    if effect == 'friction_drift':
        valve['drift_span'] = duration
    if effect == 'position_dependent_friction':
        valve['position_ref'] = 50.0
    return valve


# The chapter's valve (MODELS.md) with the spring and preload set so that the stem
# follows the input one to one once sliding (gain 1, offset 0, as Kano's model
# assumes), a light viscous term and a fast I/P, so that the plain valve is Kano's
# model up to far less than the MV noise.
PHYSICAL_SIZES = {
    'none': {},
    'stribeck_stick_slip': {'vs': (4e-6, 1.2e-5)},
    'dwell_time_breakaway': {'dwell_gain': (0.25, 0.5), 'gamma': (30.0, 120.0)},
    'asymmetric_friction': {'asym': (0.12, 0.25)},
}


def physical_valve(effect, S, J, rng):
    """
    Return the settings of a force-balance valve with Kano-equivalent S and J hiding ``effect``.

    The effect is written as physics: a Stribeck curve (``vs``), static
    friction that grows with rest time (``dFs``, ``gamma``), or friction forces
    that differ by direction (``asym``).
    """
    A, p_min, p_max, x_max = (Physical.PARAMS[k][0] for k in ('A', 'p_min', 'p_max', 'x_max'))
    span = A * (p_max - p_min)
    Fs = 0.5 * (S + J) / 100.0 * span
    Fc = 0.5 * (S - J) / 100.0 * span
    valve = {'model': 'physical', 'k': span / x_max, 'F0': A * p_min, 'Fs': Fs, 'Fc': Fc,
             'Fv': 2500.0, 'tau_ip': 0.01, 'hold': 'foh', 'integrator': 'substep',
             'substep': 1e-4}
    sizes = {k: float(rng.uniform(lo, hi)) for k, (lo, hi) in PHYSICAL_SIZES[effect].items()}
    if effect == 'stribeck_stick_slip':
        valve.update(stribeck=True, vs=sizes['vs'])
    elif effect == 'dwell_time_breakaway':
        valve.update(dFs=sizes['dwell_gain'] * Fs, gamma=sizes['gamma'])
    elif effect == 'asymmetric_friction':
        valve['asym'] = sizes['asym'] * float(rng.choice([-1, 1]))
    return valve
