"""
The coarse-to-fine search of (S, J) for the Hammerstein fit.

The SSE is a jumpy function of (S, J): a breakaway moves by whole samples.
S also trades off against the dead time (a valve that breaks away later looks
like a longer delay), so every dead time has its own narrow valley, the
narrower the less noise there is on OP and the more cycles the record holds.
And nobody recorded where the valve stuck before a segment begins: Kano's
valve stops at every reversal of a noisy OP's increment, so a wrong start
state is never forgotten (model and valve go on slipping on different
samples), which biases J and can move S.  Hence:

1. a coarse grid over the whole box (S and J up to the OP travel, every dead
   time), the valve at rest with no direction at each segment start;
2. its ``KEEP`` best candidates, at most ``PER_DELAY`` per dead time so that
   no valley is lost, each get their best start state (direction of the
   last move and where within the band of stick points OP stood), segment
   by segment;
3. they are refined five-fold per level around their own dead time, as in
   ``identify``;
4. J and the start states are gridded together at the best S (both are set
   by the first slips), then the best few are refined again.
"""

import math

import numpy as np

CHI2_95_2DOF = 5.991464547107979
COARSE_POINTS = 24
KEEP = 16
REFINE = 5
PER_DELAY = 2
FINAL_KEEP = 4
# Valve start states (direction, fraction of the band of stick points): a
# few to polish each candidate, then a fine grid together with J.
START_J_POINTS = 21
START_FINE_POINTS = 41
START_SEGMENTS = 4
START_STATES = ((0, 0.5),) + tuple((d, f) for d in (1, -1) for f in np.linspace(0, 1, 13))


