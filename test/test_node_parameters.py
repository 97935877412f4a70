"""
Parameters of the live nodes through the standard services, as ``ros2 param`` uses them.

A valve node runs as its own process on wall time; this test tunes it with
``AsyncParameterClient`` and drives its ``op`` input over real DDS.
"""

import time

import pytest
from rcl_interfaces.msg import ParameterType
from ros_helpers import start_node, stop
from stiction_ros.resources import config_file

pytestmark = pytest.mark.ros
TS = 0.05


@pytest.fixture
def valve(probe, tmp_path):
    ns = f'/pt{time.monotonic_ns() % 10**6}'
    proc = start_node('valve', {'sample_time': TS, 'model': 'choudhury', 'S': 5.0, 'J': 2.0},
                      namespace=ns, log_dir=str(tmp_path))
    client = probe.params(f'{ns}/valve')
    yield ns, client
    assert stop(proc) == 0, (tmp_path / 'valve.log').read_text()


def test_descriptors_carry_ranges_fixed_values_and_allowed_values(probe, valve):
    _, client = valve
    res = probe.call(client, lambda c: c.describe_parameters(['S', 'sample_time', 'model', 'Fs']))
    s, ts, model, fs = res.descriptors
    assert s.type == ParameterType.PARAMETER_DOUBLE and s.description
    assert (s.floating_point_range[0].from_value, s.floating_point_range[0].to_value) == (0, 100)
    # Fixed for the run, yet not rclpy read-only: the value it has may be set again.
    assert not ts.read_only and 'fixed for the run' in ts.additional_constraints
    assert 'fixed for the run' not in s.additional_constraints
    assert 'kano' in model.additional_constraints and 'physical' in model.additional_constraints
    assert '(physical)' in fs.description


def test_valid_change_applies_and_invalid_ones_are_rejected_with_a_reason(probe, valve):
    _, client = valve
    assert probe.set_params(client, S=7.0)[0].successful
    assert probe.get_params(client, 'S') == [7.0]
    cases = {
        'S': (-1.0, ''),                          # below the declared range (rclpy)
        'model': ('kanoo', 'is not one of'),      # allowed values (on-set callback)
        'sample_time': (0.1, 'only be set at start-up'),   # fixed for the run
        'Fs': (20000.0, 'the stem cannot move'),  # a physical set that cannot move the stem
        'Fc': (900.0, 'Fs >= Fc'),                # cross-check of the physical model
    }
    for name, (value, why) in cases.items():
        res = probe.set_params(client, **{name: value})[0]
        assert not res.successful, name
        assert res.reason and why.lower() in res.reason.lower(), (name, res.reason)
    now = probe.get_params(client, 'S', 'model', 'sample_time', 'Fs')
    assert now == [7.0, 'choudhury', TS, 780.0]


def test_a_rejected_atomic_change_changes_nothing(probe, valve):
    _, client = valve
    res = probe.set_params(client, atomically=True, S=9.0, J=3.0, Fs=20000.0)[0]
    assert not res.successful
    assert probe.get_params(client, 'S', 'J', 'Fs') == [5.0, 2.0, 780.0]


def test_model_switch_is_bumpless_and_a_new_S_applies_live(probe, valve):
    ns, _ = valve
    client = probe.params(f'{ns}/valve')
    probe.listen(f'{ns}/mv')
    probe.hear(f'{ns}/op', 50.0, [ns])

    def drive(values):
        for v in values:
            probe.publish(f'{ns}/op', v)
            time.sleep(TS)

    # Step OP from 50 to 60, hold it, then come back 1.5 %: Choudhury (S 5, J 2)
    # slips to 1.5 below OP, sticks as OP stops, and OP now sits where it stuck.
    # Steps, not a ramp: a wall-clock ramp is seen with jitter, and a repeated
    # OP sample makes Choudhury's valve stick mid-ramp at a timing-dependent spot.
    drive([50.0] * 10 + [60.0] * 20 + [58.5] * 20)
    held = probe.values(f'{ns}/mv')[-1]
    assert held == pytest.approx(58.5, abs=0.3)
    n_before = len(probe.values(f'{ns}/mv'))
    assert probe.set_params(client, model='kano')[0].successful
    drive([58.5] * 20)
    after = probe.values(f'{ns}/mv')[n_before:]
    assert len(after) >= 10
    # At the switch the valve must stay where it is: the new model starts at
    # rest at the current position, not at its initial position or at OP.
    assert max(abs(v - held) for v in after) < 1e-9
    # A much larger stiction, set live, holds the valve through a 8.5 % move
    # that S = 5 would follow (Kano from rest needs (S + J)/2 = 10 here).
    assert probe.set_params(client, S=20.0, J=0.0)[0].successful
    n_before = len(probe.values(f'{ns}/mv'))
    drive([58.5 - 0.25 * i for i in range(35)] + [50.0] * 10)
    assert max(abs(v - held) for v in probe.values(f'{ns}/mv')[n_before:]) < 1e-9
    assert probe.set_params(client, S=5.0, J=2.0)[0].successful
    drive([50.0] * 10)
    assert probe.values(f'{ns}/mv')[-1] < held - 3.0


def test_shipped_parameter_file_loads_with_params_file(probe, tmp_path):
    params = config_file('params/concentration_undershoot/valve.params.yaml')
    proc = start_node('valve', log_dir=str(tmp_path), extra=['--params-file', str(params)])
    try:
        client = probe.params('/valve')
        assert probe.get_params(client, 'model', 'S', 'J', 'sample_time', 'phase') == [
            'choudhury', 5.0, 2.0, 1.0, 0.75]
    finally:
        assert stop(proc) == 0
