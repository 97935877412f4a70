"""The fits' verdict over a noisy reading: shares above the noise, and fits that never slip."""

import math

import numpy as np
import pytest

from stiction_ros.analysis.caution import slips
from stiction_ros.analysis.noise_share import ROOM, share_above_noise
from stiction_ros.analysis.verdict import from_fits, MIN_SLIPS


def test_the_share_above_the_noise_runs_from_the_reference_to_the_noise():
    n = 4000
    assert share_above_noise(5.0, 5.0, 4.0, n) == 0.0
    assert share_above_noise(4.0, 5.0, 4.0, n) == pytest.approx(1.0)
    assert share_above_noise(4.5, 5.0, 4.0, n) == pytest.approx(0.5)


def test_a_fit_below_the_noise_says_the_noise_estimate_is_too_high():
    # No model fits under white noise: past the estimate's error the share would pass 1.
    n = 4000
    error = ROOM / math.sqrt(n) * 5.0
    assert share_above_noise(4.0 - 0.9 * error, 5.0, 4.0, n) > 1.0
    assert share_above_noise(4.0 - 1.1 * error, 5.0, 4.0, n) is None


def test_an_excess_within_the_noise_estimates_error_gives_no_share():
    n = 400
    edge = ROOM / math.sqrt(n) * 5.0
    assert share_above_noise(4.9, 5.0, 5.0 - 0.99 * edge, n) is None
    assert share_above_noise(4.9, 5.0, 5.0 - 1.01 * edge, n) is not None
    # More samples estimate the noise better: the same excess then counts.
    assert share_above_noise(4.9, 5.0, 5.0 - 0.99 * edge, 100 * n) is not None
    for unknown in ((4.0, None, 1.0, n), (4.0, 5.0, None, n), (4.0, 5.0, 1.0, None),
                    (4.0, 5.0, 0.0, n)):
        assert share_above_noise(*unknown) is None


def test_slips_count_each_start_of_a_move_in_each_segment():
    still = np.full(50, 40.0)
    assert slips(still, [(0, 50)]) == 0
    assert slips(np.linspace(0.0, 10.0, 50), [(0, 50)]) == 1
    stairs = np.repeat(np.arange(5.0), 10)  # four steps
    assert slips(stairs, [(0, 50)]) == 4
    # A step between two segments is no slip of either; one at a segment's start is.
    assert slips(stairs, [(0, 10), (10, 20)]) == 0
    assert slips(stairs, [(9, 20)]) == 1
    # Against a naive count: a move that starts where the valve rested.
    rng = np.random.default_rng(3)
    walk = np.round(np.cumsum(rng.normal(0, 1, 300)) * (rng.random(300) < 0.3), 0)
    naive = sum(1 for k in range(1, 300) if walk[k] != walk[k - 1]
                and (k == 1 or walk[k - 1] == walk[k - 2]))
    assert slips(walk, [(0, 300)]) == naive


def fit(**changes):
    # A clear band and jump that removes 60 % of an ideal valve's MSE.
    out = {'model': 'kano', 'S': 4.0, 'J': 2.0, 'mse': 2.0, 'S_interval': [3.8, 4.2],
           'J_interval': [1.8, 2.2], 'ideal_valve_mse': 5.0, 'improvement': 0.6,
           'mv_noise_var': 1.0, 'samples': 4000, 'op_step': 0.1, 'slips': 40}
    out.update(changes)
    return out


def test_a_fit_whose_valve_hardly_moves_claims_no_stiction():
    assert from_fits([fit()]).detected is True
    for few in range(MIN_SLIPS):
        told = from_fits([fit(slips=few)])
        assert told.detected is None and told.code == 'few_slips'
        assert f'starts to move {few} times' in told.reason
    # Nor does stick-slip refitted behind the reading's timing whose valve stays put.
    chain = {'mse': 6.0, 'dead_time_s': 2.0, 'lag_s': 0.0, 'offset': 0.0, 'gain': 1.0}
    behind = {'model': 'kano', 'S': 4.0, 'J': 2.0, 'S_interval': [3.9, 4.1],
              'J_interval': [1.9, 2.1], 'mse': 1.5, 'offset': 0.0, 'gain': 1.0,
              'dead_time_s': 2.0, 'plausible': True, 'slips': 30}
    late = fit(slips=0, frictionless=chain, behind=behind)
    assert from_fits([late]).read_behind
    told = from_fits([{**late, 'behind': {**behind, 'slips': 1}}])
    assert told.detected is None and told.code == 'few_slips'


