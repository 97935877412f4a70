"""The parameters every loop node has: timing, input checks, fault injection, state."""

from stiction_ros.nodes.params import Param
from stiction_ros.sim.ros_params import INPUT_LIMIT


def common_params(phase: float) -> list:
    """Return the :class:`Param` specs shared by the loop nodes, acting at ``phase``."""
    return [
        Param('sample_time', 1.0, 'Sample time of the loop, s. Fixed for the run.',
              1e-4, 1e4, fixed=True),
        Param('phase', float(phase),
              'When in each sample this node acts, as a fraction of sample_time '
              '(plant 0.25, controller 0.5, valve 0.75). Fixed for the run.',
              0.0, 0.75, fixed=True, step=0.25),
        Param('realtime_priority', 0,
              'On wall time, run this process under SCHED_FIFO at this priority (Linux, '
              'needs CAP_SYS_NICE; without it the node warns and keeps the normal '
              'scheduler). 0: the normal scheduler. Fixed for the run.',
              0, 98, fixed=True),
        Param('start_time', 0.0, 'On wall time, the Unix time (s) the profiles (set point, '
              'loads) count from; the loop launcher gives every node the same. 0: the first '
              'sample this node acts on. Sim time counts from 0. Fixed for the run.',
              0.0, 1e11, fixed=True),
        Param('input_limit', INPUT_LIMIT, 'Input values beyond +-this (or not finite) are '
              'rejected and the last good value held.', 1.0, 1e300),
        Param('stale_after', 5.0, 'Seconds without a valid input before /diagnostics '
              'reports it stale (ERROR).', 1e-3, 1e6),
        Param('inject_drop', 0.0, 'Fault injection: probability that an input message is '
              'lost on its way in.', 0.0, 1.0),
        Param('inject_delay', 0.0, 'Fault injection: delay of every input message, s.',
              0.0, 60.0),
        Param('inject_jitter', 0.0, 'Fault injection: random extra delay of an input '
              'message, uniform up to this, s (messages stay in order).', 0.0, 60.0),
        Param('inject_seed', 0, 'Seed of the injected faults. Fixed for the run.', 0,
              2**31 - 1, fixed=True),
        Param('input_wait', 0.5, 'On sim time: wall seconds to wait at the action instant '
              'for an input of this sample that has not come yet (0: act on what is '
              "there). Keep it under the sim clock's sync_timeout. Fixed for the run.",
              0.0, 60.0, fixed=True),
        Param('state_file', '', 'File the node writes its state to after every sample and '
              'resumes from when restarted ("": none). Fixed for the run.', fixed=True,
              constraint='a writable file path, or empty'),
    ]
