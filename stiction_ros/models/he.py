"""
He et al. (2007) cumulative-force stiction model.

A residual force ``u_r`` (in input units) accumulates the input increments
while the valve is stuck: ``c = u_r + u(k) - u(k-1)``.  The valve moves when
``|c| > fs`` and then sits ``fd`` behind the input, ``y = u - sign(c) fd``,
with ``u_r = sign(c) fd`` left over.  ``fs = (S + J)/2`` and ``fd = (S - J)/2``
so that S and J mean what they mean in Kano's and Choudhury's models.
With J > S, ``fd`` is negative: the valve moves ahead of its input, the
overshoot case of Choudhury et al. (2005) (Table 2.1's S 5, J 7), as the
other two models do; the tests measure S and J back from a slow sine for it.
"""

import math

from stiction_ros.kernels.arrays import Floats
from stiction_ros.kernels.loop_kinds import HE, loop_args, LoopArgs
from stiction_ros.kernels.valves import he_run
from stiction_ros.models.base import ValveModel

_Y, _UPREV, _UR = range(3)


class He(ValveModel):
    """He's model: breakaway when the accumulated force exceeds static friction."""

    name = 'he'
    PARAMS = {
        'S': (0.0, 0.0, 100.0, 'deadband plus stickband, % of input span'),
        'J': (0.0, 0.0, 100.0, 'slip jump, % of output span'),
    }

    def _initial_state(self, u0: float, y0: float | None) -> list[float]:
        uc = min(max(u0, 0.0), 100.0)
        return [uc if y0 is None else y0, uc, 0.0]

    def _run(self, u: Floats, y: Floats, st: Floats) -> None:
        he_run(u, y, st, self._params['S'], self._params['J'])

    def loop_args(self) -> LoopArgs:
        """Return the compiled loop's arguments for this valve."""
        return loop_args(HE, (self._params['S'], self._params['J']))

    def _run_reference(self, u: Floats, y: Floats, st: Floats) -> None:
        he_kernel(u, y, st, self._params['S'], self._params['J'])


def he_kernel(u: Floats, y: Floats, st: Floats, S: float, J: float) -> None:
    """Advance He's model over ``u``, writing ``y`` and updating ``st``."""
    fs = 0.5 * (S + J)
    fd = 0.5 * (S - J)
    for k in range(len(u)):
        uk = 0.0 if u[k] < 0.0 else 100.0 if u[k] > 100.0 else u[k]
        c = st[_UR] + uk - st[_UPREV]
        if abs(c) > fs:
            sg = math.copysign(1.0, c)
            yk = uk - sg * fd
            st[_Y] = 0.0 if yk < 0.0 else 100.0 if yk > 100.0 else yk
            st[_UR] = sg * fd
        else:
            st[_UR] = c
        st[_UPREV] = uk
        y[k] = st[_Y]
