"""The live benchmark's OP-to-MV latency: each MV against the newest OP before it."""

from bench.live_bench import newest_input_age
import numpy as np


def test_an_output_a_quarter_sample_after_its_input_reads_a_quarter_sample():
    ts = 1_000_000
    op = np.arange(10) * ts + ts // 2
    mv = op + ts // 4
    np.testing.assert_array_equal(newest_input_age(op, mv), np.full(10, ts // 4))


def test_late_or_missing_inputs_never_give_a_negative_age():
    ts = 1_000_000
    rng = np.random.default_rng(0)
    # Inputs late by up to two samples, a third of them missing, in any order.
    op = np.arange(200) * ts + ts // 2 + rng.integers(0, 2 * ts, 200)
    op = rng.permutation(op[rng.random(200) > 1 / 3])
    mv = np.arange(200) * ts + 3 * ts // 4
    age = newest_input_age(op, mv)
    assert np.all(age >= 0)
    # Every output after the first input is paired, and with the newest input before it.
    paired = mv[mv >= op.min()]
    assert age.size == paired.size
    for t, a in zip(paired, age):
        assert a == t - op[op <= t].max()
