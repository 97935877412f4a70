"""
``valve`` node: subscribes ``op``, publishes ``mv`` through the selected stiction model.

Every model's parameters are declared on the node (``S`` and ``J`` are shared
by the data-driven models; the physical model's are SI).  A change is
validated by building the model it would give, so an impossible combination
is rejected with the model's own reason and nothing changes.  Switching
``model`` is bumpless: the new model starts at rest at the current position.

Example::

    ros2 run stiction_ros valve --ros-args -p model:=kano -p S:=5.0 -p J:=2.0
    ros2 param set /valve S 7.0
"""

import sys

from std_msgs.msg import Float64
from stiction_ros.models import create, ModelError, MODELS
from stiction_ros.models.compiled import warm_up
from stiction_ros.nodes.params import Param
from stiction_ros.nodes.run import run
from stiction_ros.nodes.sampled import DATA_QOS, SampledNode


def model_params():
    """Return one :class:`Param` per model parameter name, over all models."""
    users = {}
    for model, cls in MODELS.items():
        for name in cls.PARAMS:
            if name != 'sample_time':
                users.setdefault(name, []).append(model)
    out = []
    for name, models in users.items():
        default, low, high, desc = MODELS[models[0]].PARAMS[name]
        text = f'{desc} ({", ".join(models)})'
        if isinstance(low, str):
            choices = tuple(high) if not isinstance(default, bool) else None
            out.append(Param(name, default, text, choices=choices))
        else:
            out.append(Param(name, float(default), text, low, high))
    return out


class ValveNode(SampledNode):
    """The valve: one model step per sample on the latest OP."""

    KIND = 'valve'
    PHASE = 0.75

    @staticmethod
    def own_params() -> list:
        """Return the valve's own parameters: the model and every model's parameters."""
        return [
            Param('model', 'choudhury', 'Stiction model; switching is bumpless.',
                  choices=tuple(MODELS)),
            Param('initial_position', 50.0,
                  'Position the valve rests at before its first OP, % of travel. '
                  'Fixed for the run: used at start-up only.', 0.0, 100.0, fixed=True),
        ] + model_params()

    def __init__(self):
        super().__init__('valve', self.PHASE, self.own_params())
        self.check_startup()
        warm_up()
        self.model = self._build(self.values['model'], self.values)
        self.model.reset(y0=self.values['initial_position'])
        self.op = None
        self.pub = self.create_publisher(Float64, 'mv', DATA_QOS)
        self.add_input('op')
        self.start()
        self.get_logger().info(f'{self.model!r} at {self.sample_time} s')

    def _kwargs(self, name, values):
        cls = MODELS[name]
        kwargs = {k: values[k] for k in cls.PARAMS if k in values}
        if 'sample_time' in cls.PARAMS:
            kwargs['sample_time'] = self.sample_time
        return kwargs

    def _build(self, name, values):
        return create(name, **self._kwargs(name, values))

    def check(self, values, changes):
        """Check every model the change touches, as its build would; return the first error."""
        touched = {values['model']} if 'model' in changes else set()
        touched |= {m for m, cls in MODELS.items() if set(changes) & set(cls.PARAMS)}
        for name in sorted(touched):
            try:
                MODELS[name].checked(**self._kwargs(name, values))
            except ModelError as err:
                return str(err)
        return None

    def apply(self, changes):
        """Rebuild on a model switch (starting where the valve is), else set parameters."""
        name = self.values['model']
        if 'model' in changes and name != self.model.name:
            position = self.model.position
            self.model = self._build(name, self.values)
            # At rest under the OP in force: a switch alone must not move the valve.
            self.model.reset(y0=position if position is not None
                             else self.values['initial_position'], u_rest=self.op)
            return
        mine = {k: v for k, v in changes.items() if k in self.model.PARAMS}
        if mine:
            self.model.set_params(**mine)

    def snapshot_state(self):
        """Return the model's state (position, stuck or moving, direction) and the last OP."""
        return {'model': self.model.snapshot(), 'op': self.op}

    def restore_state(self, state):
        """Resume the saved valve; another model resumes at the saved position, at rest."""
        snap = state['model']
        if snap.get('model') == self.model.name:
            self.model.restore(snap)
        elif snap.get('state'):
            self.get_logger().warning(f'the saved valve ran {snap.get("model")!r}; '
                                      f'{self.model.name} starts at its position, at rest')
        op = state.get('op')
        self.op = None if op is None else float(op)
        if snap.get('model') != self.model.name and snap.get('state'):
            self.model.reset(y0=min(max(float(snap['state'][0]), 0.0), 100.0), u_rest=self.op)

    def on_input(self, topic, value):
        """Use the newest valid OP."""
        self.op = value

    def on_sample(self, k, t):
        """Move the valve on the latest OP (or hold it before the first) and publish MV."""
        if self.op is None:
            position = self.model.position
            mv = position if position is not None else self.values['initial_position']
        else:
            mv = self.model.step(self.op)
        self.pub.publish(Float64(data=mv))


def main(args=None):
    """Run the valve node."""
    return run(ValveNode, args, 'valve')


if __name__ == '__main__':
    sys.exit(main())
