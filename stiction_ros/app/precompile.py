"""
Compile every kernel a node, the loop launcher and the analyzer use, into numba's cache.

Run once after installing (tools/bootstrap.sh and ``colcon build`` do it, see
setup.py), so that the first start of a node loads its kernels from the cache
(about 1 s) instead of compiling them (5-10 s).  Each kernel is reached
through the same public call, with the same argument types, that a run makes:
numba compiles one version per type signature, and a warm-up with other
types would leave the run's version still to compile.
"""

import os
import tempfile
import time
from typing import Callable

from stiction_ros.models import create
from stiction_ros.models.compiled import warm_up
from stiction_ros.resources import config_file
from stiction_ros.sim.closed_loop import simulate_loop, write_csv
from stiction_ros.sim.loop_config import load_loop
from stiction_ros.sim.plant import TransferFunctionPlant

Say = Callable[[str], None]


def _nodes() -> None:
    warm_up()
    create('kano_effects', S=2.0, J=1.0, effect='dwell_time_breakaway',
           dwell_gain=0.5).simulate([50.0, 52.0])
    plant = TransferFunctionPlant([3.0], [10.0, 1.0], delay=10.0, sample_time=1.0, mv0=50.0)
    for _ in range(3):
        plant.update(51.0)
        plant.output()


def _loop() -> None:
    # The launcher's offline twin: one closed-loop run per valve kind the configs use.
    for name, case in (('concentration_loop.yaml', 'undershoot'),
                       ('hidden_effect_loop.yaml', None)):
        simulate_loop(load_loop(config_file(name), case), duration=50.0)


def _analyzer() -> None:
    from stiction_ros.app.analyze import analyze_file, AnalyzeOptions
    data = simulate_loop(load_loop(config_file('concentration_loop.yaml'), 'undershoot'),
                         duration=600.0)
    with tempfile.TemporaryDirectory(prefix='stiction_precompile_') as tmp:
        path = os.path.join(tmp, 'loop.csv')
        write_csv(path, data)
        analyze_file(AnalyzeOptions(input=path, jobs=1))


STAGES: dict[str, Callable[[], None]] = {
    'nodes': _nodes, 'loop': _loop, 'analyzer': _analyzer}


def precompile(say: Say = print) -> float:
    """Compile (or load) every kernel of :data:`STAGES`; return the seconds it took."""
    t0 = time.perf_counter()
    for name, stage in STAGES.items():
        t = time.perf_counter()
        stage()
        say(f'precompile: {name} kernels ready in {time.perf_counter() - t:.1f} s')
    return time.perf_counter() - t0
