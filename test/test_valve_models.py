"""Properties the physics of a sticky valve demands of the data-driven models."""

import math
import subprocess
import sys
import textwrap

import numpy as np
import pytest
from scipy import signal

from stiction_ros.analysis.measures.measure_sj import measure_sj
from stiction_ros.models import Choudhury, create, He, Kano, Linear, ModelError, MODELS, Stenman

TWO_PARAM = ('kano', 'choudhury', 'he')
CASES = [(5.0, 0.0), (5.0, 2.0), (5.0, 5.0), (5.0, 7.0), (10.0, 3.0), (0.4, 0.1)]


def slow_sine(amplitude=20.0, period=10000, cycles=4, offset=50.0):
    t = np.arange(period * cycles, dtype=float)
    return offset + amplitude * np.sin(2 * np.pi * t / period)


def random_walk(n=3000, seed=1, std=1.0):
    rng = np.random.default_rng(seed)
    return np.clip(50 + np.cumsum(rng.normal(0, std, n)), -20, 120)


@pytest.mark.parametrize('name', TWO_PARAM + ('stenman',))
def test_ideal_valve_follows_input(name):
    u = random_walk()
    kw = {'S': 0.0} if name == 'stenman' else {'S': 0.0, 'J': 0.0}
    y = create(name, **kw).simulate(u)
    np.testing.assert_allclose(y, np.clip(u, 0, 100), atol=1e-12)


@pytest.mark.parametrize('name', TWO_PARAM)
def test_pure_deadband_never_jumps(name):
    u = random_walk(std=0.3)
    y = create(name, S=5.0, J=0.0).simulate(u)
    # Without a slip jump the output can move at most as far as the input did.
    assert np.max(np.abs(np.diff(y))) <= np.max(np.abs(np.diff(u))) + 1e-9


@pytest.mark.parametrize('name', TWO_PARAM)
@pytest.mark.parametrize('S,J', CASES)
def test_sj_measured_from_slow_sinusoid_equal_parameters(name, S, J):
    u = slow_sine()
    y = create(name, S=S, J=J).simulate(u)
    got = measure_sj(u, y)
    assert got['reversals'] >= 6
    # Each breakaway overshoots its threshold by less than one input step.
    tol = got['max_step'] + 1e-9
    assert got['S'] == pytest.approx(S, abs=tol)
    assert got['J'] == pytest.approx(J, abs=tol)


@pytest.mark.parametrize('S,J', CASES)
def test_moving_valve_lags_input_by_kinetic_band(S, J):
    u = slow_sine()
    got = measure_sj(u, Kano(S=S, J=J).simulate(u))
    assert got['fd'] == pytest.approx((S - J) / 2, abs=1e-9)
    assert got['J_bands'] == pytest.approx(J, abs=got['max_step'] + 1e-9)


@pytest.mark.parametrize('S,J', CASES)
@pytest.mark.parametrize('amplitude,period', [(20.0, 500), (4.0, 97), (30.0, 3001)])
def test_kano_and_choudhury_agree_on_smooth_sinusoids(S, J, amplitude, period):
    u = slow_sine(amplitude, period, cycles=5)
    k = Kano(S=S, J=J).simulate(u)
    c = Choudhury(S=S, J=J).simulate(u)
    np.testing.assert_allclose(k[period:], c[period:], atol=1e-12)


@pytest.mark.parametrize('name', sorted(MODELS))
def test_output_stays_within_travel(name):
    u = np.concatenate([np.linspace(50, 250, 400), np.linspace(250, -150, 800),
                        np.linspace(-150, 50, 400)])
    kw = {k: 7.0 for k in ('S', 'J') if k in MODELS[name].PARAMS}
    y = create(name, **kw).simulate(u)
    assert y.min() >= 0.0 and y.max() <= 100.0


