"""The detector's judge, stuck periods, model file and the export of the trained trees."""

import numpy as np
import pytest

from stiction_ros.analysis.detection import detect, load_model, model_file
from stiction_ros.analysis.detection.detect import HELD_ERRORS, leaned_on, RAMP_R2
from stiction_ros.analysis.detection.resolve import (
    cycle_judgeable, judgeable, limit_swings, MIN_SAMPLES, period_sanity)
from stiction_ros.analysis.detection.stuck import stuck_periods
from stiction_ros.resources import config_file
from stiction_ros.sim.closed_loop import simulate_loop
from stiction_ros.sim.disturbed_loops import disturbed_loop
from stiction_ros.sim.loop_config import load_loop


def noisy(n, seed=0, scale=1.0):
    return scale * np.random.default_rng(seed).standard_normal(n)


def test_cannot_tell_reasons():
    op = 50 + np.cumsum(noisy(600, 1, 0.1))
    pv = 10 + noisy(600, 2)
    assert judgeable(op, pv, 1.0).ok
    assert judgeable(op[:MIN_SAMPLES - 1], pv[:MIN_SAMPLES - 1], 1.0).code == 'too_short'
    # A plant export's PV of 3.5e-44 throughout: the bits of 25 read as a float.
    j = judgeable(op, np.full(600, 3.5e-44), 1.0)
    assert j.code == 'pv_constant' and 'whole number 25' in j.reason
    # Zero under a moving OP: nothing passed, or a range's bottom, said with where OP went;
    # a constant that is not zero is the transmitter's or the tag's.
    j = judgeable(op, np.zeros(600), 1.0)
    assert 'low-flow cut-off' in j.reason and f'{op.min():.3g} and {op.max():.3g} %' in j.reason
    assert 'fraction' in judgeable(op / 100.0 - 0.1, np.zeros(600), 1.0).reason
    k = judgeable(op, np.full(600, 7.5), 1.0)
    assert k.code == 'pv_constant' and 'one value' in k.reason and 'cut-off' not in k.reason
    # OP that does not move asked nothing of the valve: no shut valve to speak of.
    assert 'cut-off' not in judgeable(np.full(600, 42.0), np.zeros(600), 1.0).reason
    assert judgeable(np.full(600, 42.0), pv, 1.0).code == 'no_excitation'
    # OP exported as a 0-1 fraction: refused, and the reason says what to do.
    j = judgeable(op / 100.0 - 0.1, pv, 1.0)
    assert j.code == 'no_excitation' and 'x 100' in j.reason
    assert 'x 100' not in judgeable(np.full(600, 42.0), pv, 1.0).reason
    # OP and PV flipping every sample: a cycle the sampling cannot resolve.
    alt = np.where(np.arange(600) % 2 == 0, 1.0, -1.0)
    j = judgeable(50 + 5 * alt + noisy(600, 3, 0.1), 5 * alt + noisy(600, 4, 0.1), 180.0)
    assert j.code == 'under_sampled' and '180 s' in j.reason


def test_a_loop_whose_op_does_not_act_on_its_error_cannot_be_told():
    rec = _flow_loop({'model': 'linear'}, 7)
    assert judgeable(rec['op'], rec['pv'], 1.0, rec['sp']).ok
    # An override selector hands the valve to another controller, which
    # cycles it; this loop's PV follows the valve through a first-order lag
    # and never comes near this loop's set point, five PV ranges away.
    n = 900
    op = 50 + 3 * np.sin(2 * np.pi * np.arange(n) / 300) + noisy(n, 3, 0.05)
    pv = np.zeros(n)
    for k in range(1, n):
        pv[k] = 0.9 * pv[k - 1] + 0.1 * (op[k - 1] - 50)
    pv += noisy(n, 4, 0.1)
    far = np.full(n, pv.min() - 5 * np.ptp(pv))
    assert judgeable(op, pv, 1.0).ok
    j = judgeable(op, pv, 1.0, far)
    assert j.code == 'not_in_control' and 'above the set point' in j.reason
    d = detect(op, pv, far, 1.0)
    assert d.answer == 'cannot tell' and d.probability is None
    assert d.judge.code == 'not_in_control'
    # A few flagged set-point samples change nothing: the rest still show it.
    far[::50] = np.nan
    assert judgeable(op, pv, 1.0, far).code == 'not_in_control'
    # A slow loop still approaching a far set point: the error keeps one sign
    # and integral action drives OP one way, so it is a loop in control.
    n = 600
    ramp_op = np.linspace(30.0, 70.0, n) + noisy(n, 5, 0.05)
    slow_pv = np.linspace(0.0, 1.0, n) + noisy(n, 6, 0.05)
    assert judgeable(ramp_op, slow_pv, 1.0, np.full(n, 20.0)).ok
    # OP at its limit most of the time is wind-up, the loop's own doing.
    wound = np.where(np.arange(n) < 400, 100.0, 90.0 + noisy(n, 7))
    assert judgeable(wound, slow_pv, 1.0, np.full(n, 20.0)).ok


