"""Compile every valve kernel before a node's first sample (``warm_up``)."""

import numpy as np

from stiction_ros.kernels.valves import choudhury_run, he_run, kano_run, stenman_run
from stiction_ros.models.physical import Physical


def warm_up() -> None:
    """
    Compile (or load from numba's cache) every kernel now.

    A node calls this before its first sample: compiling in the middle of a run
    (on the first sample, or on a live switch to another model) would stall
    that sample by a second or more.
    """
    u, y = np.array([50.0, 51.0]), np.empty(2)
    kano_run(u, y, np.array([50.0, 50.0, 50.0, 50.0, 1.0, 0.0, 50.0]), 1.0, 0.5, 0.0)
    choudhury_run(u, y, np.array([50.0, 50.0, 50.0, 0.0, 50.0, 1.0, 0.0, 50.0]), 1.0, 0.5, 1.0,
                  False, 0, 50.0, False)
    he_run(u, y, np.array([50.0, 50.0, 0.0]), 1.0, 0.5)
    stenman_run(u, y, np.array([50.0]), 1.0)
    # The physical valve's two integrators.
    Physical(sample_time=0.01).simulate(u)
    Physical(sample_time=0.01, integrator='substep', substep=1e-3).simulate(u)
