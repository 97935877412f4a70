"""
Kano's model with one of the concealed physical effects of docs/EFFECTS.md.

The simulator's valve for the model-mismatch benchmark and demo: the same
compiled step the analyzer fits (``stiction_ros.analysis.mismatch``), so
``effect='none'`` is Kano's model sample for sample.  Parameters are the
effect's own (see ``EFFECTS``); unused ones are ignored.
"""

import math

import numpy as np

from stiction_ros.kernels import kano_effects as kk
from stiction_ros.kernels.arrays import Floats
from stiction_ros.kernels.loop_kinds import KANO_EFFECTS, loop_args, LoopArgs
from stiction_ros.models.base import ValveModel

EFFECTS = ('none', 'asymmetric_friction', 'dwell_time_breakaway', 'actuator_lag',
           'measurement_lag', 'position_dependent_friction', 'friction_drift',
           'stribeck_stick_slip', 'presliding_creep')


class KanoEffects(ValveModel):
    """Kano's state machine plus one effect, switched on by ``effect`` and its size."""

    name = 'kano_effects'
    PARAMS = {
        'S': (0.0, 0.0, 100.0, 'deadband plus stickband, % of input span'),
        'J': (0.0, 0.0, 100.0, 'slip jump, % of output span'),
        'effect': ('none', 'choice', EFFECTS, 'which physics to add'),
        'asymmetry': (0.0, -0.9, 0.9, 'friction forces times 1 +/- this opening/closing'),
        'dwell_gain': (0.0, 0.0, 5.0, 'static band growth after long rests, fraction of S'),
        'dwell_time': (30.0, 1e-6, 1e6, 'rest time for half the growth, s'),
        'lag_time': (0.0, 0.0, 1e6, 'actuator or measurement lag, s'),
        'position_gain': (0.0, -0.9, 0.9, 'relative friction change per 50 % of travel'),
        'position_ref': (50.0, 0.0, 100.0, 'position where friction is nominal, %'),
        'drift': (0.0, -0.9, 0.9, 'relative friction change over drift_span'),
        'drift_span': (3600.0, 1e-6, 1e9, 's over which the drift applies'),
        'min_speed': (0.0, 0.0, 100.0, 'Stribeck: sticks again below this OP speed, %/s'),
        'creep': (0.0, 0.0, 0.9, 'pre-sliding: share of OP movement followed while stuck'),
        'sample_time': (1.0, 1e-6, 1e6, 'sample time, s'),
    }

    def _on_params_changed(self) -> None:
        q = self._params
        p = kk.plain_params()
        ts = q['sample_time']
        e = q['effect']
        lag = math.exp(-ts / q['lag_time']) if q['lag_time'] > 0 else 0.0
        if e == 'asymmetric_friction':
            p[kk.ASYM] = q['asymmetry']
        elif e == 'dwell_time_breakaway':
            p[kk.DWELL], p[kk.DWELL_TAU] = q['dwell_gain'], q['dwell_time'] / ts
        elif e == 'actuator_lag':
            p[kk.A_IN] = lag
        elif e == 'measurement_lag':
            p[kk.B_OUT] = lag
        elif e == 'position_dependent_friction':
            p[kk.POS], p[kk.POS_REF] = q['position_gain'], q['position_ref']
        elif e == 'friction_drift':
            # Centred on the middle of the span, as the fit centres it on its data.
            p[kk.DRIFT], p[kk.DRIFT_SPAN] = q['drift'], q['drift_span'] / ts
            p[kk.DRIFT_MID] = 0.5 * p[kk.DRIFT_SPAN]
        elif e == 'stribeck_stick_slip':
            p[kk.STRIBECK] = q['min_speed'] * ts
        elif e == 'presliding_creep':
            p[kk.CREEP] = q['creep']
        self._p = p

    def _initial_state(self, u0: float, y0: float | None) -> list[float]:
        uc = min(max(u0, 0.0), 100.0)
        y = uc if y0 is None else y0
        return [y, uc, uc, uc, 1.0, 0.0, y, u0, 0.0, y, 0.0]

    def loop_args(self) -> LoopArgs:
        """Return the compiled loop's arguments for this valve."""
        return loop_args(KANO_EFFECTS, (self._params['S'], self._params['J']), self._p)

    def _run(self, u: Floats, y: Floats, st: Floats) -> None:
        kk.kano_effects_run(np.ascontiguousarray(u), y, st, self._params['S'],
                            self._params['J'], self._p)