def test_period_sanity_rules():
    assert period_sanity(300.0, 10.0, 1000) == ''
    assert 'only 5.0 samples' in period_sanity(50.0, 10.0, 1000)
    assert 'quarter of the record' in period_sanity(3000.0, 10.0, 1000)
    assert not cycle_judgeable(True, 40.0, 10.0).ok
    assert cycle_judgeable(True, 400.0, 10.0).ok
    assert cycle_judgeable(False, None, 10.0).ok


def test_a_sticking_valve_sampled_every_3_minutes_cannot_be_told():
    # Table 2.1's loop with a sticking valve cycles every ~75 s at 1 s; a
    # historian that keeps one sample in 180 sees no cycle it can resolve.
    cfg = load_loop(config_file('concentration_loop.yaml'), overrides={
        'valve': {'model': 'kano', 'S': 5.0, 'J': 5.0},
        'noise': {'pv_std': 0.05, 'seed': 1}})
    out = simulate_loop(cfg, 180.0 * 1500)
    from stiction_ros.analysis.oscillation import detect_oscillation
    fine = detect_oscillation(out['sp'][:5000] - out['pv'][:5000], 1.0)
    assert fine.oscillating and 60 < fine.period_s < 90
    op, pv, sp = (out[k][::180] for k in ('op', 'pv', 'sp'))
    # The detector itself, as the analyzer calls it: no probability, no vote.
    d = detect(op, pv, sp, 180.0)
    assert d.answer == 'cannot tell' and d.probability is None
    assert d.judge.code == 'under_sampled' and '180 s' in d.reason


def _flow_loop(valve, seed):
    # A fast self-regulating loop hit by load steps: PV stands in for MV.
    return disturbed_loop(valve, seed, Kc=0.2, Ti=60.0, pv_std=0.02, duration=4000.0)


def test_a_loop_cycling_between_op_limits_cannot_be_told():
    # Ten times the flow loop's gain: a linear valve driven from stop to stop.
    rec = disturbed_loop({'model': 'linear'}, 7, Kc=2.0, Ti=60.0, duration=2000.0)
    swings = limit_swings(rec['op'])
    assert swings >= 50
    j = judgeable(rec['op'], rec['pv'], 1.0, rec['sp'])
    assert j.code == 'limit_cycling' and f'other {swings} times' in j.reason
    d = detect(rec['op'], rec['pv'], rec['sp'], 1.0)
    assert d.answer == 'cannot tell' and d.probability is None and d.judge.code == 'limit_cycling'
    # At the normal gain it stays inside its range and is judged.
    calm = _flow_loop({'model': 'linear'}, 7)
    assert limit_swings(calm['op']) == 0 and judgeable(calm['op'], calm['pv'], 1.0).ok
    # One limit only (a valve too small at the top of each cycle), or one trip
    # from one limit to the other (a start-up), is not a cycle between them.
    t = np.arange(900)
    top = np.clip(70 + 40 * np.sin(2 * np.pi * t / 90), 0, 100) + noisy(900, 8, 0.05)
    assert limit_swings(np.clip(top, 0, 100)) == 0
    trip = np.concatenate([np.zeros(300), np.linspace(0, 100, 300), np.full(300, 100.0)])
    assert limit_swings(trip) == 1
    pv = np.sin(2 * np.pi * t / 90) + noisy(900, 9, 0.1)
    assert judgeable(trip + noisy(900, 10, 0.05), pv, 1.0).code != 'limit_cycling'
    # Slammed from stop to stop every few samples: two values, a cycle and not a frozen OP.
    bang = np.where(np.sin(2 * np.pi * t / 12) > 0, 100.0, 0.0)
    assert judgeable(bang, pv, 1.0).code == 'limit_cycling'


