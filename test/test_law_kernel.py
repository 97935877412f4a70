"""
The timing check's compiled law fit against the plain least-squares fit it replaced.

The reference is the one ``make bench-detector`` times it against.
"""

from bench.detector_bench import lstsq_r2
import numpy as np
import pytest
from stiction_ros import _jit
from stiction_ros.analysis.detection.timing import law_profile, MAX_SHIFT, MIN_ROWS
from stiction_ros.kernels.law import law_r2_shifts


def rows(seed, kind):
    rng = np.random.default_rng(seed)
    n = int(rng.integers(40, 400))
    e = np.cumsum(rng.normal(size=n + 1))
    d_e = np.diff(e)
    if kind == 'constant error':            # PV on its set point throughout
        e = np.full(n + 1, 2.5)
        d_e = np.zeros(n)
    elif kind == 'parallel':                 # E a multiple of dE: one column spans both
        e = 3.0 * np.concatenate([[0.0], d_e])
    d_op = 0.7 * d_e + 0.05 * e[1:] + rng.normal(scale=float(rng.uniform(0.01, 2)), size=n)
    free = rng.uniform(size=n) > rng.uniform(0, 0.5)
    known = rng.uniform(size=n) > 0.1
    return d_op, d_e, np.ascontiguousarray(e[1:]), free, known


@pytest.mark.parametrize('kind', ['random', 'constant error', 'parallel'])
def test_the_compiled_fit_gives_the_r2_of_least_squares_at_every_shift(kind):
    compared = 0
    for seed in range(60):
        d_op, d_e, e, free, known = rows(seed, kind)
        got = law_r2_shifts(d_op, d_e, e, free, known, -MAX_SHIFT, MAX_SHIFT, MIN_ROWS)
        want = np.array([lstsq_r2(d_op, d_e, e, free, known, k)
                         for k in range(-MAX_SHIFT, MAX_SHIFT + 1)])
        assert np.array_equal(np.isnan(got), np.isnan(want)), seed
        ok = ~np.isnan(want)
        assert np.allclose(got[ok], want[ok], rtol=0, atol=1e-9), seed
        assert np.all((got[ok] >= 0) & (got[ok] <= 1))
        compared += int(ok.sum())
    assert compared > 200                    # most shifts were fitted, not NaN on both sides


def test_a_law_that_holds_exactly_explains_everything_at_its_own_shift_only():
    rng = np.random.default_rng(7)
    n, k = 600, 2
    pv = np.cumsum(rng.normal(size=n))
    e = -pv
    op = 50 + np.concatenate([[0.0], np.cumsum(1.2 * np.diff(e) + 0.1 * e[1:])])
    logged = np.concatenate([np.full(k, pv[0]), pv[:-k]])     # PV logged k rows late
    r2 = law_profile(op, logged, None)
    assert r2[MAX_SHIFT + k] > 1 - 1e-9
    assert np.nanmax(np.delete(r2, MAX_SHIFT + k)) < 0.99


def test_boolean_array_arguments_are_checked_before_the_built_code_reads_them():
    check = _jit._check('b1[::1]')
    assert check(np.zeros(4, bool))
    assert not check(np.zeros(4, np.uint8)) and not check(np.zeros(8, bool)[::2])
