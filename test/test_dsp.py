"""
The analysis' own detrend, decimation and chi-square quantile against scipy's originals.

stiction_ros.analysis.dsp exists so that the default analysis need not import
scipy.signal and scipy.stats (about a second); these tests hold it to what
those give, and check that the default analysis really does without them.
"""

import json
import os
import subprocess
import sys

import numpy as np
import pytest
from scipy import signal, stats

from stiction_ros.analysis.dsp import chi2_ppf, decimate, detrend_linear, lowpass_fir


@pytest.mark.parametrize('n', [2, 3, 17, 128, 8641])
def test_detrend_equals_scipy_to_the_bit(n):
    rng = np.random.default_rng(n)
    x = rng.normal(size=n) + 0.01 * np.arange(n) ** 1.5
    assert np.array_equal(detrend_linear(x), signal.detrend(x, type='linear'))


def test_detrend_along_an_axis_equals_scipy_to_the_bit():
    segments = np.random.default_rng(7).normal(size=(40, 64)).cumsum(axis=1)
    assert np.array_equal(detrend_linear(segments, axis=1), signal.detrend(segments, axis=1))
    assert np.array_equal(detrend_linear(segments, axis=0), signal.detrend(segments, axis=0))


def test_detrend_removes_a_line_exactly():
    t = np.arange(500.0)
    assert np.max(np.abs(detrend_linear(3.0 - 0.2 * t))) < 1e-12


@pytest.mark.parametrize('factor', [2, 3, 7, 16, 25])
@pytest.mark.parametrize('n', [5, 101, 1000, 8641])
def test_decimate_equals_resample_poly(n, factor):
    x = np.random.default_rng(n * factor).normal(size=n).cumsum()
    ours, theirs = decimate(x, factor), signal.resample_poly(x, 1, factor)
    assert ours.shape == theirs.shape
    assert np.max(np.abs(ours - theirs)) <= 1e-12 * max(1.0, np.max(np.abs(theirs)))


def test_decimation_filter_passes_dc_and_stops_above_the_new_nyquist():
    factor = 8
    h = lowpass_fir(factor)
    assert abs(h.sum() - 1.0) < 1e-15
    gain = np.abs(np.fft.rfft(h, 4096))
    f = np.fft.rfftfreq(4096)
    # Kaiser beta 5: about 50 dB down a transition band beyond the cut-off.
    assert np.max(gain[f > 1.5 / (2 * factor)]) < 10 ** (-40 / 20)
    assert np.min(gain[f < 0.5 / (2 * factor)]) > 0.99


def test_decimate_by_one_is_a_copy():
    x = np.arange(5.0)
    y = decimate(x, 1)
    assert np.array_equal(x, y) and y is not x


@pytest.mark.parametrize('dof', [2, 4, 10, 128, 2016, 4032, 40000])
@pytest.mark.parametrize('q', [0.001, 0.05, 0.5, 0.95, 0.999])
def test_chi2_ppf_of_even_degrees_equals_scipy(q, dof):
    tol = 1e-12 if q >= 0.05 else 1e-10
    assert chi2_ppf(q, dof) == pytest.approx(stats.chi2.ppf(q, dof), rel=tol)


@pytest.mark.parametrize('dof', [1, 3, 2.5])
def test_chi2_ppf_of_other_degrees_is_scipys(dof):
    assert chi2_ppf(0.95, dof) == stats.chi2.ppf(0.95, dof)


def test_default_analysis_imports_neither_scipy_nor_numba_when_built_ahead(tmp_path):
    t = np.arange(2000.0)
    op = 50 + 5 * np.sin(2 * np.pi * t / 100)
    mv = np.round(op / 2) * 2
    csv = tmp_path / 'loop.csv'
    np.savetxt(csv, np.column_stack([t, op, mv, mv + 1]), delimiter=',',
               header='t,op,mv,pv', comments='')
    code = ('import json, sys\n'
            'from stiction_ros.cli.analyze import main\n'
            f'status = main([{str(csv)!r}, "--model", "kano", "--quiet"])\n'
            'print(json.dumps([status, sorted(m for m in sys.modules if m.startswith('
            '("scipy", "numba")))]))\n')
    out = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                         env={**os.environ, 'PYTHONWARNINGS': 'ignore'}, timeout=120)
    assert out.returncode == 0, out.stderr
    status, loaded = json.loads(out.stdout.strip().splitlines()[-1])
    assert status == 0
    assert loaded == [], f'the default analysis imported {loaded[:5]}'
