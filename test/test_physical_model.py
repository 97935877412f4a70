"""Physics properties of the force-balance valve model (eqs. 2.1-2.2)."""

import math

import numpy as np
import pytest
from scipy.optimize import brentq

from stiction_ros.models.base import ModelError
from stiction_ros.models.physical import Physical, quasi_static_sj

DEFAULTS = {k: spec[0] for k, spec in Physical.PARAMS.items()}
QS = quasi_static_sj()
# Relative slack on force comparisons: the forces are ~1e3 N computed from
# terms ~1e4 N, so rounding is ~1e-12 N; 1e-9 relative is far above it.
FORCE_RTOL = 1e-9


def force_span(**params):
    """Actuator force range A*(p_max - p_min) in N."""
    pr = dict(DEFAULTS, **params)
    return pr['A'] * (pr['p_max'] - pr['p_min'])


def run_steps(model, u):
    """Run ``u`` through ``step()``; return positions, net forces, stuck flags."""
    y = np.empty(len(u))
    n = np.empty(len(u))
    stuck = np.empty(len(u), dtype=bool)
    for i, ui in enumerate(u):
        y[i] = model.step(ui)
        n[i] = model.net_force()
        stuck[i] = model.stuck
    return y, n, stuck


def assert_rest_forces(model, y, n, stuck):
    """Every sample at rest must be in force balance with static friction."""
    fs = model.Fs * (1 + FORCE_RTOL)
    inner = stuck & (y > 0.0) & (y < 100.0)
    assert np.all(np.abs(n[inner]) <= fs), np.abs(n[inner]).max()
    # At a stop the stem may be pressed into it, never pulled away by more than Fs.
    assert np.all(n[stuck & (y == 100.0)] >= -fs)
    assert np.all(n[stuck & (y == 0.0)] <= fs)


