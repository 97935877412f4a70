"""
``plant`` node: subscribes ``mv``, publishes ``pv`` through a transfer function with dead time.

The process ``num(s)/den(s) e^{-delay s}`` is discretised exactly (zero-order
hold) at the loop's sample time.  Each sample the plant first advances over
the MV it held during the last sample, then publishes PV: the same order as
the offline simulator.  Structure (``num``, ``den``, ``delay``, operating
point) is fixed for a run; ``load`` and ``noise_std`` can change live.
"""

import sys

from std_msgs.msg import Float64
from stiction_ros.errors import SourceError
from stiction_ros.nodes.params import Param
from stiction_ros.nodes.run import run
from stiction_ros.nodes.sampled import DATA_QOS, SampledNode, StartupError
from stiction_ros.sim.plant import PlantError, TransferFunctionPlant
from stiction_ros.sim.profile_params import pairs

# Samples the plant catches up at once after the clock skipped ahead.
MAX_CATCH_UP = 10000


class PlantNode(SampledNode):
    """The process: one exact ZOH step per sample on the latest MV."""

    KIND = 'plant'
    PHASE = 0.25

    @staticmethod
    def own_params() -> list:
        """Return the plant's own parameters."""
        fixed = ' Fixed for the run (the plant state depends on it).'
        return [
            Param('num', [3.0], 'Numerator coefficients of the transfer function, '
                  'highest power of s first.' + fixed, fixed=True,
                  constraint='a non-empty list of finite numbers'),
            Param('den', [10.0, 1.0], 'Denominator coefficients, highest power of s first.'
                  + fixed, fixed=True,
                  constraint='a list of finite numbers, at least as long as num'),
            Param('delay', 10.0, 'Dead time, s.' + fixed, 0.0, 1e6, fixed=True),
            Param('mv0', 50.0, 'MV at the operating point, % of valve travel.' + fixed,
                  0.0, 100.0, fixed=True),
            Param('pv0', 0.0, 'PV at the operating point.' + fixed, -1e12, 1e12, fixed=True),
            Param('disturbance_steps', [], 'Load steps added to PV from their time on, as '
                  '[time_s, size] pairs in one flat list; []: none.' + fixed, fixed=True,
                  constraint='one flat list of [time, size] pairs: [t0, s0, t1, s1, ...], '
                  'e.g. [300.0, 2.0, 900.0, -1.0]; [] for none'),
            Param('seed', 0, 'Seed of the measurement noise.' + fixed, 0, 2**31 - 1,
                  fixed=True),
            Param('noise_std', 0.0, 'Standard deviation of the PV measurement noise.',
                  0.0, 1e6),
            Param('load', 0.0, 'Constant load added to PV, from the next sample on.',
                  -1e12, 1e12),
        ]

    def __init__(self):
        super().__init__('plant', self.PHASE, self.own_params())
        v = self.values
        try:
            steps = pairs(v['disturbance_steps'], 'disturbance_steps')
            self.plant = TransferFunctionPlant(
                list(v['num']), list(v['den']), delay=v['delay'], sample_time=self.sample_time,
                mv0=v['mv0'], pv0=v['pv0'], noise_std=v['noise_std'], disturbance_steps=steps,
                seed=v['seed'])
        except (PlantError, SourceError, ValueError, TypeError) as err:
            raise StartupError(f'plant: {err}') from None
        self.mv = None
        self._k = None
        self.pub = self.create_publisher(Float64, 'pv', DATA_QOS)
        self.add_input('mv', lag=1)   # the valve publishes MV late in the previous sample
        self.start()
        self.get_logger().info(
            f'{list(v["num"])}/{list(v["den"])} e^-{v["delay"]}s at {self.sample_time} s')

    def apply(self, changes):
        """Take a new noise level; ``load`` is read each sample."""
        if 'noise_std' in changes:
            self.plant.noise_std = changes['noise_std']

    def snapshot_state(self):
        """Return the process state, the MV it holds and the sample it is at."""
        return {'plant': self.plant.snapshot(), 'mv': self.mv, 'k': self._k}

    def restore_state(self, state):
        """Resume the saved process; it catches up over the samples it was down, on the held MV."""
        self.plant.restore(state['plant'])
        self.mv = None if state.get('mv') is None else float(state['mv'])
        self._k = None if state.get('k') is None else int(state['k'])

    def on_input(self, topic, value):
        """Use the newest valid MV."""
        self.mv = value

    def on_sample(self, k, t):
        """Advance over the held MV, then publish PV for sample ``k``."""
        if self._k is not None:
            held = self.mv if self.mv is not None else self.plant.mv0
            for _ in range(min(max(k - self._k, 0), MAX_CATCH_UP)):
                self.plant.update(held)
        self._k = k
        self.plant.time = t
        pv = self.plant.output() + self.values['load']
        self.pub.publish(Float64(data=pv))


def main(args=None):
    """Run the plant node."""
    return run(PlantNode, args, 'plant')


if __name__ == '__main__':
    sys.exit(main())