def test_play_whose_valve_hardly_moves_is_no_size_of_play():
    # A band without a slip jump is play, of a size read from the valve's moves.
    play = fit(J=0.0, J_interval=[0.0, 0.02], mse=1.2)
    told = from_fits([play])
    assert told.detected is False and told.play == pytest.approx(4.0)
    told = from_fits([{**play, 'slips': MIN_SLIPS - 1}])
    assert told.detected is None and told.code == 'few_slips' and told.play is None


def test_a_noisy_fit_is_stiction_by_its_share_above_the_noise():
    # 2 % of noise (variance 4): a fifth of the ideal valve's MSE, all that lies above it.
    noisy = fit(mse=4.0, ideal_valve_mse=5.0, improvement=0.2, mv_noise_var=4.0)
    told = from_fits([noisy])
    # The score is the evidence that decided: the share above the noise, not a fifth.
    assert told.detected is True and told.score == pytest.approx(1.0)
    assert from_fits([{**noisy, 'mse': 4.4, 'improvement': 0.12}]).score == \
        pytest.approx(0.6)
    # The noise read as 4.9: the excess is within its error and the share says nothing.
    told = from_fits([{**noisy, 'mv_noise_var': 4.9}])
    assert told.detected is None and told.code == 'noisy_mv'
    # A fit well under the noise read: that reading of the noise is too high to count.
    told = from_fits([{**noisy, 'mse': 3.0, 'improvement': 0.4}])
    assert told.detected is None and told.code == 'noisy_mv'
    # The claim against a valve without friction counts what lies above the noise too.
    chain = {'mse': 5.0, 'dead_time_s': 0.0, 'lag_s': 1.0, 'offset': 0.0, 'gain': 1.0}
    assert from_fits([{**noisy, 'frictionless': chain}]).detected is True


def test_play_that_a_valve_without_friction_explains_is_that_valve():
    chain = {'mse': 1.1, 'dead_time_s': 0.0, 'lag_s': 3.0, 'offset': 0.0, 'gain': 1.0}
    play = fit(J=0.02, J_interval=[0.0, 0.3], frictionless=chain)
    assert from_fits([{k: v for k, v in play.items() if k != 'frictionless'}]).code == \
        'slip_unresolved'
    told = from_fits([play])
    assert told.detected is False and told.without_friction == 'lag 3 s' and told.score == 0.0


def test_a_valve_without_friction_that_ties_within_the_noise_is_cannot_tell():
    chain = {'mse': 4.8, 'dead_time_s': 2.0, 'lag_s': 0.0, 'offset': 0.0, 'gain': 1.0}
    # Stick-slip at 5.0 and that valve at 4.8 over noise 4.0: both leave about as much.
    tie = fit(mse=5.0, ideal_valve_mse=6.5, improvement=0.23, mv_noise_var=4.0,
              frictionless=chain)
    assert from_fits([{k: v for k, v in tie.items() if k != 'frictionless'}]).detected
    told = from_fits([tie])
    assert told.detected is None and told.code == 'frictionless_fits'
    # That valve down to the noise, stick-slip well above it: timing, not friction.
    told = from_fits([{**tie, 'frictionless': {**chain, 'mse': 4.0}, 'mse': 4.9}])
    assert told.detected is False and 'dead time 2 s' in told.without_friction


def test_a_band_that_removes_too_little_is_no_stiction_only_over_a_known_noise():
    # A clear band removing a tenth of an ideal valve's MSE (a sixth of what it leaves
    # above a noise of 2), its jump within OP's move in a sample: no stiction.
    weak = fit(mse=4.5, improvement=0.1, ideal_valve_mse=5.0, mv_noise_var=2.0, op_step=2.5)
    assert from_fits([weak]).detected is False
    # A held reading: most sample-to-sample changes are none, and the noise reads 0.
    told = from_fits([{**weak, 'mv_noise_var': 0.0}])
    assert told.detected is None and told.code == 'noise_unknown'
    assert 'held or quantised' in told.reason
    # MV moving between samples: the fit comes well under the noise its changes show.
    told = from_fits([{**weak, 'mv_noise_var': 5.5}])
    assert told.detected is None and told.code == 'noise_unknown'
    assert 'MV moves between samples' in told.reason


def test_play_is_no_stiction_only_where_it_explains_mv():
    play = fit(J=0.0, J_interval=[0.0, 0.02], mse=1.2, mv_noise_var=1.0)
    assert from_fits([play]).detected is False
    # Leaving 5 times the noise: a lag in the reading may smooth slips into play.
    told = from_fits([{**play, 'mse': 2.0, 'mv_noise_var': 0.4}])
    assert told.detected is None and told.code == 'unexplained_mv'
    assert "5 times MV's noise variance" in told.reason
    told = from_fits([{**play, 'mv_noise_var': 0.0}])
    assert told.detected is None and told.code == 'noise_unknown'
