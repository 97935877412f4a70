"""The detector's figures do not depend on which BLAS kernels the host would choose."""

import json
import os
import platform
import re
import subprocess
import sys

import pytest

from stiction_ros import _blas

X86_AVX2 = (platform.machine().lower() in ('x86_64', 'amd64')
            and set(_blas.NEEDS) <= _blas._cpu_flags())
AVX512 = 'avx512f' in _blas._cpu_flags()
# Forcing the SkylakeX kernels plays a host whose OpenBLAS would choose them.
SKYLAKE = {_blas.CORETYPE: 'SkylakeX'}

KERNELS = """
import json, stiction_ros, numpy, scipy.linalg
from threadpoolctl import threadpool_info
print(json.dumps({'state': stiction_ros._blas.state(),
                  'openblas': [i.get('architecture') for i in threadpool_info()
                               if i['internal_api'] == 'openblas']}))
"""
KEY = """
import json, stiction_ros
from stiction_ros.analysis.detection.dataset import code_version
print(json.dumps(code_version()))
"""
FIGURES = """
import json, stiction_ros
from stiction_ros.analysis.detection.dataset import featurize_seed
print(json.dumps([[float(v) for v in featurize_seed(s)[1]] for s in (2, 3, 5)]))
"""


def run(code: str, **env: str):
    clean = {k: v for k, v in os.environ.items()
             if k not in (_blas.CORETYPE, _blas.NATIVE, _blas.NUMPY_PIN)}
    res = subprocess.run([sys.executable, '-c', code], env={**clean, **env},
                         capture_output=True, text=True, timeout=300, check=True)
    return json.loads(res.stdout.strip().splitlines()[-1])


@pytest.mark.skipif(not X86_AVX2, reason='the Haswell kernels need an x86-64 with AVX2 and FMA')
def test_every_openblas_runs_the_pinned_kernels_whatever_the_host_would_choose():
    for env in ({}, SKYLAKE):
        out = run(KERNELS, **env)
        # The user's own choice is overridden, and the state says so.
        assert out['state'] == (_blas.KERNEL if not env else f'{_blas.KERNEL} (over '
                                f'{_blas.CORETYPE}=SkylakeX)')
        # NumPy's OpenBLAS and SciPy's, loaded later, both.
        assert out['openblas'] and set(out['openblas']) == {_blas.KERNEL}


@pytest.mark.skipif(not (X86_AVX2 and AVX512), reason='the SkylakeX kernels need AVX-512')
def test_the_figures_are_the_pinned_kernels_figures_on_any_host():
    pinned = run(FIGURES)
    assert run(FIGURES, **SKYLAKE) == pinned
    # Unpinned, the other kernels change the figures: the pin is what holds them.
    native = run(FIGURES, **SKYLAKE, **{_blas.NATIVE: '1'})
    assert native != pinned
    assert run(KERNELS, **SKYLAKE, **{_blas.NATIVE: '1'})['openblas'][0] == 'SkylakeX'


@pytest.mark.skipif(not X86_AVX2, reason='nothing is pinned off x86-64 with AVX2 and FMA')
def test_numpy_loaded_first_is_said_and_keys_the_cache_apart():
    out = run('import numpy\n' + KERNELS)
    assert out['state'].startswith('native')
    assert run(KEY, **{_blas.CORETYPE: 'Haswell'}) != run('import numpy\n' + KEY)


@pytest.mark.skipif(not (X86_AVX2 and AVX512), reason="NumPy's AVX-512 code needs AVX-512")
def test_numpys_own_processor_choice_keys_the_cache_apart():
    # NumPy's exp and log for AVX2 alone, as on a host without AVX-512: other
    # figures in their last bits, so another key for the cache.
    assert run(KEY, **{_blas.NUMPY_PIN: ' '.join(_blas.NUMPY_ABOVE_AVX2)}) != run(KEY)


def _makefile() -> str:
    return open(os.path.join(os.path.dirname(__file__), '..', 'Makefile')).read()


def _dispatch():
    try:
        from numpy._core._multiarray_umath import __cpu_dispatch__
    except ImportError:     # NumPy 1.x: another layout, other names
        pytest.skip('NumPy 2 names its dispatch targets in numpy._core')
    return list(__cpu_dispatch__)


