"""The ideal valve: position equals input, within travel."""

from stiction_ros.kernels.arrays import Floats
from stiction_ros.kernels.loop_kinds import LINEAR, loop_args, LoopArgs
from stiction_ros.models.base import ValveModel


class Linear(ValveModel):
    """No friction: ``y = clip(u, 0, 100)``; the reference a healthy valve meets."""

    name = 'linear'
    PARAMS = {}

    def _initial_state(self, u0: float, y0: float | None) -> list[float]:
        return [min(max(u0, 0.0), 100.0)]

    def loop_args(self) -> LoopArgs:
        """Return the compiled loop's arguments for this valve."""
        return loop_args(LINEAR)

    def _run(self, u: Floats, y: Floats, st: Floats) -> None:
        for k in range(len(u)):
            uk = u[k]
            st[0] = 0.0 if uk < 0.0 else 100.0 if uk > 100.0 else uk
            y[k] = st[0]