def random_walk(rng, n, low, high, hold=5):
    """Piecewise-constant random input with some ramps, held ``hold`` samples per level."""
    levels = rng.uniform(low, high, n // hold + 1)
    u = np.repeat(levels, hold)[:n]
    ramp = np.linspace(low, high, n // 4)
    u[: ramp.size] = ramp
    return u


# -- (a) the stuck band ------------------------------------------------------
@pytest.mark.parametrize('tau_ip', [0.0, 3.571])
def test_holds_inside_static_band_from_rest(tau_ip):
    """From a rest with no stored friction force, inputs keeping |N| < Fs move nothing."""
    m = Physical(tau_ip=tau_ip, sample_time=0.5)
    rng = np.random.default_rng(1)
    # N = A*(p - p0) from the quasi-static rest at u0, and p stays within the
    # range of p_cmd, so |u - u0| < 0.95*Fs/(A*dp)*100 keeps |N| < 0.95*Fs.
    band = 0.95 * m.Fs / force_span() * 100.0
    u = 50.0 + rng.uniform(-band, band, 400)
    u[:50] = 50.0 + band * np.sin(np.linspace(0, 6 * np.pi, 50))
    u[0] = 50.0
    y, n, stuck = run_steps(m, u)
    assert np.all(y == y[0])
    assert np.all(stuck)
    assert np.all(np.abs(n) < m.Fs)
    assert y[0] == pytest.approx(QS['gain'] * (50.0 - QS['D']), abs=1e-9)


@pytest.mark.parametrize('integrator', ['exact', 'substep'])
def test_holds_inside_static_band_after_motion(integrator):
    """After a stroke the stem holds for any input that keeps |N| < Fs, and the band is S wide."""
    m = Physical(tau_ip=0.0, sample_time=0.2, integrator=integrator, substep=1e-4)
    for u in np.r_[np.full(5, 30.0), np.full(40, 60.0)]:
        m.step(u)
    assert m.stuck
    n0 = m.net_force()
    y0 = m.position
    # The stem stopped after sliding up, so friction holds Fc downwards (plus
    # at most the viscous force at the stick speed).
    assert m.Fc - 1e-6 <= n0 <= m.Fc + m.Fv * m.v_stick + 1e-6
    span = force_span()
    low = 60.0 - (n0 + m.Fs) / span * 100.0
    high = 60.0 + (m.Fs - n0) / span * 100.0
    # Towards the reversal side the band that holds the stem is S wide.
    assert 60.0 - low == pytest.approx(QS['S'], abs=m.Fv * m.v_stick / span * 100.0 + 1e-9)
    rng = np.random.default_rng(2)
    margin = 0.02 * (high - low)
    u = rng.uniform(low + margin, high - margin, 60)
    y, n, stuck = run_steps(m, u)
    assert np.all(y == y0) and np.all(stuck)
    # Just outside the band on either side the stem breaks away.
    for target in (low - margin, high + margin):
        m2 = Physical(tau_ip=0.0, sample_time=0.2, integrator=integrator, substep=1e-4)
        for u in np.r_[np.full(5, 30.0), np.full(40, 60.0)]:
            m2.step(u)
        assert m2.step(target) != y0


# -- (b) travel limits ---------------------------------------------------------
@pytest.mark.parametrize('params', [
    {},
    {'tau_ip': 0.0},
    # A stronger actuator and preload: the stem is driven hard into both stops.
    {'A': 0.07, 'F0': 3700.0, 'tau_ip': 0.0},
    {'A': 0.07, 'F0': 3700.0, 'Fv': 50.0, 'tau_ip': 0.2},
])
def test_stays_within_travel_for_wild_inputs(params):
    """Inputs far outside [0, 100] keep the stem in [0, 100] %, at rest at the stops."""
    m = Physical(sample_time=0.5, **params)
    rng = np.random.default_rng(3)
    u = random_walk(rng, 300, -500.0, 600.0, hold=8)
    u[100:130] = 1e6
    u[130:160] = -1e6
    y, n, stuck = run_steps(m, u)
    assert np.all((y >= 0.0) & (y <= 100.0))
    assert np.any(y == 0.0)
    if params.get('A', 0) > 0.06:
        assert np.any(y == 100.0)
        assert np.all(y[125:130] == 100.0)
    assert_rest_forces(m, y, n, stuck)


def test_leaves_top_stop_only_when_pulled_beyond_fs():
    """At the top stop the stem stays while N >= -Fs and leaves once N < -Fs."""
    m = Physical(A=0.07, tau_ip=0.0, sample_time=0.5)
    m.step(100.0)
    for _ in range(20):
        m.step(100.0)
    assert m.position == 100.0 and m.stuck
    x_max_force = m.k * m.x_max + m.F0
    span = force_span(A=0.07)
    # Input where N = A*p_cmd - k*x_max - F0 equals -Fs.
    u_leave = ((x_max_force - m.Fs) / m.A - m.p_min) / (m.p_max - m.p_min) * 100.0
    # 0.05 % of input is 0.05/100*span, about 4 N short of / beyond Fs.
    assert 0.05 / 100.0 * span < 0.01 * m.Fs
    assert m.step(u_leave + 0.05) == 100.0
    assert m.step(u_leave - 0.05) < 100.0


# -- (c) exact against substep ---------------------------------------------------
def test_exact_matches_substep_on_sinusoid_at_1ms():
    """
    Exact and substep agree within 2e-3 % on a slow sinusoid at Ts = 1 ms.

    The substep scheme is first order: its position error is about substep
    times the speed scale of the slow mechanical pole, and its event times
    are quantized to one substep; at substep = 1e-5 s this is ~1e-4 % here.
    """
    ts = 1e-3
    t = np.arange(6000) * ts
    u = 50.0 + 40.0 * np.sin(2 * np.pi * t / 4.0)
    kw = {'sample_time': ts, 'tau_ip': 0.2}
    ye = Physical(**kw).simulate(u)
    ys = Physical(integrator='substep', substep=1e-5, **kw).simulate(u)
    assert np.ptp(ye) > 20.0
    assert np.abs(ye - ys).max() < 2e-3


@pytest.mark.parametrize('tau_ip', [0.0, 3.571])
def test_exact_matches_substep_on_steps_at_1s(tau_ip):
    """
    On steps at Ts = 1 s the substep error shrinks ~10x per 10x smaller substep (first order).

    That convergence shows the exact integrator is the limit the substep one
    approaches; the absolute gap at substep = 1e-5 s is below 1e-3 %.
    """
    u = np.repeat([50.0, 65.0, 45.0, 20.0, 70.0, 30.0, 30.5], 6)
    kw = {'sample_time': 1.0, 'tau_ip': tau_ip}
    ye = Physical(**kw).simulate(u)
    err = []
    for sub in (1e-4, 1e-5):
        ys = Physical(integrator='substep', substep=sub, **kw).simulate(u)
        err.append(np.abs(ye - ys).max())
    assert np.ptp(ye) > 10.0
    assert err[1] < 1e-3
    assert err[1] < err[0] / 4.0


@pytest.mark.parametrize('ts, sub, tau_ip', [(1e-4, 1e-5, 0.0), (10.0, 1e-4, 3.571)])
def test_exact_matches_substep_at_extreme_sample_times(ts, sub, tau_ip):
    """The exact integrator stays right at Ts = 1e-4 s and at Ts = 10 s."""
    if ts < 1e-3:
        t = np.arange(20000) * ts
        u = 50.0 + 60.0 * np.sin(2 * np.pi * t / 1.0)
    else:
        u = np.repeat([50.0, 80.0, 60.0, 10.0, 40.0], 2)
    ye = Physical(sample_time=ts, tau_ip=tau_ip).simulate(u)
    ys = Physical(sample_time=ts, tau_ip=tau_ip, integrator='substep', substep=sub).simulate(u)
    assert np.ptp(ye) > 20.0
    assert np.abs(ye - ys).max() < 20 * sub / 1e-5 * 1e-4


def test_underdamped_valve_exact_matches_substep():
    """With little viscous friction the stem rings; both integrators see the same stops."""
    u = np.repeat([50.0, 80.0, 40.0, 90.0], 2)
    kw = {'sample_time': 0.25, 'tau_ip': 0.0, 'Fv': 0.0}
    ye = Physical(**kw).simulate(u)
    ys = Physical(integrator='substep', substep=1e-6, **kw).simulate(u)
    assert np.abs(ye - ys).max() < 1e-4


@pytest.mark.parametrize('kw, u', [
    ({'sample_time': 1e-3, 'tau_ip': 0.2},
     50.0 + 40.0 * np.sin(2 * np.pi * np.arange(8000) * 1e-3 / 4.0)),
    ({'sample_time': 1.0}, np.repeat([50.0, 65.0, 45.0, 20.0, 70.0, 30.0, 30.5, 120.0, -5.0], 6)),
    ({'sample_time': 1e-4, 'tau_ip': 0.0},
     50.0 + 60.0 * np.sin(2 * np.pi * np.arange(20000) * 1e-4)),
    ({'sample_time': 0.25, 'tau_ip': 0.0, 'Fv': 0.0}, np.repeat([50.0, 80.0, 40.0, 90.0], 2)),
    ({'sample_time': 0.1, 'v_stick': 0.0},
     random_walk(np.random.default_rng(3), 3000, 0.0, 100.0)),
])
def test_compiled_exact_integrator_is_the_python_one(kw, u):
    """
    The compiled exact integrator retraces its pure-Python reference sample for sample.

    Only the order of the floating-point sums differs (the products with the
    propagators are written out), so the two agree to rounding: 1e-9 % of travel.
    """
    m = Physical(**kw)
    fast = m.simulate(u)
    ref = m.simulate_reference(u)
    assert np.ptp(ref) > 10.0
    assert np.abs(fast - ref).max() < 1e-9
    # Same stuck/moving state at the end, so a continued run stays together too.
    m.reset()
    m.simulate(u[: u.size // 2])
    state_fast = m.state.copy()
    m.reset()
    m.simulate_reference(u[: u.size // 2])
    assert np.allclose(state_fast, m.state, rtol=1e-9, atol=1e-12)


# -- (d) force balance at rest -------------------------------------------------------
@pytest.mark.parametrize('params', [
    {},
    {'tau_ip': 0.0},
    {'v_stick': 0.0},
    {'Fv': 20.0, 'tau_ip': 0.0},
    {'integrator': 'substep', 'substep': 1e-4, 'sample_time': 0.05, 'tau_ip': 0.2},
    {'stribeck': True, 'substep': 1e-4, 'sample_time': 0.05, 'tau_ip': 0.2},
])
def test_rest_is_force_balanced(params):
    """Whenever the stem is at rest inside the travel, |A*p - k*x - F0| <= Fs."""
    kw = {'sample_time': 0.5}
    kw.update(params)
    m = Physical(**kw)
    rng = np.random.default_rng(4)
    u = random_walk(rng, 400, -10.0, 110.0, hold=6)
    y, n, stuck = run_steps(m, u)
    assert_rest_forces(m, y, n, stuck)
    # Not vacuous: the stem came to rest after moving many times.
    stops = stuck[1:] & ((y[1:] != y[:-1]) | ~stuck[:-1])
    assert np.count_nonzero(stops) >= 5
    assert np.ptp(y) > 30.0


@pytest.mark.parametrize('direction', [1.0, -1.0])
def test_rest_after_slide_balances_coulomb_friction(direction):
    """A stroke ends where pressure, spring and Coulomb friction balance: N = d*Fc."""
    m = Physical(sample_time=1.0)
    u1 = 50.0 + direction * 20.0
    for u in np.r_[np.full(3, 50.0), np.full(60, u1)]:
        m.step(u)
    assert m.stuck
    n = m.net_force()
    # The stem sticks when its speed falls below v_stick, so N exceeds d*Fc by
    # at most the viscous force there, Fv*v_stick; then p creeps on towards
    # p_cmd, at most by tau_ip*dp/dt = tau_ip*k*v_stick/A at that moment.
    slack = m.v_stick * (m.Fv + m.tau_ip * m.k) + 1e-6
    assert 0.0 <= direction * n - m.Fc <= slack
    y_line = QS['gain'] * (u1 - QS['D'] - direction * m.Fc / force_span() * 100.0)
    assert m.position == pytest.approx(y_line, abs=slack / m.k / m.x_max * 100.0)


# -- (e) the data-driven equivalent ---------------------------------------------------
def measure_sj(u, y, gain, d_offset, settle):
    """
    Measure S and J (input axis) at each breakaway of an MV-OP record.

    S: input range over a run of samples where the stem does not move.  J:
    stem motion (mapped to the input axis with ``D + y/gain``) from the last
    stuck sample to ``settle`` samples after breakaway, minus the input
    motion over the same samples, i.e. the jump beyond following the input.
    """
    z = d_offset + y / gain
    still = np.r_[False, y[1:] == y[:-1]]
    s_list, j_list = [], []
    k = 1
    while k < len(y):
        if not still[k]:
            k += 1
            continue
        first = k - 1
        while k < len(y) and still[k]:
            k += 1
        last = k - 1
        if first > 0 and k + settle < len(y):
            seg = u[first:last + 1]
            s_list.append(seg.max() - seg.min())
            m = k + settle
            j_list.append(abs(z[m] - z[last]) - abs(u[m] - u[last]))
    return np.array(s_list), np.array(j_list)


def test_slow_sinusoid_gives_quasi_static_s_and_j():
    """
    A slow sinusoid without I/P lag reproduces quasi_static_sj's S and J.

    Tolerances, each an upper bound of a known effect (doubled for safety):
    * sampling: breakaway is seen to one sample, du <= 2*pi*a/T*Ts;
    * early stop: the stem sticks when its speed falls below v_stick, a
      little before the input peaks; with a zero-order-hold input its speed
      at the end of each sample is g = (Ts/tm)/(exp(Ts/tm)-1) times the
      tracking speed (tm = Fv/k), so it stops when
      cos(phase) < v_stick/(g*v_max), which widens S by a/2*(that ratio)^2;
    * viscous lag: while sliding the stem trails by Fv*v/(A*dp)*100 % at the
      speed v it has after breakaway, which shrinks the measured J.
    The I/P lag is set to 0 because it shifts the pressure reversal behind
    the input reversal by ~tau_ip*du/dt and widens the apparent S.
    """
    ts, period, amp = 0.1, 20000.0, 40.0
    m = Physical(sample_time=ts, tau_ip=0.0)
    t = np.arange(int(1.5 * period / ts)) * ts
    u = 50.0 + amp * np.sin(2 * np.pi * t / period)
    y = m.simulate(u)
    settle = int(math.ceil(10 * m.Fv / m.k / ts))
    s_meas, j_meas = measure_sj(u, y, QS['gain'], QS['D'], settle)
    assert len(s_meas) >= 2
    span = force_span()
    w = 2 * np.pi / period
    to_speed = m.x_max / 100.0 * QS['gain']
    du = amp * w * ts
    tm = m.Fv / m.k
    g = (ts / tm) / math.expm1(ts / tm)
    v_max = to_speed * amp * w
    early = amp / 2 * (m.v_stick / (g * v_max)) ** 2
    u_b = 50.0 + amp - QS['S']
    v_b = to_speed * w * math.sqrt(amp ** 2 - (u_b - 50.0) ** 2)
    visc = m.Fv * v_b / span * 100.0
    tol_s = 2 * (du + early)
    tol_j = 2 * (du + visc)
    assert tol_s < 0.05 and tol_j < 0.05
    assert np.all(np.abs(s_meas - QS['S']) <= tol_s), (s_meas, tol_s)
    assert np.all(np.abs(j_meas - QS['J']) <= tol_j), (j_meas, tol_j)
    # The gap between opening and closing lines is 2*fd = S - J, with gain and D as mapped.
    moving = np.r_[False, y[1:] != y[:-1]]
    d = np.sign(np.gradient(u))
    coef = np.linalg.lstsq(np.c_[u, np.ones_like(u), d][moving], y[moving], rcond=None)[0]
    assert coef[0] == pytest.approx(QS['gain'], rel=2e-3)
    assert -coef[1] / coef[0] == pytest.approx(QS['D'], abs=0.05)
    assert -2 * coef[2] / coef[0] == pytest.approx(QS['S'] - QS['J'], abs=0.05)


def test_quasi_static_mapping_of_default_valve():
    """The default valve maps to J = 1.297 % and D = 11.49 %, as its source says."""
    assert QS['J'] == pytest.approx(1.297, abs=5e-4)
    assert QS['D'] == pytest.approx(11.49, abs=5e-3)
    assert QS['S'] == pytest.approx(23.990, abs=5e-4)
    # The source's S = 25.287 % equals 2*Fs/(A*dp)*100, the full static band.
    assert 2 * DEFAULTS['Fs'] / force_span() * 100 == pytest.approx(25.287, abs=5e-4)
    assert QS['gain'] == pytest.approx(force_span() / (DEFAULTS['k'] * DEFAULTS['x_max']))
    assert quasi_static_sj(Fs=900.0)['J'] > QS['J']
    with pytest.raises(ModelError):
        quasi_static_sj(mass=1.0)


# -- (f) step() against simulate() ------------------------------------------------------
@pytest.mark.parametrize('params', [
    {},
    {'tau_ip': 0.0, 'sample_time': 0.05},
    {'integrator': 'substep', 'substep': 1e-3},
    {'stribeck': True, 'substep': 1e-3},
    {'dFs': 300.0, 'gamma': 5.0, 'asym': 0.2, 'hold': 'foh', 'substep': 1e-3},
])
def test_step_equals_simulate(params):
    """Running sample by sample gives bit-identical positions to a whole-array run."""
    rng = np.random.default_rng(5)
    u = random_walk(rng, 150, -20.0, 120.0, hold=4)
    m = Physical(**params)
    y_sim = m.simulate(u)
    m.reset()
    y_step = np.array([m.step(ui) for ui in u])
    np.testing.assert_array_equal(y_sim, y_step)
    # simulate(u, y0) rests the valve under its first input (models/base.py).
    m.reset(30.0, u_rest=u[0])
    y_step0 = np.array([m.step(ui) for ui in u])
    np.testing.assert_array_equal(y_step0, Physical(**params).simulate(u, y0=30.0))


def test_stribeck_falls_back_to_substep():
    """With Stribeck friction 'exact' runs the substep integrator and gives its result."""
    u = np.repeat([50.0, 70.0, 40.0], 3)
    kw = {'stribeck': True, 'sample_time': 0.5, 'substep': 1e-4, 'tau_ip': 0.0}
    a = Physical(**kw).simulate(u)
    b = Physical(integrator='substep', **kw).simulate(u)
    np.testing.assert_array_equal(a, b)
    assert np.ptp(a) > 5.0


# -- (h) the frictions of EFFECTS.md written as physics ------------------------------
# A valve with gain 1 and no offset (spring and preload matched to the actuator),
# a fast I/P and light damping: the stem is on the quasi-static picture within a sample.
SPAN = force_span()
UNIT = {'k': SPAN / DEFAULTS['x_max'], 'F0': DEFAULTS['A'] * DEFAULTS['p_min'], 'Fv': 2500.0,
        'tau_ip': 0.0, 'Fs': 0.03 * SPAN, 'Fc': 0.02 * SPAN, 'substep': 1e-4}


def breakaway_input(u_path, **params):
    """Return the input at which the stem first moves along ``u_path`` (from rest at u[0])."""
    m = Physical(**{**UNIT, **params})
    y = m.simulate(u_path, y0=50.0)
    moved = np.flatnonzero(np.abs(y - 50.0) > 1e-6)
    return u_path[moved[0]] if moved.size else None


def test_dwell_static_friction_needs_more_force_after_a_longer_rest():
    """Fs + dFs t/(t + gamma): the input travel to break away grows with the time at rest."""
    rate, gamma = 0.1, 20.0
    travel = []
    for rest in (2, 20, 200):
        u = np.concatenate([np.full(rest, 50.0), 50.0 + rate * np.arange(1, 200)])
        travel.append(breakaway_input(u, dFs=0.02 * SPAN, gamma=gamma) - 50.0)
        # The stem still rests during the ramp: it breaks away at the travel x where
        # x = 3 + 2 t/(t + gamma) % with t = rest + x/rate seconds at rest.
        expected = brentq(lambda x: x - 3.0 - 2.0 * (rest + x / rate) / (rest + x / rate + gamma),
                          0.0, 10.0)
        assert travel[-1] == pytest.approx(expected, abs=rate + 0.01)
    assert travel[0] < travel[1] < travel[2]
    plain = np.concatenate([np.full(200, 50.0), 50 + rate * np.arange(1, 200)])
    assert breakaway_input(plain) - 50.0 == pytest.approx(3.0, abs=rate + 0.01)


@pytest.mark.parametrize('asym', [0.2, -0.2])
def test_asymmetric_friction_breaks_away_later_in_the_stiffer_direction(asym):
    """Friction forces times 1 + asym opening and 1 - asym closing."""
    up = breakaway_input(50.0 + 0.01 * np.arange(0, 800), asym=asym) - 50.0
    down = 50.0 - breakaway_input(50.0 - 0.01 * np.arange(0, 800), asym=asym)
    assert up == pytest.approx(3.0 * (1 + asym), abs=0.02)
    assert down == pytest.approx(3.0 * (1 - asym), abs=0.02)


def test_first_order_hold_ends_each_sample_on_the_kinetic_line():
    """Ramping the command through the sample keeps a driven stem sliding, as Kano's model does."""
    u = np.concatenate([np.full(5, 50.0), 50.0 + 0.5 * np.arange(1, 40)])
    foh = Physical(**UNIT, hold='foh').simulate(u, y0=50.0)
    zoh = Physical(**UNIT).simulate(u, y0=50.0)
    moving = slice(20, None)
    # Sliding at constant speed the stem lags its input by the Coulomb band Fc (2 % here).
    np.testing.assert_allclose(foh[moving], u[moving] - 2.0, atol=0.05)
    # Held input: the stem comes to rest within each sample and must break away again.
    assert np.max(np.abs(zoh[moving] - (u[moving] - 2.0))) > 0.5


def test_set_params_keeps_state_and_applies_next_sample():
    """Changing the sample time mid-run keeps the position and rebuilds the propagators."""
    m = Physical(sample_time=1.0)
    for u in np.r_[np.full(3, 50.0), np.full(30, 70.0)]:
        y = m.step(u)
    m.set_params(sample_time=0.1)
    assert m.position == y
    assert m.step(70.0) == pytest.approx(y, abs=1e-3)
    ys = [m.step(30.0) for _ in range(600)]
    assert ys[-1] < y - 5.0


def test_initial_state_rests_at_given_position():
    """Given y0 inside the static band the stem stays there; otherwise at the spring balance."""
    m = Physical(sample_time=1.0)
    y = m.simulate(np.full(20, 50.0), y0=QS['gain'] * (50.0 - QS['D']) + 1.0)
    assert np.all(y == y[0]) and y[0] == pytest.approx(QS['gain'] * (50.0 - QS['D']) + 1.0)
    assert np.all(m.simulate(np.full(5, 5.0)) == 0.0)


# -- (g) invalid parameters ------------------------------------------------------
@pytest.mark.parametrize('params, words', [
    ({'Fs': 600.0}, 'Fs'),
    ({'M': -1.0}, 'M'),
    ({'A': 0.01}, 'cannot move'),
    ({'p_min': 150000.0, 'p_max': 170000.0}, 'cannot move'),
    ({'p_min': 200000.0}, 'p_max'),
    ({'integrator': 'rk4'}, 'integrator'),
    ({'stribeck': 'yes'}, 'stribeck'),
    ({'integrator': 'substep', 'substep': 0.01}, 'substep'),
    ({'mass': 1.0}, 'unknown'),
    ({'Fv': float('nan')}, 'Fv'),
])
def test_invalid_parameters_raise(params, words):
    """Physically impossible or malformed parameters raise ModelError naming the cause."""
    with pytest.raises(ModelError, match=words):
        Physical(**params)


def test_failed_set_params_changes_nothing():
    """A rejected parameter change leaves the model as it was."""
    m = Physical()
    before = m.params
    with pytest.raises(ModelError):
        m.set_params(Fc=500.0, Fs=400.0)
    assert m.params == before