def test_stuck_periods_are_where_the_valve_really_stood_still():
    rec = _flow_loop({'model': 'kano', 'S': 3.0, 'J': 1.0}, 101)
    st = stuck_periods(rec['op'], rec['pv'], rec['sp'])
    assert st.stuck, 'a valve with a 3 % band under PI must be found stuck somewhere'
    for a, b, _ in st.stuck:
        # The physics: inside a stuck period the true position barely moves
        # while OP travels; allow the edges a smoothing window each.
        mv = rec['mv_true'][a + 5:b - 5]
        still = np.mean(np.abs(np.diff(mv)) < 1e-9) if mv.size > 1 else 1.0
        assert still > 0.8, (a, b, still)


def test_stuck_periods_without_a_slip_are_said_to_be_what_a_deadband_leaves_too():
    # Play without a slip jump (Kano, J 0) under noise that hides the restart.
    dead = disturbed_loop({'model': 'kano', 'S': 3.0, 'J': 0.0}, 101, Kc=0.2, Ti=60.0,
                          pv_std=0.3, duration=4000.0)
    d = detect(dead['op'], dead['pv'], dead['sp'], 1.0)
    stuck = d.details['stuck']
    assert stuck['stuck_periods_s'] and not stuck['slips_s']
    assert any(line.startswith('no slip after any stuck period') and 'deadband' in line
               for line in d.evidence)
    # Said before the periods it qualifies, which are listed in the order they happened.
    first = [i for i, line in enumerate(d.evidence) if line.startswith('stuck period ')]
    caveat = [i for i, line in enumerate(d.evidence) if line.startswith('no slip after')]
    assert first and caveat[0] < first[0]
    starts = [float(d.evidence[i].split()[2].split('-')[0].rstrip('s')) for i in first]
    assert starts == sorted(starts)
    # Each says how far OP moved, and in what units, as the JSON's third number
    # (the JSON keeps the first 20 periods; this record has fewer).
    travels = [float(d.evidence[i].split('range of ')[1].split()[0]) for i in first]
    by_travel = sorted((p[2] for p in stuck['stuck_periods_s']), reverse=True)[:len(first)]
    assert sorted(travels) == pytest.approx(sorted(by_travel), rel=1e-2)
    assert all("in OP's own units" in d.evidence[i] for i in first)
    # A valve that slips says so, and not this.
    sticky = _flow_loop({'model': 'kano', 'S': 3.0, 'J': 1.5}, 101)
    d = detect(sticky['op'], sticky['pv'], sticky['sp'], 1.0)
    assert d.details['stuck']['slips_s']
    assert not any(line.startswith('no slip after any') for line in d.evidence)


def test_a_linear_valve_is_rarely_found_stuck():
    shares = [stuck_periods(r['op'], r['pv'], r['sp']).stuck_op_share
              for r in (_flow_loop({'model': 'linear'}, s) for s in range(200, 206))]
    sticky = [stuck_periods(r['op'], r['pv'], r['sp']).stuck_op_share
              for r in (_flow_loop({'model': 'kano', 'S': 3.0, 'J': 1.0}, s)
                        for s in range(200, 206))]
    assert np.median(shares) < 0.2 < np.median(sticky)


def test_a_stuck_valve_leaves_a_straight_op_ramp_on_a_held_error():
    # Integral action on the constant error of a stuck valve ramps OP in a
    # straight line; a linear valve's stretches of still PV (the loop holding
    # PV against its loads) have a wandering OP and an error nearer zero.
    seeds = range(200, 206)
    sticky = [stuck_periods(r['op'], r['pv'], r['sp'])
              for r in (_flow_loop({'model': 'kano', 'S': 3.0, 'J': 1.0}, s) for s in seeds)]
    linear = [stuck_periods(r['op'], r['pv'], r['sp'])
              for r in (_flow_loop({'model': 'linear'}, s) for s in seeds)]
    linear = [st for st in linear if st.stuck]
    assert all(st.stuck for st in sticky) and linear
    assert min(st.ramp_r2 for st in sticky) > 0.9 > max(st.ramp_r2 for st in linear)
    assert min(st.log_offset for st in sticky) > max(st.log_offset for st in linear)
    empty = stuck_periods(np.zeros(300), np.zeros(300), None)
    assert not empty.stuck and np.isnan(empty.ramp_r2) and np.isnan(empty.log_offset)


