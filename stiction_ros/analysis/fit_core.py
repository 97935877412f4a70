"""
The shared core of the fits that score a valve model against a record.

Three fits search a rugged error landscape over (S, J) with compiled
kernels: the valve model OP -> MV (``identify.ValveProblem``), Kano's model
with one more effect OP -> MV (``mismatch.fit.EffectsProblem``) and the
Hammerstein model OP -> PV (``hammerstein.HammersteinProblem``).  Each holds
its data in a :class:`Problem` subclass, which is what the search code and
the kernels read.
"""

import numpy as np


class Problem:
    """
    The data of one fit, laid out for the compiled kernels.

    The contract every subclass keeps:

    * ``u``: the model's input (OP), a contiguous float64 array over the
      whole record, so a kernel can take it without a copy;
    * ``y``: the series the model is fitted to (MV or PV), likewise, of the
      same length as ``u``;
    * ``starts``, ``stops``: int64 arrays, the (start, stop) index ranges of
      the valid segments; a kernel restarts the valve at each start and
      nothing it computes reaches across a gap;
    * ``n``: the number of samples the error sum runs over, by default every
      sample of the segments (a subclass that scores fewer, such as the
      Hammerstein fit's regression rows, sets its own);
    * ``evaluations``: parameter sets scored so far; each scoring method adds
      the ones it ran, and the search reports the total.

    A subclass may keep its own names for ``u`` and ``y`` (``op``, ``mv``,
    ``pv``) beside these, bound to the same arrays.
    """

    def __init__(self, u, y, starts, stops):
        self.u = np.ascontiguousarray(u, dtype=np.float64)
        self.y = np.ascontiguousarray(y, dtype=np.float64)
        self.starts = np.ascontiguousarray(starts, dtype=np.int64)
        self.stops = np.ascontiguousarray(stops, dtype=np.int64)
        self.n = int(np.sum(self.stops - self.starts))
        self.evaluations = 0
