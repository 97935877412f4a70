"""
Loads, set points and measurement errors of the training corpus's records.

Drawn for both labels alike from the signals' stream of a seed
(``stiction_ros.sim.corpus.simulate``); loads and set-point moves are in %
MV at unit gain, measurement errors in PV units.
"""

import math

import numpy as np
from scipy import signal


def logu(rng, lo, hi):
    """Return a log-uniform draw in ``[lo, hi]``."""
    return float(math.exp(rng.uniform(math.log(lo), math.log(hi))))


def pick(rng, options, p=None):
    """Return one of ``options`` (as a string), with probabilities ``p``."""
    return str(options[int(rng.choice(len(options), p=p))])


def _filtered(x, tau_samples):
    a = math.exp(-1.0 / tau_samples)
    b, den = [1.0 - a], [1.0, -a]
    return signal.lfilter(b, den, x, zi=signal.lfilter_zi(b, den) * x[0])[0]


def wave(shape: str, period: float, phase: float, n: int) -> np.ndarray:
    """Return ``n`` samples of a unit ``'sine'``, ``'square'`` or ``'triangle'`` wave."""
    angle = 2.0 * math.pi * (np.arange(n) / period) + phase
    if shape == 'sine':
        return np.sin(angle)
    if shape == 'square':
        return np.sign(np.sin(angle))
    return 2.0 / math.pi * np.arcsin(np.sin(angle))


def _periodic(rng, n):
    """Return a load cycle (% MV): sine, or square or triangle as upstream on/off loops make."""
    period = logu(rng, 15.0, 3.0 * n)
    phase = rng.uniform(0.0, 2.0 * math.pi)
    shape = pick(rng, ('sine', 'square', 'triangle'), [0.6, 0.2, 0.2])
    return logu(rng, 0.3, 5.0) * wave(shape, period, phase, n)


def upstream_cycle(sc, n: int) -> np.ndarray:
    """
    Return the record's upstream cycle (% MV, lagged), zero where it has none.

    Drawn with the scenario (``Scenario.cycle_*``), for both labels alike: a
    cycle that another loop passes on, at a period the analyzer can judge.
    """
    if sc.cycle_amplitude <= 0.0:
        return np.zeros(n)
    cycle = sc.cycle_amplitude * wave(sc.cycle_shape, sc.cycle_period, sc.cycle_phase, n)
    return _filtered(cycle, sc.cycle_lag)


def loads(rng, sc, n):
    """Return the load (% MV equivalent, before its lag): steps, drift and any cycle."""
    activity = pick(rng, ('quiet', 'normal', 'busy'), [0.25, 0.5, 0.25])
    amp = {'quiet': 0.25, 'normal': 1.0, 'busy': 3.0}[activity]
    load = np.zeros(n)
    for _ in range(int(rng.integers(0, 2 if activity == 'quiet' else 5))):
        at = int(rng.uniform(0.05, 0.95) * n)
        load[at:] += rng.choice((-1.0, 1.0)) * logu(rng, 0.3, 4.0) * amp
    if rng.random() < 0.7:
        # A random walk: feed rates and upstream conditions wander without bound.
        walk = np.cumsum(rng.standard_normal(n))
        load += walk * (logu(rng, 0.3, 4.0) * amp / max(float(np.std(walk)), 1e-9))
    tuned_cycle = sc.look_alike == 'integrating_cycle' and sc.tuning == 'aggressive'
    if sc.look_alike == 'load_cycle' or (sc.look_alike == 'integrating_cycle'
                                         and not tuned_cycle):
        cycle = _periodic(rng, n)
        # The cycle is the condition this record is about: other loads stay smaller.
        load *= min(1.0, float(np.ptp(cycle)) / max(2.0 * float(np.std(load)), 1e-9))
        load += cycle
    return _filtered(load - load[0], logu(rng, 0.3, 30.0))


def set_point(rng, sc, n):
    """
    Return set-point moves in % MV equivalent, of the kinds historians show.

    Held; a few operator steps; many small operator moves; or a remote set
    point: a cascade secondary's SP is its master's output and moves a little
    at almost every sample (a tenth of the shared plant records have more
    set-point moves than the corpus drew before).  Level loops are mostly
    masters, and mostly hold theirs.
    """
    p = [0.8, 0.15, 0.05, 0.0] if sc.integrating else [0.35, 0.35, 0.15, 0.15]
    kind = pick(rng, ('held', 'steps', 'busy', 'remote'), p)
    moves = np.zeros(n)
    if kind in ('steps', 'busy'):
        count, size = ((1, 4), (0.5, 8.0)) if kind == 'steps' else ((4, 16), (0.2, 3.0))
        for _ in range(int(rng.integers(*count))):
            at = int(rng.uniform(0.05, 0.95) * n)
            moves[at:] += rng.choice((-1.0, 1.0)) * logu(rng, *size)
    elif kind == 'remote':
        walk = np.cumsum(rng.standard_normal(n))
        walk = _filtered(walk - walk[0], logu(rng, 2.0, 50.0))
        moves = walk * (logu(rng, 0.5, 6.0) / max(float(np.std(walk)), 1e-9))
    return moves


def measurement(rng, sc, n, scale):
    """Return additive measurement error, PV resolution and the frozen stretch."""
    white = rng.standard_normal(n)
    if rng.random() < 0.35:
        # Coloured: transmitter damping or process turbulence slower than a sample.
        white = signal.lfilter([1.0], [1.0, -rng.uniform(0.5, 0.95)], white)
        white /= max(float(np.std(white)), 1e-12)
    err = sc.noise_std * white
    res, frozen = 0.0, (-1, -1)
    if sc.look_alike == 'pv_quantisation':
        res = logu(rng, 0.8, 6.0) * max(sc.noise_std, 0.05 * scale)
    elif sc.look_alike == 'sensor_fault':
        fault = pick(rng, ('spikes', 'drift', 'freeze'))
        if fault == 'spikes':
            for _ in range(int(rng.integers(3, 30))):
                at = int(rng.integers(0, n))
                err[at:at + int(rng.integers(1, 4))] += (
                    rng.choice((-1.0, 1.0)) * logu(rng, 3.0, 15.0)
                    * max(sc.noise_std, 0.2 * scale))
        elif fault == 'drift':
            start = int(rng.uniform(0.0, 0.6) * n)
            ramp = np.clip((np.arange(n) - start) / max(n - start, 1), 0.0, None)
            err += rng.choice((-1.0, 1.0)) * logu(rng, 1.0, 10.0) * scale * ramp
        else:
            length = int(logu(rng, 30.0, 0.4 * n))
            start = int(rng.integers(int(0.1 * n), max(int(0.9 * n) - length, int(0.1 * n) + 1)))
            frozen = (start, start + length)
    return err, res, frozen