def test_a_steady_load_drift_leaves_the_ramp_of_a_stuck_valve_and_the_evidence_says_so():
    # A linear valve under PI control against a load that climbs at a steady
    # rate: the error settles to a constant that integral action turns into a
    # straight OP ramp while PV stays flat, which is what a stuck valve leaves.
    loads = [(float(t), 0.02) for t in np.arange(500.0, 3500.0, 10.0)]
    cfg = load_loop(config_file('concentration_loop.yaml'), overrides={
        'valve': {'model': 'linear'}, 'controller.Kc': 0.2, 'controller.Ti': 60.0,
        'controller.setpoint': {'type': 'steps', 'steps': [[0.0, 0.0]]},
        'plant.disturbance_steps': loads, 'noise': {'pv_std': 0.02, 'seed': 1}})
    rec = simulate_loop(cfg, 4000.0)
    st = stuck_periods(rec['op'], rec['pv'], rec['sp'])
    assert st.stuck and np.ptp(rec['mv_true'][st.stuck[0][0]:st.stuck[0][1]]) > 0.5
    assert st.ramp_r2 > RAMP_R2 and 10.0 ** st.log_offset - 1.0 > HELD_ERRORS
    d = detect(rec['op'], rec['pv'], rec['sp'], 1.0)
    assert any('load drifting at a steady rate' in line for line in d.evidence), d.evidence


def _tiny_model(tmp_path, seed=0):
    pytest.importorskip('sklearn')
    from stiction_ros.analysis.detection.train import train
    rng = np.random.default_rng(seed)
    x = rng.standard_normal((600, 4))
    x[rng.random(x.shape) < 0.1] = np.nan
    y = (np.nan_to_num(x[:, 0]) + 0.5 * np.nan_to_num(x[:, 1]) ** 2
         + 0.3 * rng.standard_normal(600)) > 0.3
    model, clf = train(x[:400], y[:400], x[400:], y[400:], ('a', 'b', 'c', 'd'),
                       {'note': 'test'}, max_iter=40)
    path = tmp_path / 'm.npz'
    model_file.save(path, model)
    return path, x, clf


def test_exported_trees_score_exactly_as_scikit_learn(tmp_path):
    path, x, clf = _tiny_model(tmp_path)
    m = model_file.load(path, ('a', 'b', 'c', 'd'))
    assert np.allclose(m.raw_score(x), clf.decision_function(x), rtol=0, atol=1e-9)
    p = m.probability(x)
    assert np.all((p >= 0) & (p <= 1))
    # Calibration is monotone: a higher raw score never means less stiction.
    order = np.argsort(m.raw_score(x))
    assert np.all(np.diff(p[order]) >= -1e-12)


def test_the_trees_credit_their_score_to_the_figures_it_depends_on(tmp_path):
    path, x, _ = _tiny_model(tmp_path)
    m = model_file.load(path)
    raw = m.raw_score(x)
    parts = [m.contributions(row) for row in x]
    # Each split's move is credited once: the parts add up to the score.
    assert np.allclose([b + c.sum() for b, c in parts], raw, rtol=0, atol=1e-9)
    # The label is made of a and b; c and d are noise the trees barely use.
    mean_abs = np.mean([np.abs(c) for _, c in parts], axis=0)
    assert min(mean_abs[:2]) > 3 * max(mean_abs[2:])
    split_on = set(m.feature[m.is_leaf == 0])
    for j in set(range(4)) - split_on:
        assert all(c[j] == 0.0 for _, c in parts)


