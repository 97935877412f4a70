"""
Labelled closed-loop records for training a stiction detector that reads OP, PV and SP.

A detector trained on textbook limit cycles fails on historian data, where a
sticky valve often sits still for an hour while integral action ramps OP, and
where healthy loops cycle from tuning, upstream loads or sensor trouble.  So
each record draws a plant, a tuning, loads, noise and a valve the way a
chemical plant's flow, pressure, level and slow quality loops vary, and half
of the healthy records carry a condition that imitates stiction
(``LOOK_ALIKES``).  Loads, noise and set points are drawn the same way for
both labels, so the label shows only through the valve and the look-alikes.
So are two things a plant has that a linear PI loop lacks: an equal-percentage
valve, whose loop gain grows as it opens, and on level loops a gap or
error-squared controller, which lets the level swing; and a cycle passed on
from upstream, which a healthy and a sticky valve's loop alike must carry.

Time constants are drawn in samples (what a historian export shows) and
converted to seconds.  Everything follows from the seed: ``draw_scenario``
draws from ``default_rng(seed)`` and the characteristic, controller law and
upstream cycle from ``default_rng([seed, 3])`` (added on 2026-11-29, so that
every other draw stayed what it was; the cycle is drawn last in it, for the
same reason), ``simulate`` draws the signals (loads, set point, noise, faults)
from ``default_rng([seed, 1])``.
"""

from dataclasses import asdict, dataclass

import numpy as np

from stiction_ros.kernels.corpus import installed_flow, LAW_GAP, LAW_PI, LAW_SQUARED, \
    loop_matrix, min_damping, QUANTISED, run_corpus_loop
from stiction_ros.models import create
from stiction_ros.sim.corpus_signals import loads, logu, measurement, pick, set_point, \
    upstream_cycle
from stiction_ros.sim.plant import TransferFunctionPlant

LOOK_ALIKES = ('aggressive_tuning', 'load_cycle', 'integrating_cycle', 'backlash', 'quantised',
               'pv_quantisation', 'sensor_fault')
STICTION_VALVES = ('kano', 'choudhury', 'he')
# Conditions a sticky valve's loop may carry as well (the valve kinds cannot).
STICTION_EXTRAS = ('aggressive_tuning', 'load_cycle', 'pv_quantisation', 'sensor_fault')
# Damping-ratio floor of the linearised loop per tuning, and the band an
# oscillating look-alike is pushed into.
FLOORS = {'sluggish': 0.45, 'normal': 0.3, 'aggressive': 0.2}
RINGING = (0.02, 0.15)
OP_LOW, OP_HIGH = 8.0, 92.0
OP_JITTER = 2.0     # largest OP noise std (%) that the PV noise may cause
# Shares of equal-percentage valves (all loops) and of nonlinear laws (integrating loops).
EQUAL_PERCENTAGE = 0.3
NONLINEAR_LAW = 0.3
# Share of loops (both labels) that carry a cycle from upstream at a period
# the analyzer judges (12 samples to a fifth of the record, at most 300).
UPSTREAM_CYCLE = 0.25
LAWS = {'': LAW_PI, 'gap': LAW_GAP, 'squared': LAW_SQUARED}


@dataclass(frozen=True)
class Scenario:
    """
    One drawn loop; with its seed it fixes the simulated record.

    ``gain`` is PV units per % MV (self-regulating) or PV units per % MV per
    second (integrating); its sign sets the controller action.
    """

    seed: int
    label: bool
    valve: str
    S: float
    J: float
    quantum: float
    integrating: bool
    sample_time: float
    samples: int
    gain: float
    tau: float
    tau2: float
    delay: float
    Kc: float
    Ti: float
    tuning: str
    noise_std: float
    look_alike: str
    rangeability: float = 1.0
    law: str = ''
    gap: float = 0.0
    inner: float = 1.0
    cycle_amplitude: float = 0.0    # % MV equivalent; 0: no upstream cycle
    cycle_period: float = 0.0       # samples
    cycle_phase: float = 0.0
    cycle_shape: str = ''
    cycle_lag: float = 1.0          # samples

    def to_json(self) -> dict:
        """Return the scenario as a dict of plain JSON types."""
        return asdict(self)


