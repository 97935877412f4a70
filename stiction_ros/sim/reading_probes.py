"""
Position readings with effects the MV verdict was never set on: a blind probe.

The verdict with MV (``docs/MV_VERDICT.md``) was set on the instrument cases of
:mod:`stiction_ros.sim.instrument_cases` (dead time, lag, calibration, rate
limit, travel stop, quantisation, backlash).  A plant's position reading meets
more than those.  Each probe here reads the same kind of closed loop (the
instrument cases' loop draw, a Kano valve with the seed's S and J, or a
linear one) through one effect a process engineer meets in plants:

* ``historian``: exception reporting, a new value stored only when the reading
  moves past a deadband (0.2-1 % of span), the last one held otherwise;
* ``drift``: the reading drifts, a ramp or a random walk of 0.5-3 %;
* ``sample_hold``: the reading is updated every 3-10 samples and held between;
* ``two_lag``: a transmitter with two lags (1-6 s each);
* ``characteristic``: the reading is a curve of the stem position
  (equal-percentage with rangeability 20-50, or quick-opening x^0.4-0.6);
* ``windup``: the loop runs near a valve end (3-7 % or 93-97 %), OP saturates;
* ``asym_actuator``: the actuator strokes faster one way (a rate limit or a lag
  that differ opening and closing);
* ``jitter_drop``: time stamps off by 5-40 % of a sample, and 0.5-3 % of the
  rows dropped in bursts;
* ``spikes``: 0.5-3 % of the samples off by 3-20 %;
* ``pink_noise``: 1/f noise of 0.3-1.5 % on the reading;
* ``osc_load``: a sinusoidal load on PV (a plant-wide oscillation, 15-80 samples);
* ``frozen``: one to three stretches (5-15 % of the record) where the reading
  froze.

A case is an effect (a frictionless valve) or ``sticky_`` and the effect.  One
seed draws one loop, one valve and one size of each effect for both, so the
two differ only in the valve.  ``probe_case`` returns ``(record, truth)`` as
``instrument_case`` does, with MV noise (the loop's own and a noisier
transmitter's) added before the effect: a historian stores, and a transmitter
holds, what was read.
"""

from collections.abc import Callable
import math

import numpy as np
from scipy.signal import lfilter

from stiction_ros.models.lags import first_order_pole
from stiction_ros.sim.instrument_cases import draw_loop, JUMP, simulate_drawn, STICTION

EFFECTS = ('historian', 'drift', 'sample_hold', 'two_lag', 'characteristic', 'windup',
           'asym_actuator', 'jitter_drop', 'spikes', 'pink_noise', 'osc_load', 'frozen')
CASES = tuple(c for e in EFFECTS for c in (e, f'sticky_{e}'))


def _loop_record(seed: int, ts: float, n: int, noise: float, sticky: bool, mv0: float,
                 wave: tuple[float, float] | None) -> tuple[dict, dict]:
    # The instrument cases' draws, in their order, so that a seed gives the same loop.
    rng = np.random.default_rng(seed)
    loop = draw_loop(rng, ts, float(n - 1))
    S = float(rng.uniform(*STICTION))
    J = float(rng.uniform(*JUMP)) * S
    valve = {'model': 'kano', 'S': S, 'J': J} if sticky else {'model': 'linear'}
    loads = []
    if wave is not None:
        # A sine on PV (period in samples, amplitude in plant moves) as a step each sample.
        period, amp = wave
        k = np.arange(1, n)
        level = amp * loop['move'] * np.sin(2.0 * np.pi * k / period)
        loads = [(float(i * ts), float(d)) for i, d in zip(k, np.diff(level, prepend=0.0))]
    return simulate_drawn(loop, ts, n, valve, noise, seed, mv0, loads), valve


def _lag(x: np.ndarray, tau: float, ts: float) -> np.ndarray:
    a = first_order_pole(tau, ts)
    return lfilter([1.0 - a], [1.0, -a], x, zi=[a * x[0]])[0]


