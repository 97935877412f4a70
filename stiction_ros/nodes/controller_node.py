"""
``controller`` node: PI(D) on ``pv`` toward the set point, or an open-loop OP source.

Publishes ``op`` and ``sp`` once per sample.  The set point is a constant
(``setpoint``) or a profile: one typed parameter per key of its source
(:mod:`stiction_ros.sim.profile_params`), ``setpoint_profile.type`` (``steps``,
``sine``, ...; ``''``: none) and its keys, such as ``setpoint_profile.steps``
(one flat list ``[t0, v0, t1, v1, ...]``).  Whichever was set last is in
force, as when an operator types a set point over a running program: setting
``setpoint`` sets ``setpoint_profile.type`` to ``''`` with it, and setting a
profile parameter puts the profile in force (if it has a type).  A value set
to what it is changes nothing, so loading a file again, or a dump of the
node, leaves the loop as it is.  In ``open_loop`` mode OP comes from ``op``
or ``op_profile.*`` the same way.  Switching back to ``closed_loop`` is
bumpless: the PI starts from the OP it was putting out.

Example::

    ros2 run stiction_ros controller --ros-args -p Kc:=0.2 -p Ti:=10.0
    ros2 param set /controller setpoint 2.0
    ros2 param set /controller setpoint_profile.steps "[0.0, 2.0, 600.0, 3.0]"
    ros2 param set /controller setpoint_profile.type steps
"""

import sys

from rclpy.parameter import Parameter
from std_msgs.msg import Float64
from stiction_ros.nodes.params import Param
from stiction_ros.nodes.run import run
from stiction_ros.nodes.sampled import DATA_QOS, SampledNode
from stiction_ros.sim.controller import PID
from stiction_ros.sim.profile_params import check_keys, key_defaults, KEYS, PAIRS_RULE
from stiction_ros.sim.profile_params import profile_spec, PROFILE_TYPES
from stiction_ros.sim.sources import make_source, SourceError

GAINS = ('Kc', 'Ti', 'Td', 'N', 'op_min', 'op_max', 'action')
# Each constant and the prefix of its profile's parameters.
PROFILES = {'setpoint': 'setpoint_profile', 'op': 'op_profile'}
RULES = {'steps': PAIRS_RULE, 'file': 'a CSV file, or empty',
         'column': 'a column name of file', 'time_column': 'a column name of file'}


def profile_params(prefix, what):
    """Return the :class:`Param` of every key of a profile under ``prefix``, ``type`` last."""
    out = []
    for key, default in key_defaults().items():
        low, high, text = KEYS[key]
        out.append(Param(f'{prefix}.{key}', default, f'{what} profile: {text}.', low, high,
                         constraint=RULES.get(key, '')))
    return out + [Param(f'{prefix}.type', '', f'{what} profile: its source, whose keys are '
                        f'the other {prefix}.* parameters; "": none, the constant is in force.',
                        choices=PROFILE_TYPES)]


def profile_values(values, prefix):
    """Return the values of the profile parameters under ``prefix``, keyed without it."""
    return {k[len(prefix) + 1:]: v for k, v in values.items() if k.startswith(prefix + '.')}