def draw_label(seed: int, balance: float = 0.5) -> bool:
    """Return the label of ``seed`` in a corpus with a fraction ``balance`` of stiction."""
    return bool(np.random.default_rng(seed).random() < balance)


def plant_model(scenario: Scenario) -> TransferFunctionPlant:
    """Return the sampled plant of ``scenario`` (exact ZOH, fractional dead time exact)."""
    den = np.polymul([scenario.tau, 1.0], [scenario.tau2, 1.0])
    if scenario.integrating:
        den = np.polymul(den, [1.0, 0.0])
    return TransferFunctionPlant([scenario.gain], den, delay=scenario.delay,
                                 sample_time=scenario.sample_time)


def pv_scale(scenario: Scenario) -> float:
    """
    Return the PV move (PV units) that a 1 % load or MV change typically causes.

    Self-regulating: the steady-state gain.  Integrating: the drift of a 1 %
    imbalance over half an integral time, roughly the peak deviation the
    controller lets through.
    """
    if scenario.integrating:
        return abs(scenario.gain) * 0.5 * scenario.Ti
    return abs(scenario.gain)


def _draw_plant(rng, integrating):
    """Return tau, tau2, delay (samples), |gain| per % (per sample if integrating), noise."""
    if integrating:
        if rng.random() < 0.8:     # level: short lag, little dead time, turbulent surface
            tau, delay = logu(rng, 0.1, 5.0), (0.0 if rng.random() < 0.5 else rng.uniform(0, 2))
            tau2 = tau * rng.uniform(0.1, 1.0) if rng.random() < 0.15 else 0.0
            residence, noise = logu(rng, 10.0, 500.0), logu(rng, 0.03, 1.5)
        else:                      # gas holder, header pressure, batch quality
            tau, delay = logu(rng, 0.5, 20.0), logu(rng, 0.5, 8.0)
            tau2 = tau * rng.uniform(0.1, 1.0) if rng.random() < 0.3 else 0.0
            residence, noise = logu(rng, 5.0, 300.0), logu(rng, 0.01, 0.8)
        return tau, tau2, delay, logu(rng, 0.2, 5.0) / residence, noise
    kind = pick(rng, ('flow', 'pressure', 'slow', 'any'), [0.4, 0.2, 0.15, 0.25])
    if kind == 'flow':             # faster than the historian: tau under a few samples
        tau, p2, noise = logu(rng, 0.1, 3.0), 0.2, logu(rng, 0.1, 2.5)
        delay = 0.0 if rng.random() < 0.6 else rng.uniform(0.0, 1.5)
    elif kind == 'pressure':
        tau, p2, noise = logu(rng, 0.5, 15.0), 0.3, logu(rng, 0.03, 1.0)
        delay = 0.0 if rng.random() < 0.4 else rng.uniform(0.0, 2.0)
    elif kind == 'slow':           # temperature, composition: lags in series, dead time
        tau, p2, noise = logu(rng, 3.0, 40.0), 0.7, logu(rng, 0.01, 0.3)
        delay = logu(rng, 1.0, 8.0)
    else:
        tau, p2, noise = logu(rng, 0.1, 40.0), 0.4, logu(rng, 0.01, 2.0)
        delay = rng.uniform(0.0, 1.0) if rng.random() < 0.5 else logu(rng, 1.0, 8.0)
    tau2 = tau * rng.uniform(0.1, 1.0) if rng.random() < p2 else 0.0
    return tau, tau2, delay, logu(rng, 0.2, 5.0), noise


