"""
Closed-loop records with random set-point and load steps, for testing detectors.

A detector that only ever sees a limit cycle has not been tested: plant data
are mostly steady loops hit by set-point changes and load disturbances.  The
plant is the chapter's Table 2.1 process unless overridden.
"""

import numpy as np

from stiction_ros.resources import config_file
from stiction_ros.sim.closed_loop import simulate_loop
from stiction_ros.sim.loop_config import load_loop


def disturbed_loop(valve, seed, Kc=0.3, Ti=20.0, pv_std=0.02, duration=4000.0,
                   set_point_steps=3, load_steps=4, overrides=None):
    """
    Simulate one record; return the dict of :func:`simulate_loop`.

    Set-point steps are uniform in [-1, 1] and load steps (added to PV) in
    [-0.8, 0.8], at uniform random times away from both ends.
    """
    rng = np.random.default_rng(seed)
    end = duration - 200.0
    steps = [[0.0, 0.0]] + [[float(t), float(rng.uniform(-1, 1))]
                            for t in sorted(rng.uniform(200.0, end, set_point_steps))]
    loads = [(float(t), float(rng.uniform(-0.8, 0.8)))
             for t in sorted(rng.uniform(200.0, end, load_steps))]
    cfg = load_loop(config_file('concentration_loop.yaml'), overrides={
        'valve': valve, 'controller.Kc': Kc, 'controller.Ti': Ti,
        'controller.setpoint': {'type': 'steps', 'steps': steps},
        'plant.disturbance_steps': loads, 'noise': {'pv_std': pv_std, 'seed': seed},
        **(overrides or {})})
    return simulate_loop(cfg, duration)
