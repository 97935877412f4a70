"""
Stenman et al. one-parameter stiction model (chapter eq. 2.3).

``y(k) = y(k-1)`` while ``|u(k) - y(k-1)| < d``, else ``y(k) = u(k)``.  The
chapter prints ``u(k-1)`` in the first branch; a stuck valve holds its previous
*position*, so we use ``y(k-1)`` as MODELS.md explains.  The band d is called
``S`` here so that every model takes the same parameter name on the ROS side.
"""

from stiction_ros.kernels.arrays import Floats
from stiction_ros.kernels.loop_kinds import loop_args, LoopArgs, STENMAN
from stiction_ros.kernels.valves import stenman_run
from stiction_ros.models.base import ValveModel


class Stenman(ValveModel):
    """One-parameter model: the valve jumps to the input once it is d away."""

    name = 'stenman'
    PARAMS = {
        'S': (0.0, 0.0, 100.0, 'stiction band d of eq. 2.3, % of span'),
    }

    def _initial_state(self, u0: float, y0: float | None) -> list[float]:
        return [min(max(u0, 0.0), 100.0) if y0 is None else y0]

    def _run(self, u: Floats, y: Floats, st: Floats) -> None:
        stenman_run(u, y, st, self._params['S'])

    def loop_args(self) -> LoopArgs:
        """Return the compiled loop's arguments for this valve."""
        return loop_args(STENMAN, (self._params['S'],))

    def _run_reference(self, u: Floats, y: Floats, st: Floats) -> None:
        stenman_kernel(u, y, st, self._params['S'])


def stenman_kernel(u: Floats, y: Floats, st: Floats, d: float) -> None:
    """Advance Stenman's model over ``u``, writing ``y`` and updating ``st``."""
    for k in range(len(u)):
        uk = 0.0 if u[k] < 0.0 else 100.0 if u[k] > 100.0 else u[k]
        if abs(uk - st[0]) >= d:
            st[0] = uk
        y[k] = st[0]
