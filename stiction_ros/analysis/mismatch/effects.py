"""
The candidate physics of docs/EFFECTS.md: parameters, grids and the sentence an engineer reads.

Each effect turns on one or two entries of the kernel's parameter vector;
at zero it is Kano's plain model.  ``grid`` lists the values the fit tries
(a coarse grid that the fit refines around its best point); ``sentence``
turns fitted values into what the engineer can act on.
"""

from dataclasses import dataclass
import math

import numpy as np

from stiction_ros.kernels import kano_effects as kk


@dataclass(frozen=True)
class Context:
    """What the parameter vectors depend on: sampling, fitted part, operating point."""

    sample_time: float
    n_fit: int
    position_ref: float


@dataclass(frozen=True)
class Effect:
    """One candidate: its id, parameter names, grid and the vector it sets."""

    eid: str
    names: tuple
    grid: object          # Context -> list of parameter tuples
    vector: object        # (tuple, Context) -> kernel parameter vector
    sentence: object      # (dict of params, S, J) -> str


def _pole(tau_s, ts):
    return math.exp(-ts / tau_s) if tau_s > 0.0 else 0.0


def _lags(ctx):
    return [(float(t),) for t in np.geomspace(0.5 * ctx.sample_time, 40 * ctx.sample_time, 14)]


def _vec(**entries):
    def make(theta, ctx):
        p = kk.plain_params()
        p[kk.POS_REF] = ctx.position_ref
        p[kk.DRIFT_MID] = 0.5 * ctx.n_fit
        p[kk.DRIFT_SPAN] = float(ctx.n_fit)
        for (index, convert), value in zip(entries.values(), theta):
            p[index] = convert(value, ctx)
        return p
    return make


def _same(v, ctx):
    return float(v)


def _pole_of(v, ctx):
    return _pole(v, ctx.sample_time)


def _samples_of(v, ctx):
    return float(v) / ctx.sample_time


def _asym_sentence(q, S, J):
    a = q['asymmetry']
    # The model scales every friction force by 1 + a opening and 1 - a closing; said as
    # "x % higher" (their ratio) it read as the breakaway's difference, which is smaller.
    more, less = ('opening', 'closing') if a > 0 else ('closing', 'opening')
    return (f'The friction forces are {1 + abs(a):.2f} times their mean {more} and '
            f'{1 - abs(a):.2f} times {less} '
            f'(packing whose friction depends on the direction of travel, such as V-rings): '
            f'after a reversal the valve needs '
            f'{S + a * J:.2f} % of OP to start opening but {S - a * J:.2f} % to start closing, '
            f'and jumps {J * (1 + a):.2f} % against {J * (1 - a):.2f} %.')


def _dwell_sentence(q, S, J):
    return (f'Breakaway needs up to {100 * q["gain"]:.0f} % more OP travel after long rests '
            f'(half of it after {q["time_constant_s"]:.0f} s at rest): dwell-time dependent '
            'static friction.')


def _act_sentence(q, S, J):
    return (f'The valve follows OP through a lag of {q["time_constant_s"]:.1f} s before friction '
            'acts: actuator or positioner dynamics (air chamber), so breakaway comes later '
            'the faster OP moves.')


def _meas_sentence(q, S, J):
    return (f'The position reading lags the stem by {q["time_constant_s"]:.1f} s: transmitter '
            'or filter lag after the friction; the valve itself breaks away on time.')


def _pos_sentence(q, S, J):
    g = q['gain_per_50pct']
    return (f'Friction is {100 * abs(g):.0f} % higher per 50 % of travel toward '
            f'{"open" if g > 0 else "closed"}: the packing is tighter in part of the stroke.')


def _drift_sentence(q, S, J):
    g = q['change_over_fit']
    return (f'Friction {"rose" if g > 0 else "fell"} by {100 * abs(g):.0f} % over the fitted '
            'part of the record: wear, a packing adjustment or temperature.')


def _stribeck_sentence(q, S, J):
    return (f'The valve sticks again whenever OP moves slower than {q["min_speed_pct_s"]:.3g} %/s '
            'while still driven the same way: velocity-weakening (Stribeck) friction.')


def _creep_sentence(q, S, J):
    return (f'While the model says stuck, the position follows {100 * q["fraction"]:.0f} % of '
            "OP's movement and gives it back on reversal: pre-sliding (elastic) deflection "
            'of packing and stem.')


EFFECTS = (
    Effect('asymmetric_friction', ('asymmetry',),
           lambda ctx: [(float(a),) for a in np.linspace(-0.45, 0.45, 19) if abs(a) > 1e-9],
           _vec(a=(kk.ASYM, _same)), _asym_sentence),
    Effect('dwell_time_breakaway', ('gain', 'time_constant_s'),
           lambda ctx: [(float(g), float(t * ctx.sample_time))
                        for t in (5.0, 15.0, 40.0, 100.0, 250.0)
                        for g in (0.05, 0.1, 0.2, 0.3, 0.45, 0.6, 0.8)],
           _vec(g=(kk.DWELL, _same), t=(kk.DWELL_TAU, _samples_of)), _dwell_sentence),
    Effect('actuator_lag', ('time_constant_s',), _lags, _vec(t=(kk.A_IN, _pole_of)),
           _act_sentence),
    Effect('measurement_lag', ('time_constant_s',), _lags, _vec(t=(kk.B_OUT, _pole_of)),
           _meas_sentence),
    Effect('position_dependent_friction', ('gain_per_50pct',),
           lambda ctx: [(float(a),) for a in np.linspace(-0.6, 0.6, 17) if abs(a) > 1e-9],
           _vec(a=(kk.POS, _same)), _pos_sentence),
    Effect('friction_drift', ('change_over_fit',),
           lambda ctx: [(float(a),) for a in np.linspace(-0.6, 0.6, 17) if abs(a) > 1e-9],
           _vec(a=(kk.DRIFT, _same)), _drift_sentence),
    Effect('stribeck_stick_slip', ('min_speed_pct_s',),
           lambda ctx: [(float(v / ctx.sample_time),) for v in np.geomspace(0.003, 5.0, 18)],
           _vec(v=(kk.STRIBECK, lambda v, ctx: float(v) * ctx.sample_time)),
           _stribeck_sentence),
    Effect('presliding_creep', ('fraction',),
           lambda ctx: [(float(c),) for c in np.linspace(0.02, 0.5, 13)],
           _vec(c=(kk.CREEP, _same)), _creep_sentence),
)
BY_ID = {e.eid: e for e in EFFECTS}
IDS = tuple(BY_ID) + ('none', 'unexplained')