def _tune(rng, tuning, integrating, tau, tau2, delay, gain):
    """Return SIMC-style Kc and Ti (samples) with a random practitioner's mismatch."""
    # Half rule for the second lag; half a sample for the hold.
    if integrating:
        theta, tau1 = delay + tau + tau2 + 0.5, 0.0
        ref = theta
    else:
        theta, tau1 = delay + 0.5 * tau2 + 0.5, tau + 0.5 * tau2
        ref = max(theta, 0.25 * tau1)
    if tuning == 'sluggish':
        lam = rng.uniform(3.0, 10.0) * max(theta, tau1)
    elif tuning == 'normal':
        lam = logu(rng, 1.0, 3.0) * ref
    else:
        lam = rng.uniform(0.2, 0.5) * ref
    if integrating:
        kc, ti = 1.0 / (gain * (lam + theta)), 4.0 * (lam + theta)
    else:
        kc, ti = tau1 / (gain * (lam + theta)), min(tau1, 4.0 * (lam + theta))
    return kc * logu(rng, 0.6, 1.6), ti * logu(rng, 0.6, 1.6)


def _place(plant, sign, kc, ki, floor, ceiling=None):
    """
    Return Kc and Kc ts / Ti moved until the linearised loop's damping is acceptable.

    With ``ceiling`` the integral gain first rises until the slow poles ring
    (too much reset is the commonest cause of an oscillating loop); then the
    loop is detuned until every pole is damped at least ``floor`` and the
    near-Nyquist ones at least ``max(floor, 0.3)``.  The third value says
    whether the slow damping ended at or below ``ceiling``.
    """
    def zeta(kc, ki):
        return min_damping(loop_matrix(plant._phi, plant._g0, plant._g1, plant._c, plant._m,
                                       plant._fractional, kc, ki, sign))
    fast_floor = max(floor, 0.3)
    if ceiling is not None:
        for _ in range(60):
            if zeta(kc, ki)[0] <= ceiling or zeta(kc, ki * 1.3)[1] < fast_floor:
                break
            ki *= 1.3
    for _ in range(300):
        low, high = zeta(kc, ki)
        if low >= floor and high >= fast_floor:
            break
        if high < fast_floor:
            # Keep Ti: too much gain overall, not too much reset.
            kc, ki = kc * 0.9, ki * 0.9
        else:
            kc, ki = kc * 0.95, ki * 0.95 ** 2
    low, high = zeta(kc, ki)
    return kc, ki, ceiling is None or low <= ceiling


