"""The sampled PI(D) must give the textbook responses at the sample instants."""

import numpy as np
import pytest

from stiction_ros.sim.controller import PID


def test_pi_response_to_constant_error_is_kc_e_one_plus_t_over_ti():
    kc, ti, ts, e = 0.2, 10.0, 0.5, 1.5
    c = PID(Kc=kc, Ti=ti, sample_time=ts, bias=50.0, op_min=-1e9, op_max=1e9)
    ops = np.array([c.update(e, 0.0) for _ in range(100)])
    t = np.arange(100) * ts
    np.testing.assert_allclose(ops, 50.0 + kc * e * (1 + t / ti), atol=1e-12)


def test_direct_action_reverses_the_sign():
    c = PID(Kc=1.0, Ti=5.0, bias=0.0, action='direct', op_min=-100, op_max=100)
    assert c.update(0.0, 1.0) == pytest.approx(1.0)


def test_anti_windup_releases_immediately_when_the_error_reverses():
    c = PID(Kc=1.0, Ti=2.0, sample_time=1.0, bias=50.0)
    for _ in range(200):
        c.update(100.0, 0.0)  # drives the output into its upper limit
    assert c.op == 100.0
    # Without windup the output leaves the limit on the first sample of negative error.
    assert c.update(0.0, 1.0) < 100.0


def test_derivative_on_pv_gives_no_kick_on_setpoint_step():
    c = PID(Kc=1.0, Ti=0.0, Td=5.0, N=10.0, sample_time=0.1, bias=0.0, op_min=-1e3, op_max=1e3)
    c.update(0.0, 0.0)
    assert c.update(1.0, 0.0) == pytest.approx(1.0)  # proportional part only
    # a PV ramp of slope r gives a derivative contribution tending to -Kc Td r
    for k in range(1, 400):
        op = c.update(0.0, 0.01 * k)
    assert op == pytest.approx(-0.01 * 399 - 5.0 * 0.01 / 0.1, rel=1e-6)


def test_invalid_tuning_is_rejected_and_changes_nothing():
    c = PID(Kc=0.2, Ti=10.0)
    with pytest.raises(ValueError, match='Ti'):
        c.set_gains(Kc=0.5, Ti=-1.0)
    assert (c.Kc, c.Ti) == (0.2, 10.0)
    with pytest.raises(ValueError, match='op_min'):
        c.set_gains(op_min=100.0, op_max=0.0)
