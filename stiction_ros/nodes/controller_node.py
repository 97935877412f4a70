"""
``controller`` node: PI(D) on ``pv`` toward the set point, or an open-loop OP source.

Publishes ``op`` and ``sp`` once per sample.  The set point is a constant
(``setpoint``) or a profile (``setpoint_profile``, YAML such as
``{type: steps, steps: [[0, 0], [10, 1]]}``); whichever was set last is in
force, as when an operator types a set point over a running program.  In
``open_loop`` mode OP comes from ``op`` or ``op_profile`` the same way.
Switching back to ``closed_loop`` is bumpless: the PI starts from the OP it
was putting out.

Example::

    ros2 run stiction_ros controller --ros-args -p Kc:=0.2 -p Ti:=10.0
    ros2 param set /controller setpoint 2.0
"""

import sys

from std_msgs.msg import Float64
from stiction_ros.nodes.params import Param
from stiction_ros.nodes.run import run
from stiction_ros.nodes.sampled import DATA_QOS, SampledNode
from stiction_ros.sim.controller import PID
from stiction_ros.sim.sources import Constant, make_source, SourceError, SOURCES
import yaml

PROFILE_RULE = ('empty, a number, or a YAML mapping with type: one of ' + ', '.join(SOURCES)
                + " and that type's keys; anything else is rejected with the reason")
GAINS = ('Kc', 'Ti', 'Td', 'N', 'op_min', 'op_max', 'action')


def parse_source(text, value, where):
    """Return the source described by YAML ``text``, or a constant ``value`` if empty."""
    if not text.strip():
        return Constant(value)
    try:
        spec = yaml.safe_load(text)
    except yaml.YAMLError as err:
        raise SourceError(f'{where}: not valid YAML: {err}') from None
    return make_source(spec, where)


class ControllerNode(SampledNode):
    """The controller: one PI(D) update per sample on the latest PV."""

    KIND = 'controller'

    def __init__(self):
        super().__init__('controller', 0.5, [
            Param('mode', 'closed_loop', 'closed_loop: PI(D) on pv; open_loop: OP from '
                  'op / op_profile. Switching to closed_loop is bumpless.',
                  choices=('closed_loop', 'open_loop')),
            Param('Kc', 1.0, 'Controller gain (OP % per PV unit).', -1e6, 1e6),
            Param('Ti', 0.0, 'Integral time, s (0: no integral action).', 0.0, 1e9),
            Param('Td', 0.0, 'Derivative time, s (on PV, filtered).', 0.0, 1e9),
            Param('N', 10.0, 'Derivative filter: Td/N is the filter time constant.', 1.0, 1000.0),
            Param('op_min', 0.0, 'Lowest OP, %.', -1e6, 1e6),
            Param('op_max', 100.0, 'Highest OP, %.', -1e6, 1e6),
            Param('bias', 50.0, 'OP when the error and the integral are zero, %. '
                  'Fixed for the run (changing it would bump OP).', -1e6, 1e6, read_only=True),
            Param('action', 'reverse', 'reverse: OP rises when PV is below SP; direct: falls.',
                  choices=('reverse', 'direct')),
            Param('setpoint', 0.0, 'Constant set point; setting it overrides a profile.',
                  -1e12, 1e12),
            Param('setpoint_profile', '', 'Set-point profile as YAML, e.g. '
                  '{type: steps, steps: [[0, 0], [10, 1]]}; empty: use setpoint.',
                  constraint=PROFILE_RULE),
            Param('op', 50.0, 'Open-loop OP, %; setting it overrides op_profile.', -1e6, 1e6),
            Param('op_profile', '', 'Open-loop OP profile as YAML, e.g. '
                  '{type: sine, offset: 50, amplitude: 10, period: 200}; empty: use op.',
                  constraint=PROFILE_RULE),
        ])
        v = self.values
        self.check_startup()
        self.pid = PID(sample_time=self.sample_time, bias=v['bias'],
                       **{k: v[k] for k in GAINS})
        self.sp_source = parse_source(v['setpoint_profile'], v['setpoint'], 'setpoint_profile')
        self.op_source = parse_source(v['op_profile'], v['op'], 'op_profile')
        self.pv = None
        self.op_pub = self.create_publisher(Float64, 'op', DATA_QOS)
        self.sp_pub = self.create_publisher(Float64, 'sp', DATA_QOS)
        # An open-loop controller needs no PV: it is not reported until it is used.
        self.add_input('pv', watch=v['mode'] == 'closed_loop')
        self.start()
        self.get_logger().info(f'{v["mode"]} Kc={v["Kc"]} Ti={v["Ti"]} at {self.sample_time} s')

    def check(self, values, changes):
        """Return why the gains or profiles would be invalid, or None."""
        try:
            PID(sample_time=self.sample_time, bias=values['bias'],
                **{k: values[k] for k in GAINS})
            for key, const in (('setpoint_profile', 'setpoint'), ('op_profile', 'op')):
                if key in changes:
                    parse_source(values[key], values[const], key)
        except (ValueError, SourceError) as err:
            return str(err)
        return None

    def apply(self, changes):
        """Retune, switch mode bumplessly, or replace the set point / OP source."""
        v = self.values
        gains = {k: v[k] for k in GAINS if k in changes}
        if gains:
            self.pid.set_gains(**gains)
        if 'setpoint' in changes:
            self.sp_source = Constant(v['setpoint'])
        if 'setpoint_profile' in changes:
            self.sp_source = parse_source(v['setpoint_profile'], v['setpoint'], 'setpoint_profile')
        if 'op' in changes:
            self.op_source = Constant(v['op'])
        if 'op_profile' in changes:
            self.op_source = parse_source(v['op_profile'], v['op'], 'op_profile')
        if changes.get('mode') == 'closed_loop':
            self.pid.reset(op=self.pid.op, pv=self.pv)

    def snapshot_state(self):
        """Return the PI(D) memory and the last PV."""
        return {'pid': self.pid.snapshot(), 'pv': self.pv}

    def restore_state(self, state):
        """Resume the saved controller, so that OP continues without a bump."""
        self.pid.restore(state['pid'])
        self.pv = None if state.get('pv') is None else float(state['pv'])

    def on_input(self, topic, value):
        """Use the newest valid PV."""
        self.pv = value

    def on_sample(self, k, t):
        """Compute OP for sample ``k`` from the latest PV and publish OP and SP."""
        sp = self.sp_source(t)
        if self.values['mode'] == 'open_loop':
            op = self.op_source(t)
            self.pid.op = op
        elif self.pv is None or not self._guard('pv').fresh:
            # No new PV since the last sample (lost, late, or the plant is down):
            # hold OP rather than integrate an old error.
            op = self.pid.op
        else:
            op = self.pid.update(sp, self.pv)
        self.sp_pub.publish(Float64(data=float(sp)))
        self.op_pub.publish(Float64(data=float(op)))


def main(args=None):
    """Run the controller node."""
    return run(ControllerNode, args, 'controller')


if __name__ == '__main__':
    sys.exit(main())
