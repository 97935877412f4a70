"""
The shared core of the fits that score a valve model against a record.

Three fits search a rugged error landscape over (S, J) with compiled
kernels: the valve model OP -> MV (``identify.ValveProblem``), Kano's model
with one more effect OP -> MV (``mismatch.fit.EffectsProblem``) and the
Hammerstein model OP -> PV (``hammerstein.HammersteinProblem``).  Each holds
its data in a :class:`Problem` subclass, which is what the search code and
the kernels read.

Gaps.  The valid segments are the samples a fit scores; between them a valve
model does not stop.  Its state (stuck or moving, which way, where it stuck)
is its whole history, and OP is all that drives it:

* where OP is known across a gap (MV missing, the loop in manual, a PV
  flagged bad), the model runs on through the gap and only the scoring
  pauses, so a gap costs its own samples and nothing else;
* where OP is unknown, nothing carries the state, and the next segment
  restarts from the state that fits it best of the four a valve can be in
  at a measured position y0 (``kernels.valve_starts.restart``): stuck at y0 (y0 the
  median of its first samples, or its first sample, should it slip among
  them), or moving up or down.  A stuck valve needs no direction: Kano's
  next breakaway comes at OP = y0 +- (S + J) / 2 whichever way it last moved
  (stuck after moving up, it needs J more up or S back from OP = y0 + (S - J)
  / 2; after moving down the mirror image), so the stuck restart is exact.
  A moving valve would, started stuck, wait for J more of OP travel, longer
  than a whole limit cycle when J is large.  The restarts are scored side by
  side until they merge into one state, usually at the first breakaway, and
  the best one's error counts: the unknown start is profiled out, over every
  sample.  Leaving out the samples until then instead would score each (S,
  J) on a different set of samples, and those sums do not compare.

The old restart, at rest with the band centred on the first OP, put the band
up to (S + J) / 2 off: in a limit cycle whose OP swings about S the model then
never broke away after a gap, and 32 blank samples of 600 took a fit from S
3.47, J 1.23 to S 2.53, J 0.

The record's first segment starts the models' own way (``simulate``: at
rest, the band centred on the first input), at the position that fits the
scored samples before the first move best (across gaps where OP is known):
their mean, profiled out like a restart's state
(``kernels.valve_starts.first_rest``).  After a move a model's
position no longer depends on where it started, so only that first rest
needs it.  Started at the first measured sample alone, a model carried that
sample's noise through the whole first rest, often hundreds of samples of a
loop waiting for its first set-point step, and the fit bought its way out
with a smaller band: at 2 % MV noise sticky valves (S 2.43, J 0.61) came out
as play (S 1.99, J 0).  ``carried_runs`` gives the stretches a model runs
through.
"""

import numpy as np


def carried_runs(segments, x):
    """
    Return the (start, stop) stretches a model runs through: segments joined across known gaps.

    Consecutive segments are joined when ``x`` (the model's input) is finite on
    every sample between them; a gap with one unknown sample keeps them apart.
    """
    out = []
    for a, b in segments:
        a, b = int(a), int(b)
        if out and np.all(np.isfinite(x[out[-1][1]:a])):
            out[-1] = (out[-1][0], b)
        else:
            out.append((a, b))
    return out


class Problem:
    """
    The data of one fit, laid out for the compiled kernels.

    The contract every subclass keeps:

    * ``u``: the model's input (OP), a contiguous float64 array over the
      whole record, so a kernel can take it without a copy;
    * ``y``: the series the model is fitted to (MV or PV), likewise, of the
      same length as ``u``;
    * ``starts``, ``stops``: int64 arrays, the (start, stop) index ranges of
      the valid segments, the samples scored; the valve kernels (identify's,
      the effects kernel) run on through a gap where ``u`` is finite and
      restart after one where it is not (the module's docstring says how);
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
