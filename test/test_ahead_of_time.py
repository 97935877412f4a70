"""
Kernels built ahead of time give what numba's just-in-time ones give, and only when they fit.

stiction_ros._jit runs a kernel from the ahead-of-time module while numba is
not loaded and the arguments match its signature.  Each test runs in a fresh
process (this one has numba loaded long since).  The built module is made by
``stiction-precompile`` (tools/bootstrap.sh runs it); here it is required.
"""

import json
import os
from pathlib import Path
import subprocess
import sys

import numpy as np
import pytest

from stiction_ros import _jit

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope='module', autouse=True)
def built():
    status = _jit.ahead_of_time_status()
    assert status == 'fresh', f'ahead-of-time kernels {status}'


def python(code, jit_only=False):
    env = {k: v for k, v in os.environ.items() if k != _jit.JIT_ONLY}
    if jit_only:
        env[_jit.JIT_ONLY] = '1'
    run = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                         env=env, timeout=300, cwd=ROOT)
    assert run.returncode == 0, run.stderr[-2000:]
    return json.loads(run.stdout.strip().splitlines()[-1])


ANALYSE = """
import json, sys
from stiction_ros.app.analyze import analyze_file, AnalyzeOptions

def timeless(x):
    # Wall times differ from run to run; everything else must not.
    if isinstance(x, dict):
        return dict((k, timeless(v)) for k, v in x.items()
                    if 'seconds' not in k and 'elapsed' not in k)
    return [timeless(v) for v in x] if isinstance(x, list) else x


out = dict()
for name, path in {paths!r}.items():
    out[name] = timeless(analyze_file(AnalyzeOptions(input=path, jobs=1)).report)
loaded = sorted({{m.split('.')[0] for m in sys.modules}} & {{'numba', 'scipy'}})
print(json.dumps([loaded, json.dumps(out, sort_keys=True, default=str)]))
"""


def test_an_analysis_gives_the_same_report_to_the_bit_either_way(tmp_path):
    # With MV: the (S, J) search of both models; without: the Hammerstein fit.
    t = np.arange(3000.0)
    op = 50 + 6 * np.sin(2 * np.pi * t / 150) + np.random.default_rng(3).normal(0, 0.3, t.size)
    mv = np.empty_like(op)
    pos = op[0]
    for k, u in enumerate(op):
        if abs(u - pos) > 2.5:
            pos = u - np.sign(u - pos) * 0.8
        mv[k] = pos
    # Measured, so noisy: a noise-free moving average of a stuck valve draws
    # straight lines, which the detector refuses as a historian's.
    pv = (np.convolve(mv - 50, np.full(20, 0.05))[:t.size]
          + np.random.default_rng(4).normal(0, 0.05, t.size))
    with_mv, no_mv = tmp_path / 'mv.csv', tmp_path / 'no_mv.csv'
    np.savetxt(with_mv, np.column_stack([t, op, mv, pv]), delimiter=',', header='t,op,mv,pv',
               comments='')
    np.savetxt(no_mv, np.column_stack([t, op, pv]), delimiter=',', header='t,op,pv',
               comments='')
    code = ANALYSE.format(paths={'mv': str(with_mv), 'no_mv': str(no_mv)})
    built_loaded, built_reports = python(code)
    jit_loaded, jit_reports = python(code, jit_only=True)
    assert 'numba' not in built_loaded and 'numba' in jit_loaded
    assert built_reports == jit_reports
    # The reports hold the fits: the search did run.
    assert '"S"' in built_reports and 'hammerstein' in built_reports


GUARD = """
import json, sys
import numpy as np
from stiction_ros.kernels.valves import kano_run
u = np.linspace(40.0, 60.0, 200)
results = []
for dtype in (np.float64, np.float32):
    y, st = np.zeros(200), np.zeros(8)
    st[0], st[4] = 40.0, 1.0
    kano_run(u.astype(dtype), y, st, 3.0, 1.0, 0.0)
    results.append([y.tolist(), 'numba' in sys.modules])
print(json.dumps(results))
"""


def test_arguments_outside_the_signature_go_to_numba_not_to_the_built_code():
    # float32 read as float64 would be garbage (or a crash) in the built code.
    (y64, numba_after_64), (y32, numba_after_32) = python(GUARD)
    assert not numba_after_64 and numba_after_32
    assert np.max(np.abs(np.array(y64) - np.array(y32))) < 1e-4
    assert y64[-1] > 55.0


def test_a_changed_kernel_source_makes_the_built_module_stale(tmp_path, monkeypatch):
    kernels = tmp_path / 'kernels'
    kernels.mkdir()
    for f in Path(_jit.KERNEL_DIR).glob('*.py'):
        (kernels / f.name).write_bytes(f.read_bytes())
    monkeypatch.setattr(_jit, 'KERNEL_DIR', str(kernels))
    assert _jit.ahead_of_time_status() == 'fresh'
    with open(kernels / 'sse.py', 'a') as f:
        f.write('\n# edited\n')
    assert _jit.ahead_of_time_status().startswith('stale')
    monkeypatch.setenv(_jit.JIT_ONLY, '1')
    assert _jit.ahead_of_time_status().endswith('is set')


def test_signatures_are_read_argument_by_argument():
    assert _jit.arguments('f8[:, ::1](i8, f8[::1], f8[:, ::1], b1)') == [
        'i8', 'f8[::1]', 'f8[:, ::1]', 'b1']
    assert _jit.arguments('Tuple((f8[:, ::1], i8[:, ::1]))(f8[::1], i8)') == ['f8[::1]', 'i8']
    assert _jit.arguments('void()') == []


def test_kernel_modules_imported_after_numba_are_built_too():
    # stiction-precompile loads numba in its first stages and imports some kernel
    # modules only afterwards: their aot kernels must still be in the build.
    code = ('import json\n'
            'from stiction_ros import _jit\n'
            'from stiction_ros.kernels import valves\n'
            '_jit.load_numba()\n'
            'from stiction_ros.kernels import hammerstein\n'
            'print(json.dumps(sorted(_jit.export_name(f) for f, _ in '
            '_jit.ahead_of_time_functions())))\n')
    names = python(code)
    assert 'hammerstein___grid_sse' in names and 'valves__kano_run' in names
    with open(_jit.AOT_MANIFEST, encoding='utf-8') as f:
        built = json.load(f)['kernels']
    assert 'hammerstein___grid_sse' in built and 'hammerstein__segment_path' in built
