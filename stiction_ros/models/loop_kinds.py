"""Valve kinds of the compiled offline loop (``ValveModel.loop_args``, ``loop_kernel``)."""

import numpy as np

KANO, CHOUDHURY, HE, STENMAN, LINEAR, PHYSICAL_EXACT, PHYSICAL_SUBSTEP, KANO_EFFECTS = range(8)


def loop_args(kind, fp=(), arr=None, phis=None, hs=None, q=0, jmax=0):
    """Return the valve part of ``loop_kernel.run_loop``'s arguments, unused ones empty."""
    return (kind, np.array(fp, dtype=np.float64),
            np.empty(0) if arr is None else np.ascontiguousarray(arr, dtype=np.float64),
            np.empty((0, 5, 5)) if phis is None else phis,
            np.empty(0) if hs is None else hs, int(q), int(jmax))