def draw_scenario(seed: int, label: bool | None = None, extra_delay: float = 0.0) -> Scenario:
    """
    Draw one loop from ``seed``; ``label`` None draws stiction with probability 1/2.

    ``extra_delay`` (samples) lengthens the drawn plant's dead time before the
    loop is tuned for it: loops outside the corpus (at most 8 samples), for
    ``study.probes.long_dead_time``; everything else drawn stays the same.

    Returns
    -------
    Scenario
        Deterministic in ``seed`` (and ``label``).

    """
    rng = np.random.default_rng(seed)
    # Always consume the label draw so that the rest of the stream is the same.
    first = rng.random()
    label = first < 0.5 if label is None else bool(label)
    S = J = quantum = 0.0
    if label:
        valve = pick(rng, STICTION_VALVES, [0.4, 0.3, 0.3])
        S = logu(rng, 0.3, 10.0)
        J = S * rng.uniform(0.1, 1.5)
        look = pick(rng, STICTION_EXTRAS) if rng.random() < 0.3 else ''
    else:
        look = pick(rng, LOOK_ALIKES) if rng.random() < 0.5 else ''
        valve = look if look in ('backlash', 'quantised') else 'linear'
        if look == 'backlash':
            S = logu(rng, 0.3, 5.0)
        elif look == 'quantised':
            quantum = logu(rng, 0.1, 1.5)
    ts = float(pick(rng, (10.0, 5.0, 1.0), [0.75, 0.1, 0.15]))
    samples = (int(rng.integers(700, 801)) if rng.random() < 0.45
               else int(round(logu(rng, 500.0, 2500.0))))
    integrating = look == 'integrating_cycle' or rng.random() < 0.3
    if look == 'aggressive_tuning' or (look == 'integrating_cycle' and rng.random() < 0.5):
        tuning = 'aggressive'
    else:
        tuning = pick(rng, ('sluggish', 'normal', 'aggressive'),
                      [0.45, 0.4, 0.15] if integrating else [0.3, 0.5, 0.2])
    ringing = tuning == 'aggressive' and look in ('aggressive_tuning', 'integrating_cycle')
    sign = -1.0 if rng.random() < 0.25 else 1.0     # direct-acting loops
    common = {'seed': int(seed), 'label': bool(label), 'valve': valve, 'S': float(S),
              'J': float(J), 'quantum': float(quantum), 'integrating': bool(integrating),
              'sample_time': ts, 'samples': samples, 'tuning': tuning, 'look_alike': look}
    # Only a plant with lag or dead time to spare rings at the historian's
    # rate; a ringing look-alike redraws its plant (same stream) until it does.
    for _ in range(20):
        tau, tau2, delay, gain, noise = _draw_plant(rng, integrating)
        delay += extra_delay
        kc, ti = _tune(rng, tuning, integrating, tau, tau2, delay, gain)
        sc = Scenario(**common, gain=float(sign * gain / (ts if integrating else 1.0)),
                      tau=float(tau * ts), tau2=float(tau2 * ts), delay=float(delay * ts),
                      Kc=0.0, Ti=1.0, noise_std=0.0)
        kc, ki, ok = _place(plant_model(sc), sign, kc, kc / ti,
                            *(RINGING if ringing else (FLOORS[tuning],)))
        if ok:
            break
    sc = _replace(sc, Kc=float(kc), Ti=float(kc / ki * ts))
    # Nobody runs a loop whose OP jitters by more than a few % from noise alone.
    sc = _replace(sc, noise_std=float(min(noise * pv_scale(sc), OP_JITTER / kc)))
    return _draw_plant_extras(np.random.default_rng([seed, 3]), sc)


def _draw_plant_extras(rng, sc):
    """
    Return ``sc`` with its characteristic, its upstream cycle and (level loops) its law.

    Every value is drawn whether used or not, so that each stays the same
    when another changes.  The tuning is that of the operating point, where
    the characteristic's slope is 1 and the law is set aside, as an engineer
    tunes; away from it the loop gain is what the nonlinearity makes it.
    """
    equal, rangeability = rng.random() < EQUAL_PERCENTAGE, logu(rng, 10.0, 50.0)
    nonlinear, law = rng.random() < NONLINEAR_LAW, pick(rng, ('gap', 'squared'))
    # In PV units.  Error squared reaches the PI's gain only at the gap, so it is
    # drawn wider: within it the law is gentler than the PI it replaces.
    size = logu(rng, 0.3, 3.0) * (3.0 if law == 'squared' else 1.0)
    gap, inner = size * max(pv_scale(sc), sc.noise_std), rng.uniform(0.05, 0.3)
    if not (sc.integrating and nonlinear):
        law, gap, inner = '', 0.0, 1.0
    cycled, amplitude = rng.random() < UPSTREAM_CYCLE, logu(rng, 0.3, 3.0)
    period, phase = logu(rng, 12.0, min(300.0, sc.samples / 5.0)), rng.uniform(0.0, 2.0 * np.pi)
    shape, lag = pick(rng, ('sine', 'triangle', 'square'), [0.7, 0.15, 0.15]), logu(rng, 0.3, 10.0)
    return _replace(sc, rangeability=float(rangeability if equal else 1.0), law=law,
                    gap=float(gap), inner=float(inner),
                    cycle_amplitude=float(amplitude if cycled else 0.0),
                    cycle_period=float(period if cycled else 0.0),
                    cycle_phase=float(phase if cycled else 0.0),
                    cycle_shape=shape if cycled else '', cycle_lag=float(lag if cycled else 1.0))