class Search:
    """
    Coarse-to-fine grid over the (S, J) box; remembers every pair scored.

    A candidate is (sse, S, J, dead time, start), ``start`` the valve's start
    state per segment (see ``kernels.hammerstein.segment_path``); the steps
    are those of the module docstring.
    """

    def __init__(self, problem, s_max: float, j_max: float, resolution: float):
        self.problem = problem
        self.s_max, self.j_max = s_max, j_max
        self.points = []
        self.levels = max(1, math.ceil(math.log(max(s_max, j_max) / COARSE_POINTS / resolution,
                                                REFINE)))

    def score(self, s_ax, j_ax, start, dlo=None, dhi=None) -> list:
        """Return the candidates of a grid from one start state, and remember them."""
        sse, delay = self.problem.grid(s_ax, j_ax, start, dlo, dhi)
        out = [(float(sse[i, j]), float(s_ax[i]), float(j_ax[j]), int(delay[i, j]), start)
               for i in range(len(s_ax)) for j in range(len(j_ax))]
        self.points += out
        return out

    def coarse(self) -> list:
        """Return the best candidates of the coarse grid over the whole box, start at rest."""
        found = self.score(np.linspace(0.0, self.s_max, COARSE_POINTS + 1),
                           np.linspace(0.0, self.j_max, COARSE_POINTS + 1),
                           self.problem.at_rest())
        return self.polish(_best(found, KEEP, PER_DELAY))

    def longest_segments(self) -> np.ndarray:
        """Return the indices of the ``START_SEGMENTS`` longest segments (starts fitted)."""
        lengths = [b - a for a, b in self.problem.segments]
        return np.argsort([-n for n in lengths], kind='stable')[:START_SEGMENTS]

    def polish(self, candidates: list) -> list:
        """Return ``candidates`` each with its best start state, segment by segment."""
        out = []
        for sse, S, J, d, start in candidates:
            best = (sse, S, J, d, start)
            for seg in self.longest_segments():
                for state in START_STATES:
                    trial = best[4][:seg] + (state,) + best[4][seg + 1:]
                    p = self.score([S], [J], trial, d - 1, d + 1)[0]
                    best = min(best, p, key=lambda c: c[0])
            out.append(best)
        return _best(out, len(candidates), PER_DELAY)

    def settle_start(self, best: tuple) -> tuple:
        """
        Return ``best`` with J and the start states searched together at its S and dead time.

        J and the start state trade off (both set when the valve slips after
        the record begins) and each has narrow valleys, so they are gridded
        jointly, segment by segment for the ``START_SEGMENTS`` longest.
        """
        _, S, J, d, start = best
        j_ax = np.linspace(0.0, min(self.j_max, 2 * J + 0.1 * self.s_max), START_J_POINTS)
        states = ((0, 0.5),) + tuple((k, f) for k in (1, -1)
                                     for f in np.linspace(0.0, 1.0, START_FINE_POINTS))
        for seg in self.longest_segments():
            for state in states:
                trial = best[4][:seg] + (state,) + best[4][seg + 1:]
                best = min([best] + self.score([S], j_ax, trial, d - 1, d + 1),
                           key=lambda c: c[0])
        return best

    def rescore(self, candidates: list, keep: int) -> list:
        """Return the ``keep`` best of ``candidates`` scored afresh here, all dead times."""
        out = []
        for _, s0, j0, _, start in candidates:
            out += self.score([s0], [j0], start)
        return _best(out, keep, PER_DELAY)

    def refine(self, best: list, progress=None) -> list:
        """Return the best candidates (as many as ``best``) refining ``best`` level by level."""
        keep = len(best)
        s_step = self.s_max / COARSE_POINTS
        j_step = self.j_max / COARSE_POINTS
        for level in range(self.levels):
            found = []
            for _, s0, j0, d0, start in best:
                found += self.score(_window(s0, s_step, self.s_max),
                                    _window(j0, j_step, self.j_max), start, d0 - 1, d0 + 1)
            best = _best(found + best, keep, PER_DELAY)
            s_step, j_step = s_step / REFINE, j_step / REFINE
            if progress is not None:
                progress(level + 2, self.levels + 3)
        return best

    def deadband(self, best: tuple) -> tuple:
        """
        Return the best candidate with J = 0: a valve with a deadband and no slip jump.

        What tells stiction from backlash is the jump, so the fit is redone
        with J held at zero: S on a grid four times the coarse one over the
        box, from ``best``'s start state and from rest, every dead time, then
        refined three levels around the best.  Scored after everything the
        result is read from, so it changes none of it.
        """
        points = 4 * COARSE_POINTS
        s_ax = np.linspace(0.0, self.s_max, points + 1)
        found = self.score(s_ax, [0.0], best[4]) + self.score(s_ax, [0.0], self.problem.at_rest())
        cand = min(found, key=lambda c: c[0])
        step = self.s_max / points
        for _ in range(3):
            ax = np.unique(np.clip(np.linspace(cand[1] - step, cand[1] + step, 2 * REFINE + 1),
                                   0.0, self.s_max))
            cand = min([cand] + self.score(ax, [0.0], cand[4], cand[3] - 1, cand[3] + 1),
                       key=lambda c: c[0])
            step /= REFINE
        return cand

    def region(self, best: tuple, n_eff: float) -> tuple:
        """Return the pairs inside the 95 % region and the grid steps of the last window."""
        sse_min, S, J, d, start = best
        bound = sse_min * math.exp(CHI2_95_2DOF / n_eff) * (1 + 1e-12)
        ws, wj = self.s_max / COARSE_POINTS, self.j_max / COARSE_POINTS
        # Grow a window around the optimum while the region touches its edge.
        for _ in range(5):
            steps = (ws / 12, wj / 12)
            s_ax = np.union1d(np.linspace(max(0.0, S - ws), min(self.s_max, S + ws), 25), [S])
            j_ax = np.union1d(np.linspace(max(0.0, J - wj), min(self.j_max, J + wj), 25), [J])
            scored = self.score(s_ax, j_ax, start, d - 1, d + 1)
            inside = [p for p in scored if p[0] <= bound]
            if not inside:
                # An exact fit (SSE ~1e-23, a PV late against OP lets the model
                # fit the controller's own law) rescores above its own bound by
                # rounding: the region is the optimum alone (S and J are on the axes).
                inside = [best]
            lo_s, hi_s = min(p[1] for p in inside), max(p[1] for p in inside)
            lo_j, hi_j = min(p[2] for p in inside), max(p[2] for p in inside)
            if not ((lo_s == s_ax[0] > 0.0) or (hi_s == s_ax[-1] < self.s_max)
                    or (lo_j == j_ax[0] > 0.0) or (hi_j == j_ax[-1] < self.j_max)):
                break
            ws, wj = 2 * ws, 2 * wj
        return [p for p in self.points if p[0] <= bound], steps


def _best(points, keep, per_delay) -> list:
    """
    Return the ``keep`` lowest-SSE candidates of distinct (S, J), ties to smaller S + J.

    S trades off against the dead time (a later breakaway looks like a longer
    delay), so each dead time has its own valley; ``per_delay`` caps the
    candidates taken from one of them, to keep the others in the search.
    """
    seen = {}
    count = {}
    for p in sorted(points, key=lambda p: (p[0], p[1] + p[2])):
        key = (round(p[1], 9), round(p[2], 9))
        if key in seen or count.get(p[3], 0) == per_delay:
            continue
        seen[key] = p
        count[p[3]] = count.get(p[3], 0) + 1
        if len(seen) == keep:
            break
    return list(seen.values())


def _window(x0, step, top) -> np.ndarray:
    """Return the points spanning ``x0 +- step`` at ``step / REFINE``, clipped to [0, top]."""
    return np.unique(np.clip(np.linspace(x0 - step, x0 + step, 2 * REFINE + 1), 0.0, top))
