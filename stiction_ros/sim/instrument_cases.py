"""
Closed-loop recordings with hidden instrument and timing effects, for proving ``--explain``.

Real valve recordings differ from a simulation first through instruments and
timing, before any friction law: the measured valve position MV reads the
controller output OP late (dead time), through a frictionless lag, through a
positioner with an offset and a gain, at a limited rate, against a travel stop,
through play without slip (backlash), or through a position transmitter of
coarse resolution (quantisation).  Each case
is a loop like ``stiction_ros.sim.concealed_cases`` (random FOPDT or integrating
plant, SIMC PI, set-point and load steps, noise on PV and MV) drawn *in
samples*: every loop time (plant, controller, steps) is drawn as for 1 s
sampling and multiplied by ``sample_time``, so the loop looks alike in samples
at any sample time.  Instrument sizes are drawn in *seconds*, as a real
instrument's are, so at 5 s sampling a 1 s dead time is a fifth of a sample
(hence the floors: dead time at least 0.5 sample, lag at least 0.7 sample).

Dead time, lag and calibration act on the measured MV only: from OP and MV
alone an actuator dead time cannot be told from a transmitter dead time on a
time-invariant valve, and the plant then sees the same loop in every case of a
seed.  Backlash and stiction act on the position the plant receives.

``instrument_case(case, seed)`` returns ``(record, truth)``.  ``record`` holds
arrays ``t, sp, pv, op, mv`` (and ``mv_true``, the position the plant got).
``truth`` (the TRUTH shape)::

    {'case': 'dead_time_lag',           # one of CASES
     'friction': False,                  # stiction (Kano, J > 0) hidden
     'effects': ['dead_time', 'response_lag'],   # sorted effect ids, [] if none
     'sizes': {'dead_time': 1.7,         # s
               'response_lag': 3.2,      # s, the lag's time constant
               'positioner_calibration': {'offset': -1.2, 'gain': 1.04},  # %, -
               'backlash': 2.5,          # %, Kano S with J = 0
               'quantisation': 0.5},     # %, the transmitter's step
     'sample_time': 1.0, 'seed': 7, 'noise': 1.0,
     'valve': {'model': 'kano', 'S': 3.1, 'J': 1.2},   # the valve simulated
     'integrating': False, 'Kc': 1.3, 'Ti': 40.0}      # the loop, for reading results

``sizes`` holds the present effects only.  Each case depends only on its
arguments.  One seed gives every case the same loop, the same stiction and,
for each effect, the same size wherever it is hidden (each effect draws from
its own stream), so the cases of a seed differ only in what they hide.
"""

import math

import numpy as np
from scipy.signal import lfilter

from stiction_ros.models.lags import first_order_pole
from stiction_ros.resources import config_file
from stiction_ros.sim.closed_loop import simulate_loop
from stiction_ros.sim.loop_config import load_loop

# case: (friction hidden, valve family, hidden instrument effects)
_CASES = {
    'clean_linear': (False, 'linear', ()),
    'clean_sticky': (True, 'kano', ()),
    'dead_time': (False, 'linear', ('dead_time',)),
    'response_lag': (False, 'linear', ('response_lag',)),
    'positioner_calibration': (False, 'linear', ('positioner_calibration',)),
    'backlash': (False, 'backlash', ('backlash',)),
    'quantisation': (False, 'linear', ('quantisation',)),
    'sticky_dead_time': (True, 'kano', ('dead_time',)),
    'sticky_calibration': (True, 'kano', ('positioner_calibration',)),
    'lag_calibration': (False, 'linear', ('positioner_calibration', 'response_lag')),
    'dead_time_lag': (False, 'linear', ('dead_time', 'response_lag')),
    'rate_limit': (False, 'linear', ('rate_limit',)),
    'travel_limits': (False, 'linear', ('travel_limits',)),
}
CASES = tuple(_CASES)
EFFECTS = ('dead_time', 'response_lag', 'positioner_calibration', 'backlash', 'quantisation',
           'rate_limit', 'travel_limits')
# Size ranges: seconds for times, % of span for offset, backlash and resolution.
DEAD_TIME = (0.5, 3.0)
LAG = (1.0, 5.0)
OFFSET = (0.5, 3.0)
GAIN_ERROR = (0.02, 0.06)
BACKLASH = (1.0, 4.0)
STEP = (0.25, 1.0)
# Rate limit: a share of the largest OP change in a sample (so that steps become ramps at
# any sample time); travel stop: the quantile of the position where the stop sits.
RATE_SHARE = (0.15, 0.4)
STOP_QUANTILE = (0.95, 0.99)
STICTION = (2.0, 5.0)
JUMP = (0.2, 0.6)
# Below these (in samples) the effect would hide inside one sample and no analysis could see it.
DEAD_TIME_FLOOR = 0.5
LAG_FLOOR = 0.7
# A loop needs room for its set-point and load steps (drawn 300 to 900 samples apart).
MIN_SAMPLES = 1000