def _historian(y, x, rng, ts, size):
    deadband = size['deadband'] = float(rng.uniform(0.2, 1.0))
    out, last = np.empty_like(y), y[0]
    for k, v in enumerate(y):
        if abs(v - last) > deadband:
            last = v
        out[k] = last
    return out


def _drift(y, x, rng, ts, size):
    total = float(rng.uniform(0.5, 3.0)) * (1.0 if rng.random() < 0.5 else -1.0)
    if rng.random() < 0.5:
        size['ramp'] = total
        return y + np.linspace(0.0, total, len(y))
    walk = np.cumsum(rng.standard_normal(len(y)))
    walk -= walk[0]
    size['random_walk'] = abs(total)
    return y + walk / (np.max(np.abs(walk)) or 1.0) * abs(total)


def _sample_hold(y, x, rng, ts, size):
    every = size['every'] = int(rng.integers(3, 11))
    return y[(np.arange(len(y)) // every) * every]


def _two_lag(y, x, rng, ts, size):
    taus = [max(float(rng.uniform(1.0, 6.0)), 0.7 * ts) for _ in range(2)]
    size['lags_s'] = taus
    return _lag(_lag(x, taus[0], ts), taus[1], ts)


def _characteristic(y, x, rng, ts, size):
    z = np.clip(x / 100.0, 0.0, 1.0)
    if rng.random() < 0.5:
        r = size['equal_percentage'] = float(rng.uniform(20.0, 50.0))
        return 100.0 * r ** (z - 1.0)
    p = size['quick_opening'] = float(rng.uniform(0.4, 0.6))
    return 100.0 * z ** p


def _asym_actuator(y, x, rng, ts, size):
    up_fast = rng.random() < 0.5
    out = np.empty_like(x)
    pos = x[0]
    if rng.random() < 0.5:
        big = float(np.max(np.abs(np.diff(x)))) or 1.0
        fast, slow = float(rng.uniform(0.3, 0.6)) * big, float(rng.uniform(0.05, 0.2)) * big
        up, down = (fast, slow) if up_fast else (slow, fast)
        size['rate_pct_s'] = {'opening': up / ts, 'closing': down / ts}
        for k, v in enumerate(x):
            pos += min(max(v - pos, -down), up)
            out[k] = pos
        return out
    fast_s = max(float(rng.uniform(0.5, 2.0)), 0.7 * ts)
    slow_s = float(rng.uniform(4.0, 12.0)) * max(1.0, ts)
    up, down = (fast_s, slow_s) if up_fast else (slow_s, fast_s)
    size['lag_s'] = {'opening': up, 'closing': down}
    a_up, a_down = first_order_pole(up, ts), first_order_pole(down, ts)
    for k, v in enumerate(x):
        a = a_up if v > pos else a_down
        pos = a * pos + (1.0 - a) * v
        out[k] = pos
    return out


def _spikes(y, x, rng, ts, size):
    share = size['share'] = float(rng.uniform(0.005, 0.03))
    hit = rng.random(len(y)) < share
    jolt = rng.uniform(3.0, 20.0, len(y)) * rng.choice([-1.0, 1.0], len(y))
    out = y.copy()
    out[hit] = np.clip(y[hit] + jolt[hit], -5.0, 105.0)
    return out


def _pink_noise(y, x, rng, ts, size):
    std = size['std'] = float(rng.uniform(0.3, 1.5))
    f = np.fft.rfftfreq(len(y))
    f[0] = f[1]
    shaped = (rng.standard_normal(len(f)) + 1j * rng.standard_normal(len(f))) / np.sqrt(f)
    w = np.fft.irfft(shaped, len(y))
    return y + std * (w - w.mean()) / w.std()


def _frozen(y, x, rng, ts, size):
    share, pieces = float(rng.uniform(0.05, 0.15)), int(rng.integers(1, 4))
    size.update(share=share, stretches=pieces)
    out, length = y.copy(), int(share * len(y) / pieces)
    for _ in range(pieces):
        a = int(rng.integers(0, len(y) - length))
        out[a:a + length] = out[a]
    return out


# Effects on the reading: (noisy reading, noise-free position, own rng, ts, sizes) -> MV.
# Two lags act on the position; the noise is added after them (a transmitter's own).
_READING: dict[str, Callable] = {
    'historian': _historian, 'drift': _drift, 'sample_hold': _sample_hold,
    'two_lag': _two_lag, 'characteristic': _characteristic, 'asym_actuator': _asym_actuator,
    'spikes': _spikes, 'pink_noise': _pink_noise, 'frozen': _frozen}
_ON_POSITION = ('two_lag', 'characteristic', 'asym_actuator')


def probe_case(case: str, seed: int, sample_time: float = 1.0, n_samples: int = 4321,
               noise: float = 1.0, extra_mv_noise: float = 0.0) -> tuple[dict, dict]:
    """
    Return ``(record, truth)`` of one closed loop read through the effect of ``case``.

    ``noise`` scales the loop's PV and MV noise as in ``instrument_case``;
    ``extra_mv_noise`` (% of span) is a noisier transmitter's.  ``record``
    holds ``t, sp, pv, op, mv`` (and ``mv_true``); ``truth`` the case, the
    valve, the effect's ``sizes`` and ``friction``.  The result depends only
    on the arguments.
    """
    if case not in CASES:
        raise ValueError(f'unknown probe {case!r}; choose one of {list(CASES)}')
    sticky = case.startswith('sticky_')
    effect = case.removeprefix('sticky_')
    ts, n = float(sample_time), int(n_samples)
    rng = np.random.default_rng([seed, 7, EFFECTS.index(effect)])
    sizes: dict = {}
    mv0, wave = 50.0, None
    if effect == 'windup':
        mv0 = float(rng.uniform(93.0, 97.0) if rng.random() < 0.5 else rng.uniform(3.0, 7.0))
        sizes['operating_point'] = mv0
    if effect == 'osc_load':
        wave = (float(rng.uniform(15.0, 80.0)), float(rng.uniform(1.0, 3.0)))
        sizes.update(period_samples=wave[0], amplitude_moves=wave[1])
    record, valve = _loop_record(int(seed), ts, n, noise, sticky, mv0, wave)
    x = np.asarray(record['mv_true'], dtype=float)
    noise_rng = np.random.default_rng([seed, 29])
    own = 0.1 * noise * np.random.default_rng(int(seed) + 1).standard_normal(n)
    extra = extra_mv_noise * noise_rng.standard_normal(n)
    if effect in _ON_POSITION:
        mv = _READING[effect](x, x, rng, ts, sizes) + own + extra
    elif effect in _READING:
        mv = _READING[effect](x + own + extra, x, rng, ts, sizes)
    else:
        mv = x + own + extra
    keep = np.ones(n, dtype=bool)
    t = np.asarray(record['t'], dtype=float).copy()
    if effect == 'jitter_drop':
        jitter, dropped = float(rng.uniform(0.05, 0.4)), float(rng.uniform(0.005, 0.03))
        t += jitter * ts * rng.uniform(-1.0, 1.0, n)
        t[0] = 0.0
        while np.sum(~keep) < int(dropped * n):
            a = int(rng.integers(1, n - 6))
            keep[a:a + int(rng.integers(1, 6))] = False
        sizes.update(jitter_share=jitter, dropped_share=float(np.mean(~keep)))
    out = {'t': t[keep], 'sp': record['sp'][keep], 'pv': record['pv'][keep],
           'op': record['op'][keep], 'mv': mv[keep], 'mv_true': x[keep]}
    truth = {'case': case, 'friction': sticky, 'effects': [effect], 'sizes': sizes,
             'sample_time': ts, 'seed': int(seed), 'noise': float(noise),
             'extra_mv_noise': float(extra_mv_noise), 'valve': valve,
             'mv_noise': round(math.hypot(0.1 * noise, extra_mv_noise), 4)}
    return out, truth