def _replace(sc, **changes):
    values = asdict(sc)
    values.update(changes)
    return Scenario(**values)


def _valve(sc, mv0):
    """Return the valve's loop arguments and state, at rest at ``mv0``."""
    if sc.valve == 'quantised':
        kind, fp, arr, phis, hs, q, jmax = create('linear').loop_args()
        return (QUANTISED, fp, np.zeros(1), arr, phis, hs, q, jmax)
    if sc.valve == 'backlash':
        model = create('kano', S=sc.S, J=0.0)
    elif sc.valve == 'linear':
        model = create('linear')
    else:
        model = create(sc.valve, S=sc.S, J=sc.J)
    model.reset(y0=mv0)
    model.step(mv0)
    kind, fp, arr, phis, hs, q, jmax = model.loop_args()
    return (kind, fp, model.state, arr, phis, hs, q, jmax)


def _operating_point(rng, sc):
    """Return MV at rest before the record starts, the first draw of the signals' stream."""
    mv0 = rng.uniform(20.0, 80.0)
    return sc.quantum * round(mv0 / sc.quantum) if sc.valve == 'quantised' else mv0


def _controller(sc, sign, bias):
    ts = sc.sample_time
    return np.array([sc.Kc, sc.Kc * ts / sc.Ti, sign, bias, float(LAWS[sc.law]), sc.gap,
                     sc.inner])


def _run(sc, plant, sp, op_open, pv_load, err, pid, sens, mv0):
    n = sp.shape[0]
    out = {k: np.empty(n) for k in ('op', 'mv', 'pv')}
    kind, fp, st, arr, phis, hs, q, jmax = _valve(sc, mv0)
    run_corpus_loop(sp, op_open, pv_load, err, pid, sens, kind, fp, st, arr, phis, hs, q, jmax,
                    sc.quantum, plant._phi, plant._g0, plant._g1, plant._c, plant._m,
                    plant._fractional, out['op'], out['mv'], out['pv'])
    return out


