"""
Two loops in series: a sticky valve's cycle, through a vessel, as the load of a healthy loop.

A plant-wide oscillation has one source and many loops that only carry it:
a sticky flow valve cycles, the cycle passes through a tank into the next
unit, and that unit's loop, with a perfectly good valve, cycles at the same
period.  Read one loop at a time, the carrier looks like stiction too (a
cycle in OP and PV with stuck-looking turns).  :func:`coupled_pair` makes
such a pair from the corpus's own draws, for the shared-cycle study
(``study.shared_cycles``) and its tests.

The upstream loop is a sticky draw of the corpus (``draw_scenario(seed,
label=True)``) without a load cycle of its own; the downstream one the first
healthy draw of seeds ``seed + DOWNSTREAM_OFFSET + k REDRAW`` (k = 0, 1, ...)
that was tuned at the same sample time (the corpus places a loop's damping
at its own sampling, which a resampled loop would lose) and has no cycle of
its own (no upstream cycle, load cycle or integrating-loop cycle; a hot
tuning, which rings but does not cycle, stays).  The upstream PV, less its
mean, passes a first-order lag of ``lag`` samples (the vessel), is scaled
to a cycle of ``amplitude`` % MV (the corpus's range for upstream cycles)
and is added to the downstream loop's loads.
"""

from dataclasses import dataclass, replace

import numpy as np
from scipy.signal import lfilter

from stiction_ros.sim.corpus import draw_scenario, Scenario, simulate

DOWNSTREAM_OFFSET = 500_000
REDRAW = 10_000_000
# Healthy draws whose loads cycle by themselves: not a carrier of another loop's cycle.
OWN_CYCLES = ('load_cycle', 'integrating_cycle')
LAG_SAMPLES = (0.5, 20.0)       # the vessel's time constant, uniform
AMPLITUDE = (0.3, 3.0)          # % MV, log-uniform: as the corpus's upstream cycles


@dataclass
class CoupledPair:
    """Both loops of one draw: scenarios, records, and the coupling between them."""

    upstream: Scenario
    downstream: Scenario
    up: dict
    down: dict
    lag: float          # samples
    amplitude: float    # % MV, the cycle's half peak-to-peak if it were a sine


def _downstream(seed: int, sample_time: float) -> Scenario:
    for k in range(200):
        sc = draw_scenario(seed + DOWNSTREAM_OFFSET + k * REDRAW, label=False)
        if sc.sample_time == sample_time and sc.look_alike not in OWN_CYCLES:
            return replace(sc, cycle_amplitude=0.0)
    raise RuntimeError(f'no healthy draw sampled every {sample_time} s for seed {seed}')


def vessel(x: np.ndarray, lag: float) -> np.ndarray:
    """Return ``x`` through a first-order lag of ``lag`` samples with unit gain."""
    a = float(np.exp(-1.0 / lag))
    return np.asarray(lfilter([1.0 - a], [1.0, -a], x))


def coupled_pair(seed: int) -> CoupledPair:
    """
    Return the pair of ``seed``: a sticky loop whose PV cycle loads a healthy one.

    Each record depends on ``seed`` alone (the coupling draws from stream
    ``[seed, 17]``).
    """
    rng = np.random.default_rng([seed, 17])
    up_sc = draw_scenario(seed, label=True)
    look = '' if up_sc.look_alike == 'load_cycle' else up_sc.look_alike
    up_sc = replace(up_sc, cycle_amplitude=0.0, look_alike=look)
    up = simulate(up_sc)
    down_sc = replace(_downstream(seed, up_sc.sample_time), samples=up_sc.samples)
    lag = float(rng.uniform(*LAG_SAMPLES))
    amplitude = float(np.exp(rng.uniform(*np.log(AMPLITUDE))))
    carried = vessel(up['pv'] - float(np.mean(up['pv'])), lag)
    size = float(np.std(carried)) * np.sqrt(2.0)
    load = carried * (amplitude / size) if size > 0 else carried
    down = simulate(down_sc, load=load)
    return CoupledPair(up_sc, down_sc, up, down, lag, amplitude)
