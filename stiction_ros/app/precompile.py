"""
Compile every kernel a node, the loop launcher and the analyzer use, into numba's cache.

Then build the analyzer's default kernels ahead of time into an extension
module, so that an analysis starts without loading numba (0.7 s).

Run once after installing (tools/bootstrap.sh and ``colcon build`` do it, see
setup.py), so that the first start of a node loads its kernels from the cache
(about 1 s) instead of compiling them (5-10 s).  Each kernel is reached
through the same public call, with the same argument types, that a run makes:
numba compiles one version per type signature, and a warm-up with other
types would leave the run's version still to compile.
"""

from concurrent.futures import ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
import importlib
import multiprocessing
import os
import pkgutil
import sys
import tempfile
import time
from typing import Callable

from stiction_ros import kernels
from stiction_ros._jit import build_ahead_of_time, JIT_ONLY
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


def _corpus() -> None:
    # Imported here: an install without the corpus stage never loads the corpus code.
    from stiction_ros.sim.corpus import draw_scenario, simulate
    for seed in (0, 1):
        simulate(draw_scenario(seed))


STAGES: dict[str, Callable[[], None]] = {
    'nodes': _nodes, 'loop': _loop, 'analyzer': _analyzer}
# A development venv's (tools/bootstrap.sh): the simulated corpus that the detector's
# training, the studies and many tests draw.  Compiled in the tests instead, it took
# each of two workers about 20 s at once.
DEVELOPMENT_STAGES: dict[str, Callable[[], None]] = {'corpus': _corpus}


def build_kernels(say: Say = print) -> bool:
    """
    Build the analyzer's kernels ahead of time (see :mod:`stiction_ros._jit`); return success.

    A failed build (no C compiler, a read-only install) costs only speed: the
    kernels then compile just in time, so it is reported, not raised.
    """
    if os.environ.get(JIT_ONLY):
        say(f'precompile: {JIT_ONLY} is set: no kernels built ahead of time')
        return False
    t = time.perf_counter()
    for info in pkgutil.iter_modules(kernels.__path__):
        importlib.import_module(f'{kernels.__name__}.{info.name}')
    try:
        names = build_ahead_of_time()
    except Exception as exc:  # noqa: B902 - any failure of the C build leaves the JIT path
        say(f'precompile: kernels not built ahead of time ({type(exc).__name__}: {exc}); '
            'they compile on first use instead')
        return False
    say(f'precompile: {len(names)} analyzer kernels built ahead of time in '
        f'{time.perf_counter() - t:.1f} s')
    return True


def _say_on_stderr(text: str) -> None:
    print(text, file=sys.stderr, flush=True)


def _build_alone() -> bool:
    return build_kernels(_say_on_stderr)


def precompile(say: Say = print, development: bool = False) -> float:
    """
    Compile (or load) every kernel of :data:`STAGES`, and build the analyzer's; return seconds.

    The ahead-of-time build is a C compile of its own, in a second process
    beside the stages (36 s in one process, in 2026-12 on 2 cores, most of
    the set-up after pip): it writes its manifest only once its module is
    whole, so a stage that looks for it meanwhile runs just in time.
    """
    t0 = time.perf_counter()
    # spawn, not fork: numba's compiler is not known to survive a fork.
    with ProcessPoolExecutor(1, mp_context=multiprocessing.get_context('spawn')) as pool:
        built = pool.submit(_build_alone)
        stages = {**STAGES, **DEVELOPMENT_STAGES} if development else STAGES
        for name, stage in stages.items():
            t = time.perf_counter()
            stage()
            say(f'precompile: {name} kernels ready in {time.perf_counter() - t:.1f} s')
        try:
            built.result()
        except (BrokenProcessPool, OSError) as exc:
            # As a failed build: the analyzer's kernels then compile on first use.
            say(f'precompile: the process building kernels ahead of time ended '
                f'({type(exc).__name__}: {exc}); they compile on first use instead')
    return time.perf_counter() - t0