def test_choudhury_saturates_fully_open_and_closed():
    u = np.concatenate([np.linspace(50, 130, 200), np.full(20, 130.0),
                        np.linspace(130, -30, 400), np.full(20, -30.0)])
    y = Choudhury(S=5.0, J=2.0).simulate(u)
    assert np.all(y[u >= 100] == 100.0)
    assert np.all(y[u <= 0] == 0.0)
    # Leaving the stop: stuck until the input is fs below it, then a jump of J.
    back = np.flatnonzero((u < 100) & (np.arange(len(u)) > 220))
    first_move = back[np.flatnonzero(y[back] < 100.0)[0]]
    assert 100 - u[first_move] == pytest.approx(3.5, abs=0.41)
    assert 100 - y[first_move] - (100 - u[first_move] - 3.5) == pytest.approx(2.0, abs=0.41)


def test_kano_treats_input_beyond_range_as_the_bound():
    u = np.concatenate([np.linspace(50, 160, 300), np.linspace(160, -60, 600)])
    np.testing.assert_array_equal(Kano(S=4.0, J=1.0).simulate(u),
                                  Kano(S=4.0, J=1.0).simulate(np.clip(u, 0, 100)))


@pytest.mark.parametrize('name', sorted(MODELS))
def test_step_equals_simulate(name):
    u = random_walk(n=600, std=0.8)
    kw = {k: v for k, v in (('S', 3.0), ('J', 1.0)) if k in MODELS[name].PARAMS}
    if name == 'physical':
        kw = {'sample_time': 0.5}
    model = create(name, **kw)
    whole = model.simulate(u)
    model.reset()
    one_by_one = np.array([model.step(x) for x in u])
    np.testing.assert_array_equal(whole, one_by_one)


COMPILED_CASES = [
    ('kano', {}), ('kano', {'tau': 3.0}),
    ('choudhury', {}), ('choudhury', {'lam': 0.6}),
    ('choudhury', {'characteristic': 'equal_percentage', 'output_units': 'mA'}),
    ('choudhury', {'characteristic': 'square_root', 'input_units': 'mA'}),
    ('he', {}), ('stenman', {}),
]


@pytest.mark.parametrize('name, extra', COMPILED_CASES)
@pytest.mark.parametrize('S, J', [(3.0, 1.0), (4.0, 4.0), (2.0, 0.0), (2.0, 5.0), (0.0, 0.0)])
def test_compiled_kernel_is_the_pure_python_model_sample_for_sample(name, extra, S, J):
    # simulate() runs compiled code; the pure-Python kernel next to each model is the
    # oracle.  Random walks through both end stops, a sine, steps and a constant stretch
    # visit every branch (stick, slip, reversal, saturation).
    kw = {k: v for k, v in (('S', S), ('J', J)) if k in MODELS[name].PARAMS}
    model = create(name, **kw, **extra)
    u = np.concatenate([random_walk(4000, seed=7, std=2.0), slow_sine(30.0, 700, 2),
                        np.repeat([20.0, 80.0, 79.0, 81.0], 50), np.full(30, 81.0)])
    if extra.get('input_units') == 'mA':
        u = 4.0 + 0.16 * u
    for y0 in (None, 37.5):
        fast, reference = model.simulate(u, y0=y0), model.simulate_reference(u, y0=y0)
        np.testing.assert_array_equal(fast, reference)
        # The state a run leaves behind is the same too, so step() continues alike.
        after = model.step(u[-1] + 1.0)
        model.simulate_reference(u, y0=y0)
        assert model.step(u[-1] + 1.0) == after


def test_stuck_valve_holds_inside_the_band():
    # After a reversal the valve stays put while the input wanders less than S.
    wander = 2.4 * np.abs(np.sin(np.linspace(0, 20, 800)))
    u = np.concatenate([np.linspace(40, 60, 200), 60 - wander])
    y = Kano(S=5.0, J=1.0).simulate(u)
    assert np.ptp(y[200:]) == 0.0