def _check(case, seed, sample_time, n_samples, noise):
    if case not in _CASES:
        raise ValueError(f'unknown case {case!r}; choose one of {list(CASES)}')
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f'seed must be a non-negative integer, got {seed!r}')
    if not isinstance(sample_time, (int, float)) or not math.isfinite(sample_time) \
            or sample_time <= 0:
        raise ValueError(f'sample_time must be a positive number of seconds, got {sample_time!r}')
    if isinstance(n_samples, bool) or not isinstance(n_samples, (int, np.integer)) \
            or n_samples < MIN_SAMPLES:
        raise ValueError(f'n_samples must be an integer of at least {MIN_SAMPLES}, '
                         f'got {n_samples!r}')
    if not isinstance(noise, (int, float)) or not math.isfinite(noise) or noise < 0:
        raise ValueError(f'noise must be a non-negative number, got {noise!r}')


def draw_loop(rng: np.random.Generator, ts: float, span: float) -> dict:
    """Draw plant, SIMC PI and steps as concealed_cases does at 1 s, then scale by ``ts``."""
    integrating = bool(rng.integers(2))
    delay = float(rng.uniform(2.0, 6.0))
    if integrating:
        K = float(rng.uniform(0.01, 0.03))
        tc = 3.0 * delay
        Kc, Ti = 1.0 / (K * (tc + delay)), 4.0 * (tc + delay)
        # An integrator's gain is per second: the same gain per sample is K / ts.
        num, den = [K / ts], [1.0, 0.0]
        move = 1.0 / Kc
    else:
        K, tau = float(rng.uniform(0.8, 2.0)), float(rng.uniform(20.0, 60.0))
        tc = delay
        Kc, Ti = 0.5 * tau / (K * (tc + delay)), min(tau, 4.0 * (tc + delay))
        num, den = [K], [tau * ts, 1.0]
        move = K
    t, sp, steps = 0.0, 0.0, [[0.0, 0.0]]
    while t < span - 400.0:
        t += float(rng.uniform(300.0, 900.0))
        sp += float(rng.choice([-1, 1]) * rng.uniform(4.0, 12.0) * move)
        sp = float(np.clip(sp, -25 * move, 25 * move))
        steps.append([t * ts, sp])
    loads = [(float(x) * ts, float(rng.choice([-1, 1]) * rng.uniform(2.0, 6.0) * move))
             for x in sorted(rng.uniform(300.0, span - 300.0, 6))]
    return {'integrating': integrating, 'num': num, 'den': den, 'delay': delay * ts,
            'Kc': Kc, 'Ti': Ti * ts, 'steps': steps, 'loads': loads, 'move': move}


def _sizes(effects, seed, ts):
    # Each effect draws from its own stream: its size at a seed is the same in every case
    # that hides it, and independent of the other effects' sizes.
    rngs = {e: np.random.default_rng([int(seed), 1 + i]) for i, e in enumerate(EFFECTS)}
    sizes = {}
    if 'dead_time' in effects:
        d = float(rngs['dead_time'].uniform(*DEAD_TIME))
        sizes['dead_time'] = max(d, DEAD_TIME_FLOOR * ts)
    if 'response_lag' in effects:
        tau = float(rngs['response_lag'].uniform(*LAG))
        sizes['response_lag'] = max(tau, LAG_FLOOR * ts)
    if 'positioner_calibration' in effects:
        rng = rngs['positioner_calibration']
        offset = float(rng.choice([-1, 1]) * rng.uniform(*OFFSET))
        gain = 1.0 + float(rng.choice([-1, 1]) * rng.uniform(*GAIN_ERROR))
        sizes['positioner_calibration'] = {'offset': offset, 'gain': gain}
    if 'quantisation' in effects:
        sizes['quantisation'] = float(rngs['quantisation'].uniform(*STEP))
    if 'backlash' in effects:
        sizes['backlash'] = float(rngs['backlash'].uniform(*BACKLASH))
    if 'rate_limit' in effects:
        sizes['rate_limit'] = {'share': float(rngs['rate_limit'].uniform(*RATE_SHARE))}
    if 'travel_limits' in effects:
        rng = rngs['travel_limits']
        sizes['travel_limits'] = {'quantile': float(rng.uniform(*STOP_QUANTILE)),
                                  'side': 'high' if rng.random() < 0.5 else 'low'}
    return sizes


def _actuator(x: np.ndarray, sizes: dict, ts: float) -> np.ndarray:
    # The rate limit and the travel stop, sized on the position they act on.
    if 'rate_limit' in sizes:
        rl = sizes['rate_limit']
        rl.setdefault('rate', rl['share'] * float(np.max(np.abs(np.diff(x)))))
        y, out = x[0], np.empty_like(x)
        for i, v in enumerate(x):
            y += min(max(v - y, -rl['rate']), rl['rate'])
            out[i] = y
        rl['rate_pct_s'] = rl['rate'] / ts
        x = out
    if 'travel_limits' in sizes:
        tl = sizes['travel_limits']
        q = tl['quantile'] if tl['side'] == 'high' else 1.0 - tl['quantile']
        tl.setdefault('stop', float(np.quantile(x, q)))
        x = np.minimum(x, tl['stop']) if tl['side'] == 'high' else np.maximum(x, tl['stop'])
    return x


