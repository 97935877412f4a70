"""
A valve node driven by hand, as a ROS user would: ``/op`` published from outside.

Start-up convention (models/base.py ``reset``): the valve rests at
``initial_position`` under the input that holds it there, so a constant OP
that differs from it by more than the band moves it, from any start.
"""

import pytest
from ros_helpers import start_node, stop, wait_for

pytestmark = pytest.mark.ros


@pytest.mark.parametrize('model', ['kano', 'choudhury'])
def test_a_standalone_valve_moves_to_a_constant_op_beyond_its_band(probe, tmp_path, model):
    ns = f'/by_hand_{model}'
    probe.listen(f'{ns}/mv')
    valve = start_node('valve', {'sample_time': 0.05, 'model': model, 'S': 5.0, 'J': 2.0,
                                 'initial_position': 50.0}, ns, str(tmp_path))
    try:
        wait_for(lambda: len(probe.values(f'{ns}/mv')) > 3, what='valve output')
        assert set(probe.values(f'{ns}/mv')) == {50.0}
        # Sent until heard: a message sent before the node matched our publisher is lost.
        wait_for(lambda: probe.publish(f'{ns}/op', 70.0) or probe.values(f'{ns}/mv')[-1] > 60.0,
                 what='the valve moving to OP 70')
        n = len(probe.values(f'{ns}/mv'))
        wait_for(lambda: len(probe.values(f'{ns}/mv')) > n + 5, what='more samples')
        # Moved past the band and came to rest within the kinetic band of the OP.
        assert abs(probe.values(f'{ns}/mv')[-1] - 70.0) <= 5.0
    finally:
        assert stop(valve) == 0