def test_stenman_jumps_to_input_once_band_exceeded():
    u = random_walk(std=0.5)
    y = Stenman(S=2.0).simulate(u)
    held = np.diff(y) == 0
    jumped = ~held
    assert np.all(y[1:][jumped] == np.clip(u[1:], 0, 100)[jumped])
    assert np.all(np.abs(np.clip(u[1:], 0, 100) - y[:-1])[held] < 2.0)


def test_he_sticks_while_moving_slower_than_the_jump_per_sample():
    # He's model re-engages static friction every sample: a slow ramp moves in
    # steps of about J, a fast one smoothly.
    slow = He(S=5.0, J=2.0).simulate(np.linspace(40, 60, 2001))
    steps = np.diff(slow)[200:]
    assert steps[steps > 0].min() > 1.9
    fast = He(S=5.0, J=2.0).simulate(np.linspace(40, 80, 11))
    assert np.all(np.diff(fast)[2:] > 0)


def test_parameters_change_live_and_validate():
    m = Kano(S=5.0, J=2.0)
    m.step(50.0)
    m.set_params(S=7.0)
    assert m.S == 7.0 and m.J == 2.0
    with pytest.raises(ModelError, match='S'):
        m.set_params(S=-1.0)
    with pytest.raises(ModelError, match='unknown'):
        m.set_params(Q=1.0)
    assert m.S == 7.0  # a rejected change leaves everything as it was
    with pytest.raises(ModelError, match='unknown valve model'):
        create('kanoo')
    with pytest.raises(ModelError, match='finite'):
        Kano(S=math.nan)
    with pytest.raises(ModelError, match='index 2'):
        Kano(S=1.0).simulate([1.0, 2.0, math.nan])


def test_linear_model_is_the_identity_within_travel():
    u = random_walk()
    np.testing.assert_array_equal(Linear().simulate(u), np.clip(u, 0, 100))


def test_choudhury_ma_input_matches_percent_input():
    u = random_walk()
    pct = Choudhury(S=4.0, J=1.0).simulate(u)
    ma = Choudhury(S=4.0, J=1.0, input_units='mA').simulate(4 + u * 0.16)
    np.testing.assert_allclose(ma, pct, atol=1e-9)
    out_ma = Choudhury(S=4.0, J=1.0, output_units='mA').simulate(u)
    np.testing.assert_allclose(out_ma, 4 + pct * 0.16, atol=1e-12)


def test_choudhury_ewma_is_eq_2_5():
    u = 50 + np.random.default_rng(3).normal(0, 5, 500)
    lam = 0.1
    y = Choudhury(lam=lam).simulate(u)
    # G_f(z) = lam z / (z - (1 - lam)), started in steady state at u[0]
    zi = signal.lfiltic([lam], [1, -(1 - lam)], y=[u[0]])
    ref, _ = signal.lfilter([lam], [1, -(1 - lam)], u, zi=zi)
    np.testing.assert_allclose(y, np.clip(ref, 0, 100), atol=1e-9)


@pytest.mark.parametrize('char,pos,flow', [
    ('linear', 50, 50.0),
    ('square_root', 25, 50.0),
    ('equal_percentage', 50, 100 * (math.sqrt(50) - 1) / 49),
])
def test_choudhury_flow_characteristics(char, pos, flow):
    m = Choudhury(characteristic=char)
    assert m.simulate([pos])[0] == pytest.approx(flow)
    # Monotone and from shut to fully open.
    y = m.simulate(np.linspace(0, 100, 101))
    assert y[0] == pytest.approx(0.0) and y[-1] == pytest.approx(100.0)
    assert np.all(np.diff(y) > 0)


def test_kano_air_chamber_is_a_first_order_lag():
    ts, tau = 0.5, 3.0
    u = np.r_[np.full(5, 40.0), np.full(100, 60.0)]
    y = Kano(tau=tau, sample_time=ts).simulate(u)
    sysd = signal.cont2discrete(([1.0], [tau, 1.0]), ts, method='zoh')
    b, a = np.ravel(sysd[0]), sysd[1]
    zi = signal.lfiltic(b, a, y=[40.0], x=[40.0])
    ref, _ = signal.lfilter(b, a, u, zi=zi)
    # the lag acts on the current sample, so it leads scipy's ZOH form by one sample
    np.testing.assert_allclose(y[:-1], ref[1:], atol=1e-9)