def measured(mv_true: np.ndarray, sizes: dict, ts: float, mv_std: float,
             noise_rng: np.random.Generator) -> np.ndarray:
    """
    Return the MV a positioner and transmitter with ``sizes`` report for position ``mv_true``.

    In order: dead time (linear interpolation between samples, the first
    value held before the record), rate limit and travel stop, first-order
    lag (pole ``exp(-Ts/tau)`` on the same sample's input, as the analyzer's
    own lags, starting at rest at the first value), offset and gain, noise,
    then quantisation (a transmitter rounds what it senses, noise included).
    """
    x = np.asarray(mv_true, dtype=float)
    if 'dead_time' in sizes:
        k = np.arange(len(x), dtype=float)
        x = np.interp(k - sizes['dead_time'] / ts, k, x)
    x = _actuator(x, sizes, ts)
    if 'response_lag' in sizes:
        a = first_order_pole(sizes['response_lag'], ts)
        x, _ = lfilter([1.0 - a], [1.0, -a], x, zi=[a * x[0]])
    if 'positioner_calibration' in sizes:
        cal = sizes['positioner_calibration']
        x = cal['offset'] + cal['gain'] * x
    if mv_std > 0:
        x = x + mv_std * noise_rng.standard_normal(len(x))
    if 'quantisation' in sizes:
        q = sizes['quantisation']
        x = q * np.round(x / q)
    return x


def simulate_drawn(loop: dict, ts: float, n_samples: int, valve: dict, noise: float,
                   seed: int, mv0: float = 50.0, loads: list | None = None) -> dict:
    """
    Return the record of ``loop`` (from :func:`draw_loop`) run with ``valve``.

    PV noise scales with ``noise`` as in :func:`instrument_case`; MV carries
    none (the caller reads the position through its own effects).  ``mv0``
    is the operating point (OP's bias too), ``loads`` more load steps.
    """
    cfg = load_loop(config_file('concentration_loop.yaml'), overrides={
        'sample_time': ts, 'plant.num': loop['num'], 'plant.den': loop['den'],
        'plant.delay': loop['delay'], 'plant.mv0': mv0, 'controller.bias': mv0,
        'controller.Kc': loop['Kc'], 'controller.Ti': loop['Ti'],
        'controller.setpoint': {'type': 'steps', 'steps': loop['steps']},
        'plant.disturbance_steps': list(loop['loads']) + list(loads or []), 'valve': valve,
        'noise': {'pv_std': 0.01 * 8.0 * loop['move'] * noise, 'mv_std': 0.0, 'seed': int(seed)}})
    return simulate_loop(cfg, (n_samples - 1) * ts)


def instrument_case(case: str, seed: int, sample_time: float = 1.0, n_samples: int = 8641,
                    noise: float = 1.0) -> tuple[dict, dict]:
    """
    Return ``(record, truth)`` of one closed loop hiding the effects of ``case``.

    ``noise`` scales the PV and MV noise (1 = PV 1 % of a typical move, MV
    0.1 % standard deviation).  The result depends only on the arguments.
    """
    _check(case, seed, sample_time, n_samples, noise)
    ts = float(sample_time)
    friction, family, effects = _CASES[case]
    rng = np.random.default_rng(seed)
    loop = draw_loop(rng, ts, float(n_samples - 1))
    # Drawn in every case, so that the sticky cases of a seed share one valve.
    S = float(rng.uniform(*STICTION))
    J = float(rng.uniform(*JUMP)) * S
    sizes = _sizes(effects, seed, ts)
    if family == 'linear':
        valve = {'model': 'linear'}
    elif family == 'kano':
        valve = {'model': 'kano', 'S': S, 'J': J}
    else:
        # Kano's model with no slip jump is pure play: the valve follows OP at S/2 behind.
        valve = {'model': 'kano', 'S': sizes['backlash'], 'J': 0.0}
    mv_std = 0.1 * noise
    record = simulate_drawn(loop, ts, n_samples, valve, noise, seed)
    # The stream simulate_loop itself would draw MV noise from.
    noise_rng = np.random.default_rng(int(seed) + 1)
    record['mv'] = measured(record['mv_true'], sizes, ts, mv_std, noise_rng)
    truth = {'case': case, 'friction': friction, 'effects': sorted(effects), 'sizes': sizes,
             'sample_time': ts, 'seed': int(seed), 'noise': float(noise), 'valve': valve,
             'integrating': loop['integrating'], 'Kc': loop['Kc'], 'Ti': loop['Ti']}
    return record, truth
