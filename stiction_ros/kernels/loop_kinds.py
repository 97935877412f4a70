"""Valve kinds of the compiled offline loop (``ValveModel.loop_args``, ``loop_kernel``)."""

import numpy as np

from stiction_ros.kernels.arrays import Floats

KANO, CHOUDHURY, HE, STENMAN, LINEAR, PHYSICAL_EXACT, PHYSICAL_SUBSTEP, KANO_EFFECTS = range(8)

# kind, float parameters, array, propagators, steps, q, jmax
LoopArgs = tuple[int, Floats, Floats, Floats, Floats, int, int]


def loop_args(kind: int, fp: tuple[float, ...] = (), arr: Floats | None = None,
              phis: Floats | None = None, hs: Floats | None = None, q: int = 0,
              jmax: int = 0) -> LoopArgs:
    """Return the valve part of ``loop_kernel.run_loop``'s arguments, unused ones empty."""
    return (kind, np.array(fp, dtype=np.float64),
            np.empty(0) if arr is None else np.ascontiguousarray(arr, dtype=np.float64),
            np.empty((0, 5, 5)) if phis is None else phis,
            np.empty(0) if hs is None else hs, int(q), int(jmax))