def simulate(scenario: Scenario, load: np.ndarray | None = None, oversample: int = 1,
             average: bool = False) -> dict:
    """
    Simulate the closed loop of ``scenario``.

    ``load``: another load, in % MV as the scenario's own and at least
    ``scenario.samples`` long, added to them (another loop's cycle coming
    through a vessel: ``sim.coupled_loops``); None adds nothing.

    ``oversample``: the controller, valve and plant run this many times per
    record sample, as a DCS runs faster than its historian exports; loads,
    set point and measurement error are drawn as for 1 and held over each
    record sample, and the record is the value at each sample time, or with
    ``average`` the mean over the sample (a historian's interval average).
    1 (the corpus) gives the record of the scenario as drawn.

    Returns
    -------
    dict
        Arrays ``t`` (s), ``op`` (%), ``pv`` (as measured), ``sp`` and ``mv``
        (true valve position, %), each ``scenario.samples`` long.

    """
    sc = scenario
    if int(oversample) != oversample or oversample < 1:
        raise ValueError(f'oversample must be a whole number of at least 1, not {oversample}')
    rng = np.random.default_rng([sc.seed, 1])
    n, ts = sc.samples, sc.sample_time
    load_in = None
    if load is not None:
        load_in = np.asarray(load, dtype=np.float64)
        if load_in.ndim != 1 or len(load_in) < n or not np.all(np.isfinite(load_in[:n])):
            raise ValueError(f'load must be {n} finite values or more, not {load_in.shape}')
        load_in = load_in[:n]
    plant = plant_model(sc)
    mv0 = _operating_point(rng, sc)
    pv0 = rng.uniform(10.0, 90.0)
    scale = pv_scale(sc)
    sp_mv = set_point(rng, sc, n)
    load = loads(rng, sc, n) + upstream_cycle(sc, n)
    if load_in is not None:
        load = load + load_in
    # Shrink loads and set-point moves together so that the OP they call for
    # stays inside the valve's range (a saturated loop teaches nothing); they
    # are in flow, which the characteristic gives less of as the valve closes.
    need = (0.0 if sc.integrating else sp_mv) - load
    high = installed_flow(OP_HIGH, mv0, sc.rangeability)
    low = -installed_flow(OP_LOW, mv0, sc.rangeability)
    room = min(high / max(need.max(), 1e-9), low / max(-need.min(), 1e-9))
    shrink = min(1.0, room)
    sp_mv, load = sp_mv * shrink, load * shrink
    err, res, frozen = measurement(rng, sc, n, scale)
    m = int(oversample)
    if m > 1:
        sc = _replace(sc, sample_time=ts / m, samples=n * m)
        plant = plant_model(sc)
        sp_mv, load, err = (np.repeat(a, m) for a in (sp_mv, load, err))
        frozen = (frozen[0] * m, frozen[1] * m)
    if sc.integrating:
        sp = pv0 + scale * sp_mv
        pv_load = sc.gain * sc.sample_time * np.concatenate(([0.0], np.cumsum(load[:-1])))
    else:
        sp = pv0 + sc.gain * sp_mv
        pv_load = sc.gain * load
    sign = 1.0 if sc.gain > 0 else -1.0
    pid = _controller(sc, sign, mv0)
    sens = np.array([pv0, mv0, res, float(frozen[0]), float(frozen[1]), sc.rangeability])
    out = _run(sc, plant, sp, np.empty(0), pv_load, err, pid, sens, mv0)
    out['sp'] = sp
    if m > 1:
        for k in out:
            out[k] = out[k].reshape(n, m).mean(axis=1) if average else out[k][::m].copy()
    return {'t': np.arange(n) * ts, 'op': out['op'], 'pv': out['pv'], 'sp': out['sp'],
            'mv': out['mv']}


def plant_response(scenario: Scenario, mv: np.ndarray, mv0: float | None = None) -> np.ndarray:
    """
    Return the noise-free PV deviation of the open loop driven by ``mv`` (%).

    The compiled loop's own plant path (ideal valve, no loads, the scenario's
    characteristic about ``mv0``, by default the record's operating point),
    for checking the discretisation against a continuous-time simulation.
    """
    mv = np.ascontiguousarray(mv, dtype=np.float64)
    zeros = np.zeros(mv.shape[0])
    if mv0 is None:
        mv0 = _operating_point(np.random.default_rng([scenario.seed, 1]), scenario)
    sc = _replace(scenario, valve='linear', Kc=0.0, Ti=1.0)
    pid = _controller(sc, 1.0, mv0)
    sens = np.array([0.0, mv0, 0.0, -1.0, -1.0, sc.rangeability])
    return _run(sc, plant_model(sc), zeros, mv, zeros, zeros, pid, sens, mv0)['pv']


def make_corpus(seeds, label_balance: float = 0.5,
                progress=None) -> tuple[list[Scenario], list[dict]]:
    """
    Draw and simulate one record per seed; return the scenarios and the records.

    Each seed's label is drawn from the seed with probability ``label_balance``
    of stiction (0.5 gives the labels of ``draw_scenario(seed)``);
    ``progress(done, total)`` is called after each record if given.
    """
    seeds = [int(s) for s in seeds]
    scenarios, records = [], []
    for i, seed in enumerate(seeds):
        sc = draw_scenario(seed, draw_label(seed, label_balance))
        scenarios.append(sc)
        records.append(simulate(sc))
        if progress is not None:
            progress(i + 1, len(seeds))
    return scenarios, records
