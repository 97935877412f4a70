"""
Closed-loop records with random set-point and load steps, for testing detectors.

A detector that only ever sees a limit cycle has not been tested: plant data
are mostly steady loops hit by set-point changes and load disturbances.  The
plant is the chapter's Table 2.1 process unless overridden.
"""

import numpy as np

from stiction_ros.closed_loop import simulate_loop
from stiction_ros.loop_config import load_loop
from stiction_ros.paths import config_file


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


VALVES = {'kano S=3 J=1': {'model': 'kano', 'S': 3.0, 'J': 1.0},
          'choudhury S=2 J=1': {'model': 'choudhury', 'S': 2.0, 'J': 1.0},
          'linear': {'model': 'linear'}}
TUNINGS = ((0.2, 60.0), (0.3, 20.0), (0.1, 200.0))
NOISES = (0.02, 0.1)


def detection_rates(detector, seeds=range(100, 115), progress=None):
    """
    Return {valve: {'found': n, 'runs': n, 'by_tuning': {...}}} of ``detector``.

    ``detector(record)`` returns True when it calls stiction.  Every valve of
    ``VALVES`` runs at every tuning of ``TUNINGS`` and noise of ``NOISES``
    for each seed.
    """
    out = {}
    for name, valve in VALVES.items():
        by = {}
        for (Kc, Ti) in TUNINGS:
            for noise in NOISES:
                hits = [bool(detector(disturbed_loop(valve, s, Kc, Ti, noise))) for s in seeds]
                by[f'Kc={Kc} Ti={Ti} noise={noise}'] = sum(hits)
                if progress is not None:
                    progress(f'{name}, Kc={Kc}, Ti={Ti}, noise {noise}: {sum(hits)}/{len(hits)}')
        out[name] = {'found': sum(by.values()), 'runs': len(by) * len(seeds), 'by_tuning': by}
    return out