class ControllerNode(SampledNode):
    """The controller: one PI(D) update per sample on the latest PV."""

    KIND = 'controller'
    PHASE = 0.5

    @staticmethod
    def own_params() -> list:
        """Return the controller's own parameters."""
        return [
            Param('mode', 'closed_loop', 'closed_loop: PI(D) on pv; open_loop: OP from '
                  'op / op_profile.*. Switching to closed_loop is bumpless.',
                  choices=('closed_loop', 'open_loop')),
            Param('Kc', 1.0, 'Controller gain (OP % per PV unit).', -1e6, 1e6),
            Param('Ti', 0.0, 'Integral time, s (0: no integral action).', 0.0, 1e9),
            Param('Td', 0.0, 'Derivative time, s (on PV, filtered).', 0.0, 1e9),
            Param('N', 10.0, 'Derivative filter: Td/N is the filter time constant.', 1.0, 1000.0),
            Param('op_min', 0.0, 'Lowest OP, %.', -1e6, 1e6),
            Param('op_max', 100.0, 'Highest OP, %.', -1e6, 1e6),
            Param('bias', 50.0, 'OP when the error and the integral are zero, %. '
                  'Fixed for the run (changing it would bump OP).', -1e6, 1e6, fixed=True),
            Param('action', 'reverse', 'reverse: OP rises when PV is below SP; direct: falls.',
                  choices=('reverse', 'direct')),
            Param('setpoint', 0.0, 'Constant set point. Setting it puts it in force: '
                  'setpoint_profile.type becomes "" with it.', -1e12, 1e12),
            *profile_params('setpoint_profile', 'Set-point'),
            Param('op', 50.0, 'Open-loop OP, %. Setting it puts it in force: op_profile.type '
                  'becomes "" with it.', -1e6, 1e6),
            *profile_params('op_profile', 'Open-loop OP'),
        ]

    def __init__(self):
        super().__init__('controller', self.PHASE, self.own_params())
        v = self.values
        self.check_startup()
        self.pid = PID(sample_time=self.sample_time, bias=v['bias'],
                       **{k: v[k] for k in GAINS})
        # The source of each constant-or-profile, and the mapping it was built from.
        self.in_force = {const: self._spec(const, v) for const in PROFILES}
        self.sp_source = make_source(self.in_force['setpoint'], 'setpoint_profile')
        self.op_source = make_source(self.in_force['op'], 'op_profile')
        self.pv = None
        self.op_pub = self.create_publisher(Float64, 'op', DATA_QOS)
        self.sp_pub = self.create_publisher(Float64, 'sp', DATA_QOS)
        # An open-loop controller needs no PV: it is not reported until it is used.
        self.add_input('pv', watch=v['mode'] == 'closed_loop')
        self.start()
        self.get_logger().info(f'{v["mode"]} Kc={v["Kc"]} Ti={v["Ti"]} at {self.sample_time} s')

    @staticmethod
    def _spec(const, values):
        """Return the source mapping in force for ``const`` (its profile, or the constant)."""
        prefix = PROFILES[const]
        spec = profile_spec(profile_values(values, prefix), prefix)
        return spec if spec is not None else {'type': 'constant', 'value': values[const]}

    def expand(self, params):
        """Set ``setpoint`` (``op``) alone, and its profile's type becomes '': last set wins."""
        names = {p.name for p in params}
        return params + [Parameter(f'{prefix}.type', Parameter.Type.STRING, '')
                         for const, prefix in PROFILES.items()
                         if const in names and f'{prefix}.type' not in names
                         and self.values[f'{prefix}.type']]

    def check(self, values, changes):
        """Return why the gains or profiles would be invalid, or None."""
        try:
            PID(sample_time=self.sample_time, bias=values['bias'],
                **{k: values[k] for k in GAINS})
            for const, prefix in PROFILES.items():
                mine = profile_values(changes, prefix)
                if mine or const in changes:
                    reason = check_keys(profile_values(values, prefix), mine, prefix)
                    if reason is not None:
                        return reason
                    make_source(self._spec(const, values), prefix)
        except (ValueError, SourceError) as err:
            return str(err)
        return None

    def apply(self, changes):
        """Retune, switch mode bumplessly, or put a new set point / OP source in force."""
        v = self.values
        gains = {k: v[k] for k in GAINS if k in changes}
        if gains:
            self.pid.set_gains(**gains)
        for const, prefix in PROFILES.items():
            spec = self._spec(const, v)
            # Only a change: a profile set again as it is keeps running where it is.
            if spec != self.in_force[const]:
                self.in_force[const] = spec
                source = make_source(spec, prefix)
                if const == 'setpoint':
                    self.sp_source = source
                else:
                    self.op_source = source
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