def test_the_makefile_pins_numpy_for_the_detector_and_its_study_only():
    text = _makefile()
    names = re.search(r'^NUMPY_ABOVE_AVX2 := (.*)$', text, re.M)
    assert names and tuple(names.group(1).split()) == _blas.NUMPY_ABOVE_AVX2
    assert re.search(rf"^PINNED := .*{_blas.NUMPY_PIN}='\$\(NUMPY_ABOVE_AVX2\)'", text, re.M)
    for module in ('stiction_ros.cli.detector', 'stiction_ros.cli.accuracy'):
        assert f'$(PINNED) $(PY) -m {module}' in text, module
    # What a user's analysis costs is timed as the user runs it: unpinned.
    assert '$(PINNED) $(PY) -m bench' not in text


@pytest.mark.skipif(not X86_AVX2, reason='the names are those of x86 targets')
def test_every_numpy_target_above_avx2_is_named():
    # A NumPy with a new target would let a host that has it run other code.
    assert set(_dispatch()) - {'X86_V3'} <= set(_blas.NUMPY_ABOVE_AVX2)


@pytest.mark.skipif(not (X86_AVX2 and AVX512), reason='without AVX-512 NumPy runs AVX2 code')
def test_pinned_numpy_runs_the_code_an_avx2_processor_runs():
    _dispatch()
    code = ('import json\nfrom numpy._core._multiarray_umath import __cpu_dispatch__, '
            '__cpu_features__\nprint(json.dumps([t for t in __cpu_dispatch__ '
            'if __cpu_features__.get(t)]))')
    assert len(run(code)) > 1
    # What a processor with AVX2 and FMA but no AVX-512 enables in the same NumPy.
    assert run(code, **{_blas.NUMPY_PIN: ' '.join(_blas.NUMPY_ABOVE_AVX2)}) == ['X86_V3']


def _warned_build(cache, said: str) -> str:
    """Return a script that builds an empty seed range for ``cache`` and prints ``said``."""
    # An empty seed range: the warnings come before any figure is computed.
    return f"""
import json, warnings, stiction_ros
from stiction_ros import _blas
from stiction_ros.analysis.detection import dataset
with warnings.catch_warnings(record=True) as seen:
    warnings.simplefilter('always')
    dataset.build(range(0), cache={str(cache)!r}, progress=False)
print(json.dumps({said}))
"""


@pytest.mark.skipif(not X86_AVX2, reason='nothing is pinned off x86-64 with AVX2 and FMA')
def test_a_script_that_loads_numpy_first_is_warned_before_figures_are_computed(tmp_path):
    build = _warned_build(tmp_path, '[str(w.message) for w in seen '
                                    'if "import stiction_ros first" in str(w.message)]')
    late = run('import numpy\n' + build)
    assert len(late) == 1 and 'NumPy was loaded before stiction_ros' in late[0]
    assert run(build) == []


@pytest.mark.skipif(not X86_AVX2, reason='nothing is pinned off x86-64 with AVX2 and FMA')
def test_a_script_without_the_numpy_pin_is_warned_where_numpy_would_run_avx512(tmp_path):
    # The other way to miss make detector's cache: the host's AVX-512 code.
    build = _warned_build(tmp_path, '[_blas.numpy_above_avx2(), [str(w.message) for w in '
                                    'seen if _blas.NUMPY_PIN in str(w.message)]]')
    above, said = run(build)
    assert set(above) <= set(_blas.NUMPY_ABOVE_AVX2)
    assert len(said) == (1 if above else 0)
    if above:
        assert all(t in said[0] for t in above)
    assert run(build, **{_blas.NUMPY_PIN: ' '.join(_blas.NUMPY_ABOVE_AVX2)}) == [[], []]


@pytest.mark.parametrize('above', [['X86_V4'], []])
def test_the_numpy_warning_follows_what_numpy_runs_on_any_host(above, monkeypatch, tmp_path):
    import warnings
    from stiction_ros.analysis.detection import dataset
    monkeypatch.setattr(dataset, 'numpy_above_avx2', lambda: above)
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter('always')
        dataset.build(range(0), cache=tmp_path, progress=False)
    said = [str(w.message) for w in seen if _blas.NUMPY_PIN in str(w.message)]
    assert len(said) == len(above)
    assert all('X86_V4' in m for m in said)
