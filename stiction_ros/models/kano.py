"""
Kano et al. (2004) two-parameter stiction model (chapter Fig. 2.4, eq. 2.6).

S is the deadband plus stickband on the input axis, J the slip jump on the
output axis; in friction terms the static band is ``fs = (S + J) / 2`` and the
kinetic band ``fd = (S - J) / 2``.  An optional first-order air-chamber lag
(time constant ``tau`` seconds at ``sample_time``) acts on the input before
the friction logic, as Kano proposed for noisy controller outputs.
"""

from stiction_ros.kernels.arrays import Floats
from stiction_ros.kernels.loop_kinds import KANO, loop_args, LoopArgs
from stiction_ros.kernels.valves import kano_run
from stiction_ros.models.base import ValveModel
from stiction_ros.models.breakaway import breakaway
from stiction_ros.models.lags import first_order_pole

# state layout: position, u(k-1), u(k-2), u_s, resting flag, direction,
# air-chamber output.  Direction 0 means "at rest with no friction force
# stored" (the initial state), so breakaway needs fs either way.
_Y, _U1, _U2, _US, _STP, _D, _UF = range(7)


class Kano(ValveModel):
    """Kano's model: a resting/moving state machine driven by input increments."""

    name = 'kano'
    PARAMS = {
        'S': (0.0, 0.0, 100.0, 'deadband plus stickband, % of input span'),
        'J': (0.0, 0.0, 100.0, 'slip jump, % of output span'),
        'tau': (0.0, 0.0, 1e6, 'air-chamber lag time constant, s (0 = none)'),
        'sample_time': (1.0, 1e-6, 1e6, 'sample time for the lag, s'),
    }

    def _on_params_changed(self) -> None:
        self._a = first_order_pole(self._params['tau'], self._params['sample_time'])

    def _initial_state(self, u0: float, y0: float | None) -> list[float]:
        uc = min(max(u0, 0.0), 100.0)
        y = uc if y0 is None else y0
        return [y, uc, uc, uc, 1.0, 0.0, u0]

    def _run(self, u: Floats, y: Floats, st: Floats) -> None:
        kano_run(u, y, st, self._params['S'], self._params['J'], self._a)

    def loop_args(self) -> LoopArgs:
        """Return the compiled loop's arguments for this valve."""
        return loop_args(KANO, (self._params['S'], self._params['J'], self._a))

    def _run_reference(self, u: Floats, y: Floats, st: Floats) -> None:
        kano_kernel(u, y, st, self._params['S'], self._params['J'], self._a)


def kano_kernel(u: Floats, y: Floats, st: Floats, S: float, J: float, a: float) -> None:
    """Advance Kano's model over ``u``, writing ``y`` and updating ``st`` in place."""
    fd = 0.5 * (S - J)
    for k in range(len(u)):
        uf = a * st[_UF] + (1.0 - a) * u[k]
        st[_UF] = uf
        uk = 0.0 if uf < 0.0 else 100.0 if uf > 100.0 else uf
        u1 = st[_U1]
        # Kano's rule: a moving valve comes to rest when the input increment
        # stops or reverses; u_s remembers the input at that instant.
        if st[_STP] == 0.0 and (uk - u1) * (u1 - st[_U2]) <= 0.0:
            st[_US] = u1
            st[_STP] = 1.0
        if st[_STP] == 1.0:
            d = breakaway(st[_D], uk - st[_US], S, J)
            if d != 0.0:
                st[_D] = d
                st[_STP] = 0.0
        if st[_STP] == 0.0:
            yk = uk - st[_D] * fd
            yk = 0.0 if yk < 0.0 else 100.0 if yk > 100.0 else yk
        else:
            yk = st[_Y]
        st[_Y] = yk
        st[_U2] = u1
        st[_U1] = uk
        y[k] = yk