def test_a_missing_or_damaged_model_file_is_a_clear_error(tmp_path):
    path, _, _ = _tiny_model(tmp_path)
    with pytest.raises(model_file.DetectorFileError, match='make detector'):
        model_file.load(tmp_path / 'absent.npz')
    cut = tmp_path / 'cut.npz'
    cut.write_bytes(path.read_bytes()[:300])
    with pytest.raises(model_file.DetectorFileError, match='not a readable'):
        model_file.load(cut)
    with pytest.raises(model_file.DetectorFileError, match='trained on features'):
        model_file.load(path, ('x', 'y', 'z', 'w'))
    # One leaf value changed behind the checksum's back.
    with np.load(path, allow_pickle=False) as z:
        arrays = {k: z[k] for k in z.files}
    arrays['value'] = arrays['value'].copy()
    arrays['value'][3] += 1.0
    edited = tmp_path / 'edited.npz'
    np.savez(edited, **arrays)
    with pytest.raises(model_file.DetectorFileError, match='checksum'):
        model_file.load(edited)
    # Bytes flipped inside a compressed member, and a plain .npy in its place.
    raw = bytearray(path.read_bytes())
    for i in range(len(raw) // 3, len(raw) // 3 + 40):
        raw[i] ^= 0xFF
    flipped = tmp_path / 'flipped.npz'
    flipped.write_bytes(bytes(raw))
    with pytest.raises(model_file.DetectorFileError):
        model_file.load(flipped)
    npy = tmp_path / 'plain.npy'
    np.save(npy, np.zeros(3))
    with pytest.raises(model_file.DetectorFileError, match='not a readable'):
        model_file.load(npy)
    # A NaN leaf behind a recomputed checksum: refused, not a NaN probability.
    m = model_file.load(path)
    value = m.value.copy()
    value[-1] = np.nan
    nan_file = tmp_path / 'nan.npz'
    model_file.save(nan_file, model_file.TreeModel(**{**m.__dict__, 'value': value}))
    with pytest.raises(model_file.DetectorFileError, match='NaN'):
        model_file.load(nan_file)
    # A node no training record reached cannot weigh a path's credit.
    count = m.count.copy()
    count[0] = 0
    empty = tmp_path / 'empty.npz'
    model_file.save(empty, model_file.TreeModel(**{**m.__dict__, 'count': count}))
    with pytest.raises(model_file.DetectorFileError, match='no training record'):
        model_file.load(empty)


def test_the_shipped_model_loads_and_matches_the_features():
    from stiction_ros.analysis.detection import FEATURE_NAMES, load_model
    m = load_model()
    assert m.feature_names == FEATURE_NAMES
    assert 'no plant data' in m.meta['trained_on']


def test_a_verdict_names_the_figures_the_trees_leaned_on():
    rec = _flow_loop({'model': 'kano', 'S': 3.0, 'J': 1.0}, 201)
    d = detect(rec['op'], rec['pv'], rec['sp'], 1.0)
    leaned = d.to_json()['leaned_on']
    model = load_model()
    # The score the parts add up to is the one the probability was read from.
    assert np.isclose(np.interp(leaned['score'], model.calib_x, model.calib_y),
                      d.probability, atol=0.02)
    names = [c['feature'] for c in leaned['contributions']]
    assert len(names) == 3 and set(names) <= set(d.features) | {'cnn_large_logit'}
    from stiction_ros.analysis.detection.feature_words import words
    assert d.evidence[0].startswith('the learned detector leaned most on ' + words(names[0]))
    assert d.evidence[0].endswith(f'as a probability of {d.probability:.2f})')


def test_a_stacked_detector_weighs_the_large_network_in(tmp_path):
    path, x, _ = _tiny_model(tmp_path)
    m = model_file.load(path)
    w = [0.3, 0.5, 0.7]
    stacked = model_file.TreeModel(**{**m.__dict__, 'meta': {**m.meta, 'stack': {'coef': w}}})
    logit = np.linspace(-3, 3, len(x))
    assert np.allclose(stacked.score(x, logit), 0.3 + 0.5 * m.raw_score(x) + 0.7 * logit)
    with pytest.raises(ValueError, match='large network'):
        stacked.probability(x)
    # The parts of a stacked score still add up to it, the network one part.
    leaned = leaned_on(stacked, x[0], 2.0, top=len(m.feature_names) + 1)
    parts = {c['feature']: c['log_odds'] for c in leaned['contributions']}
    assert parts['cnn_large_logit'] == pytest.approx(1.4)
    assert leaned['start'] + sum(parts.values()) == pytest.approx(leaned['score'], abs=0.01)
    assert leaned['score'] == pytest.approx(stacked.score(x[:1], [2.0])[0], abs=1e-3)
    # Saved with two weights behind a fresh checksum: refused on load.
    bad = tmp_path / 'bad_stack.npz'
    model_file.save(bad, model_file.TreeModel(
        **{**m.__dict__, 'meta': {**m.meta, 'stack': {'coef': [0.1, 0.2],
                                                      'network_sha256': 'x'}}}))
    with pytest.raises(model_file.DetectorFileError, match='three finite weights'):
        model_file.load(bad)


def test_a_missing_or_other_large_network_is_a_clear_error(tmp_path, monkeypatch):
    from stiction_ros.analysis.detection import cnn, stack
    model = tmp_path / 'detector.npz'
    model.write_bytes(model_file.DEFAULT_PATH.read_bytes())
    monkeypatch.setattr(stack, 'LARGE_PATH', tmp_path / 'absent.npz')
    with pytest.raises(model_file.DetectorFileError, match='make cnn-large'):
        load_model(model)
    net = cnn.load(model_file.DEFAULT_PATH.parent / 'stiction_cnn_large.npz')
    arrays = {k: getattr(net, k) for k in cnn.ARRAYS}
    arrays['fc2_b'] = arrays['fc2_b'] + 0.5
    other = tmp_path / 'other.npz'
    cnn.save(other, arrays, net.meta)
    monkeypatch.setattr(stack, 'LARGE_PATH', other)
    with pytest.raises(model_file.DetectorFileError, match='another large network'):
        load_model(model)


def test_a_tree_that_points_back_is_refused_not_walked_forever(tmp_path):
    path, _, _ = _tiny_model(tmp_path)
    m = model_file.load(path)
    inner = int(np.flatnonzero(m.is_leaf == 0)[1])
    left = m.left.copy()
    left[inner] = inner  # a cycle: the node is its own child
    bad = tmp_path / 'cycle.npz'
    model_file.save(bad, model_file.TreeModel(**{**m.__dict__, 'left': left}))
    with pytest.raises(model_file.DetectorFileError, match='points back'):
        model_file.load(bad)


def test_the_large_network_reads_the_whole_record_and_three_80_percent_windows():
    from stiction_ros.analysis.detection import cnn, stack
    from stiction_ros.sim.corpus import draw_scenario, simulate
    sc = draw_scenario(7_000_123)
    rec = simulate(sc)
    op, pv, sp = rec['op'], rec['pv'], rec['sp']
    n = len(pv)
    naive = [cnn.cnn_logit(op[int(round(a * n)):int(round(b * n))],
                           pv[int(round(a * n)):int(round(b * n))],
                           sp[int(round(a * n)):int(round(b * n))], sc.integrating,
                           str(stack.LARGE_PATH)) for a, b in stack.VIEWS]
    assert (0.0, 1.0) in stack.VIEWS and len(set(naive)) == len(naive)
    assert stack.large_logit(op, pv, sp, sc.integrating) == pytest.approx(np.mean(naive),
                                                                          abs=1e-12)
    # A scalar set point is the same as one held at that value.
    assert stack.large_logit(op, pv, 50.0, sc.integrating) == pytest.approx(
        stack.large_logit(op, pv, np.full(n, 50.0), sc.integrating), abs=1e-12)
    # A record longer than one network window is already read as several windows.
    rng = np.random.default_rng(5)
    long_op = 50 + np.cumsum(rng.normal(0, 0.1, cnn.WINDOW + 1))
    long_pv = 10 + rng.normal(0, 1, cnn.WINDOW + 1)
    assert stack.large_logit(long_op, long_pv, None, False) == cnn.cnn_logit(
        long_op, long_pv, None, False, str(stack.LARGE_PATH))


def test_a_detector_stacked_on_other_views_of_the_record_is_refused(tmp_path):
    from stiction_ros.analysis.detection import stack
    m = model_file.load()
    for views in (None, [[0.0, 1.0]], 3):
        st = {k: v for k, v in m.meta['stack'].items() if k != 'views'}
        if views is not None:
            st['views'] = views
        path = tmp_path / f'views_{len(str(views))}.npz'
        model_file.save(path, model_file.TreeModel(**{**m.__dict__,
                                                      'meta': {**m.meta, 'stack': st}}))
        with pytest.raises(model_file.DetectorFileError, match='views'):
            stack.check_network(model_file.load(path).meta, str(path))


def test_an_answer_needs_odds_of_three_to_one():
    from stiction_ros.analysis.detection.detect import answer_of, BALANCED, reason_of
    lo, hi = BALANCED
    # The map is calibrated at even odds, so these edges are 3:1 either way.
    assert hi / (1 - hi) == pytest.approx(3.0) and (1 - lo) / lo == pytest.approx(3.0)
    assert answer_of(hi, BALANCED) == 'stiction'
    assert answer_of(np.nextafter(hi, 0.0), BALANCED) == 'cannot tell'
    assert answer_of(lo, BALANCED) == 'cannot tell'
    assert answer_of(np.nextafter(lo, 0.0), BALANCED) == 'no stiction'
    # A band of one point is the forced choice.
    assert answer_of(0.5, (0.5, 0.5)) == 'stiction'
    assert answer_of(np.nextafter(0.5, 0.0), (0.5, 0.5)) == 'no stiction'
    # Between the edges the reason says which way the evidence leans and what would tell.
    for p, lean in ((0.43, 'no stiction'), (0.63, 'stiction')):
        why = reason_of(p, BALANCED)
        assert 'balanced' in why and f'leaning to {lean};' in why and 'travel test' in why
    assert 'balanced' not in reason_of(0.8, BALANCED) + reason_of(0.1, BALANCED)
    # Just under an edge is not printed as the edge.
    assert 'probability of stiction 0.7499, between' in reason_of(0.7499, BALANCED)


@pytest.mark.parametrize('lag_rows', [0, 1, 2, 3])
def test_pv_answering_a_set_point_step_is_no_slip(lag_rows):
    # A fast flow loop follows its set point within a few rows: PV jumps, but
    # as a response, not as a valve breaking free.  The centred change sees the
    # jump rows before the step's own row, and must not call it a slip there.
    rng = np.random.default_rng(7)
    n, k = 600, 300
    sp = np.where(np.arange(n) < k, 50.0, 52.0)
    pv = 50.0 + 0.05 * rng.standard_normal(n)
    pv[k + lag_rows:] += 2.0
    op = 40.0 + 0.05 * rng.standard_normal(n)
    op[k:] += 4.0
    st = stuck_periods(op, pv, sp)
    assert not [s for s in st.slips if k - 10 <= s[0] <= k + 10], st.slips
    # The same jump with no set-point step is a slip.
    st = stuck_periods(op, pv, np.full(n, 50.0))
    assert [s for s in st.slips if k - 10 <= s[0] <= k + 10], st.slips


@pytest.mark.parametrize('lag_rows', [0, 1, 2])
@pytest.mark.parametrize('slope', [1.0, 10.0])
def test_a_level_answering_a_set_point_step_is_no_slip(lag_rows, slope):
    # A level's proxy is PV's smoothed slope, which reaches 3 rows further than
    # PV itself: a level that turns at once to a new set point, by a hundred
    # noise widths a row and more, shows its turn up to 10 rows before the
    # step's row, and must not be called a slip there.  (With no lag PV
    # moves at the step's own row, as a clock skew of a row can show it.)
    rng = np.random.default_rng(11)
    n, k = 600, 300
    sp = np.where(np.arange(n) < k, 50.0, 60.0)
    pv = 50.0 + 0.01 * rng.standard_normal(n)
    t = np.arange(n) - (k - 1 + lag_rows)
    pv += np.where(t > 0, slope * t, 0.0)
    op = 40.0 + 0.05 * rng.standard_normal(n)
    op[k:] += 4.0
    st = stuck_periods(op, pv, sp, integrating=True)
    assert not [s for s in st.slips if k - 15 <= s[0] <= k + 15], st.slips
    # The same turn with no set-point step is a slip.
    st = stuck_periods(op, pv, np.full(n, 50.0), integrating=True)
    assert [s for s in st.slips if k - 15 <= s[0] <= k + 15], st.slips
