"""
Choudhury et al. (2005) two-parameter stiction model (chapter Fig. 2.2, eq. 2.4).

The full signal path of Fig. 2.2: optional EWMA prefilter (eq. 2.5, ``lam``),
4-20 mA to % look-up, saturation (fully closed / fully open), the stick-slip
logic driven by the sign of the input slope, and the valve's flow
characteristic on the output (optionally converted back to mA).

Where the chapter's flow chart is ambiguous we follow the physics, as Kano's
model does: the stick point ``x_ss`` is fixed when a *moving* valve sticks, and
a stuck valve moves again once the input has travelled more than J in the
direction it last moved or more than S the other way.  This is the chapter's
"I = 1 uses J, a reversal uses S" rule, except that an input which stops and
then turns back must still overcome S.
"""

import math

from stiction_ros.kernels.arrays import Floats
from stiction_ros.kernels.characteristics import (
    apply_characteristic, characteristic_code, CHARACTERISTICS, invert_characteristic,
    ma_to_percent, percent_to_ma, UNITS)
from stiction_ros.kernels.loop_kinds import CHOUDHURY, loop_args, LoopArgs
from stiction_ros.kernels.valves import choudhury_run
from stiction_ros.models.base import ValveModel
from stiction_ros.models.breakaway import breakaway

# state layout: output, stem position, filtered input x (k-1), sign of the
# previous slope, stick point x_ss, stuck flag, last direction of motion
# (0 = at rest with no friction force stored), EWMA filter output.
_Y, _POS, _XPREV, _SPREV, _XSS, _STUCK, _DIR, _XF = range(8)


class Choudhury(ValveModel):
    """Choudhury's model: sign-of-slope stick detection, S/J breakaway, eq. 2.4."""

    name = 'choudhury'
    PARAMS = {
        'S': (0.0, 0.0, 100.0, 'deadband plus stickband, % of input span'),
        'J': (0.0, 0.0, 100.0, 'slip jump, % of output span'),
        'lam': (1.0, 1e-6, 1.0, 'EWMA prefilter weight lambda of eq. 2.5 (1 = no filter)'),
        'input_units': ('percent', 'choice', UNITS, 'units of the valve input'),
        'output_units': ('percent', 'choice', UNITS, 'units of the reported output'),
        'characteristic': ('linear', 'choice', CHARACTERISTICS, 'flow characteristic'),
        'rangeability': (50.0, 1.5, 1000.0, 'rangeability R of the equal-percentage curve'),
    }

    def _on_params_changed(self) -> None:
        self._char = characteristic_code(self._params['characteristic'])
        self._ma_in = self._params['input_units'] == 'mA'
        self._ma_out = self._params['output_units'] == 'mA'

    def _to_percent(self, u: float) -> float:
        return ma_to_percent(u) if self._ma_in else u

    def rest_input(self, y0: float) -> float:
        """Return the input (its units) that holds the stem where the output is ``y0``."""
        flow = ma_to_percent(y0) if self._ma_out else y0
        pos = invert_characteristic(self._char, flow, self._params['rangeability'])
        return percent_to_ma(pos) if self._ma_in else pos

    def _initial_state(self, u0: float, y0: float | None) -> list[float]:
        x0 = self._to_percent(u0)
        if y0 is None:
            pos = min(max(x0, 0.0), 100.0)
        else:
            flow = ma_to_percent(y0) if self._ma_out else y0
            pos = invert_characteristic(self._char, flow, self._params['rangeability'])
        st = [0.0, pos, x0, 0.0, x0, 1.0, 0.0, x0]
        st[_Y] = self._output(pos)
        return st

    def _output(self, pos: float) -> float:
        flow = apply_characteristic(self._char, pos, self._params['rangeability'])
        return percent_to_ma(flow) if self._ma_out else flow

    def _run(self, u: Floats, y: Floats, st: Floats) -> None:
        p = self._params
        choudhury_run(u, y, st, p['S'], p['J'], p['lam'], self._ma_in, self._char,
                      p['rangeability'], self._ma_out)

    def loop_args(self) -> LoopArgs:
        """Return the compiled loop's arguments for this valve."""
        p = self._params
        return loop_args(CHOUDHURY, (p['S'], p['J'], p['lam'], float(self._ma_in), self._char,
                                     p['rangeability'], float(self._ma_out)))

    def _run_reference(self, u: Floats, y: Floats, st: Floats) -> None:
        p = self._params
        lam = p['lam']
        for k in range(len(u)):
            x = lam * self._to_percent(u[k]) + (1.0 - lam) * st[_XF]
            st[_XF] = x
            choudhury_logic(x, st, p['S'], p['J'])
            st[_Y] = self._output(st[_POS])
            y[k] = st[_Y]


def choudhury_logic(x: float, st: Floats, S: float, J: float) -> None:
    """Advance the stick-slip logic one sample for filtered input ``x`` (%)."""
    fd = 0.5 * (S - J)
    dx = x - st[_XPREV]
    s = 0.0 if dx == 0.0 else math.copysign(1.0, dx)
    if x <= 0.0 or x >= 100.0:
        # Saturated: resting on an end stop as if it had just moved there, so
        # leaving the stop takes the static band and ends in a slip jump J.
        d = -1.0 if x <= 0.0 else 1.0
        st[_POS] = 0.0 if x <= 0.0 else 100.0
        st[_STUCK] = 1.0
        st[_DIR] = d
        st[_XSS] = st[_POS] + d * fd
    else:
        if st[_STUCK] == 0.0 and s != st[_SPREV]:
            st[_STUCK] = 1.0
            st[_XSS] = st[_XPREV]
        if st[_STUCK] == 1.0:
            d = breakaway(st[_DIR], x - st[_XSS], S, J)
            if d != 0.0:
                st[_DIR] = d
                st[_STUCK] = 0.0
        if st[_STUCK] == 0.0:
            pos = x - st[_DIR] * fd
            st[_POS] = 0.0 if pos < 0.0 else 100.0 if pos > 100.0 else pos
    st[_SPREV] = s
    st[_XPREV] = x