STICKY = [('kano', {'S': 6.0, 'J': 2.0}), ('kano', {'S': 6.0, 'J': 2.0, 'tau': 2.0}),
          ('choudhury', {'S': 6.0, 'J': 2.0}), ('he', {'S': 6.0, 'J': 2.0}),
          ('stenman', {'S': 6.0}), ('kano_effects', {'S': 6.0, 'J': 2.0})]


@pytest.mark.parametrize('name, kw', STICKY)
@pytest.mark.parametrize('y0', [21.0, 37.0, 50.0, 79.0])
@pytest.mark.parametrize('sign', [1.0, -1.0])
def test_a_valve_put_at_rest_moves_once_the_commanded_change_exceeds_its_band(name, kw, y0,
                                                                              sign):
    # The chapter's models: a valve at rest under its input breaks away once the input has
    # moved more than the static band from it, whatever the first input is.
    model = create(name, **kw)
    target = y0 + sign * 20.0
    model.reset(y0=y0)
    moved = [model.step(target) for _ in range(20)]
    assert sign * (moved[-1] - y0) > 10.0, moved
    assert abs(moved[-1] - target) <= kw['S'], moved
    # A change inside the deadband (S - J) / 2 leaves it where it is.
    model.reset(y0=y0)
    small = y0 + sign * 0.4 * (kw['S'] - kw.get('J', 0.0)) / 2.0
    assert [model.step(small) for _ in range(20)] == [y0] * 20


def test_a_physical_valve_put_at_rest_moves_once_the_pressure_change_beats_friction():
    model = create('physical', sample_time=0.1)
    # At rest at 40 % under the input whose pressure balances the spring there: a command
    # whose extra force beats static friction (Fs / (A dp) of the span) moves it toward the
    # command; one inside that band does not.
    p = model.params
    band = 100.0 * p['Fs'] / (p['A'] * (p['p_max'] - p['p_min']))
    rest = model.rest_input(40.0)
    model.reset(y0=40.0)
    far = [model.step(rest + 2.0 * band) for _ in range(200)]
    assert far[-1] > 45.0, far[-5:]
    model.reset(y0=40.0)
    near = [model.step(rest + 0.5 * band) for _ in range(200)]
    assert max(abs(x - 40.0) for x in near) < 1e-9


def test_a_model_switch_at_rest_does_not_move_the_valve():
    # The valve node switches models at rest under the OP in force (u_rest): no bump.
    model = create('kano', S=6.0, J=2.0)
    model.reset(y0=50.0)
    y = [model.step(u) for u in (55.0, 55.5, 55.5)]   # moves, then sticks near 55
    other = create('choudhury', S=6.0, J=2.0)
    other.reset(y0=y[-1], u_rest=55.5)
    assert [other.step(55.5) for _ in range(5)] == [y[-1]] * 5


def test_simulate_keeps_to_one_core():
    """
    A long simulate() runs on the calling thread only.

    Its input check once used np.dot, which OpenBLAS splits across threads that
    then spin: every call held a second core (process CPU 1.98x the wall time).
    """
    script = textwrap.dedent("""
        import time
        import numpy as np
        from stiction_ros.models import create
        op = 50 + np.cumsum(np.random.default_rng(0).normal(0, 0.5, 1_000_000))
        model = create('kano', S=5.0, J=2.0)
        model.simulate(op)
        wall, cpu = time.perf_counter(), time.process_time()
        while time.perf_counter() - wall < 1.0:
            model.simulate(op)
        print((time.process_time() - cpu) / (time.perf_counter() - wall))
    """)
    share = float(subprocess.run([sys.executable, '-c', script], capture_output=True, text=True,
                                 check=True).stdout)
    # One thread cannot use more than one core; the margin is for the clocks' granularity.
    assert share < 1.25, share
