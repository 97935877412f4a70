"""
Gaps in a record: a short one costs the valve fits its own samples and almost nothing else.

The record is the closed loop of test_analyze_cli (Kano, S 3.47 %, J 1.23 %,
600 s, noisy OP and MV) with 32 samples blanked in MV alone, or in OP and MV
together.  Every expectation compares the record with the same record
without the gap, both analysed here; none is a number the fits once gave.
A gap in MV alone leaves OP, the valve's input, so the model runs on through
it; a gap in OP too restarts the model from the state that fits best
(``stiction_ros.analysis.fit_core``).
"""

from fit_reference import first_rest, reference_output
import numpy as np
import pytest

from stiction_ros.analysis.fit_core import carried_runs
from stiction_ros.analysis.identify import identify, ValveProblem
from stiction_ros.analysis.mismatch.explain import model_output
from stiction_ros.analysis.pipeline import fit_models, Options
from stiction_ros.analysis.record import assemble
from stiction_ros.app.analyze import analyze_file, AnalyzeOptions
from stiction_ros.kernels import kano_effects as kk
from stiction_ros.kernels.sse import kano_output
from stiction_ros.kernels.valve_starts import restart_position, RESTART_SAMPLES
from stiction_ros.resources import config_file
from stiction_ros.sim.closed_loop import simulate_loop
from stiction_ros.sim.loop_config import load_loop

GAP = 32
# Where the gaps start: early, in the middle (the record of the bug) and late.
STARTS = (150, 300, 450)
BLANKED = {'mv': ('mv',), 'op and mv': ('op', 'mv')}
# 0.1 % of span, the identification tests' tolerance; the grid step is 0.01 %.
TOLERANCE = 0.1


@pytest.fixture(scope='module')
def loop():
    cfg = load_loop(config_file('concentration_loop.yaml'), overrides={
        'valve': {'model': 'kano', 'S': 3.47, 'J': 1.23},
        'noise': {'pv_std': 0.02, 'mv_std': 0.1, 'seed': 1}, 'duration': 600.0})
    return simulate_loop(cfg)


def record(data, blank=(), start=300):
    signals = {k: np.array(data[k], dtype=np.float64) for k in ('op', 'mv', 'pv', 'sp')}
    for name in blank:
        signals[name][start:start + GAP] = np.nan
    return assemble(signals, 1.0)


@pytest.fixture(scope='module')
def whole(loop):
    return fit_models(record(loop), Options(model='both'))[0]


@pytest.mark.parametrize('start', STARTS)
@pytest.mark.parametrize('blank', BLANKED)
def test_a_gap_of_32_samples_leaves_S_and_J_and_the_error_as_without_it(
        loop, whole, blank, start):
    rec = record(loop, BLANKED[blank], start)
    assert len(rec.valve_segments()) == 2
    fits = fit_models(rec, Options(model='both'))[0]
    for fit, ref in zip(fits, whole):
        assert fit.samples == ref.samples - GAP
        assert abs(fit.S - ref.S) <= TOLERANCE and abs(fit.J - ref.J) <= TOLERANCE, (
            fit.model, (fit.S, fit.J), (ref.S, ref.J))
        # The fit still leaves the MV noise and little else (restarting the model at
        # rest after the gap left it stuck there: 16 times the error).
        assert fit.mse < 1.5 * ref.mse, (fit.model, fit.mse, ref.mse)


def test_the_fits_run_through_a_gap_in_mv_alone_as_through_no_gap(loop):
    # With OP known, a gap after the valve's first move changes only which samples
    # are scored: scoring the gap-free record on the same samples gives the same sums
    # (within the first rest it also moves the rest's best start, test_identify).
    rec = record(loop, ('mv',))
    segs = rec.valve_segments()
    op, mv = np.asarray(loop['op'], dtype=np.float64), np.asarray(loop['mv'], dtype=np.float64)
    for model in ('kano', 'choudhury'):
        gapped = ValveProblem(model, rec.signals['op'], rec.signals['mv'], segs)
        full = ValveProblem(model, op, mv)
        s, j = np.linspace(2.0, 5.0, 7), np.linspace(0.0, 2.5, 6)
        pred = full.output(3.47, 1.23)
        scored = np.zeros(len(op), dtype=bool)
        for a, b in segs:
            scored[a:b] = True
        direct = np.sum((pred[scored] - mv[scored]) ** 2)
        assert np.isclose(gapped.grid([3.47], [1.23])[0, 0], direct, rtol=1e-12)
        assert np.all(gapped.grid(s, j) <= full.grid(s, j))


def test_the_prediction_is_what_the_fit_scored_after_a_gap_in_op(loop):
    rec = record(loop, ('op', 'mv'))
    segs = rec.valve_segments()
    op, mv = rec.signals['op'], rec.signals['mv']
    for model in ('kano', 'choudhury'):
        problem = ValveProblem(model, op, mv, segs)
        pred = problem.output(3.47, 1.23)
        assert np.array_equal(np.isfinite(pred), rec.valid)
        r = (pred - mv)[rec.valid]
        assert np.isclose(problem.mse(3.47, 1.23), float(r @ r) / problem.n, rtol=1e-12)
    # The effects kernel too: its output is what its SSE sums.
    starts = np.array([a for a, _ in segs])
    stops = np.array([b for _, b in segs])
    out, _ = model_output(op, mv, segs, 3.47, 1.23, kk.plain_params())
    y0s = np.array([np.median(mv[a:a + 10]) for a in starts])
    sse = kk.kano_effects_sse(op, mv, starts, stops, y0s, 3.47, 1.23, kk.plain_params(),
                              np.inf)
    r = (out - mv)[rec.valid]
    assert np.isclose(sse, float(r @ r), rtol=1e-12)


def test_a_record_without_gaps_fits_as_the_models_run_it(loop):
    # The restarts are for gaps: a record without one starts the valve at rest where
    # its first rest fits best, as the models' own simulate runs from there, and its
    # S, J and MSE are those of the plain search.
    rec = record(loop)
    assert rec.valve_segments() == [(0, len(loop['op']))]
    op, mv = rec.signals['op'], rec.signals['mv']
    for fit in fit_models(rec, Options(model='both'))[0]:
        plain = identify(op, mv, fit.model)
        assert (fit.S, fit.J, fit.mse) == (plain.S, plain.J, plain.mse)
        pos = reference_output(fit.model, op, mv, fit.S, fit.J)
        assert fit.mse == pytest.approx(float(np.mean((pos - mv) ** 2)), rel=1e-12)
        out = ValveProblem(fit.model, op, mv).output(fit.S, fit.J)
        assert np.allclose(out, pos, rtol=0.0, atol=1e-12)
        k = first_rest(fit.model, op, fit.S, fit.J)
        # after the first move the start is forgotten: to the bit
        assert np.array_equal(out[k:], pos[k:]) and 0 < k < len(op)
    k = first_rest('kano', op, 3.47, 1.23)
    assert np.array_equal(kano_output(op, mv[0], 3.47, 1.23, 0.0)[k:],
                          ValveProblem('kano', op, mv).output(3.47, 1.23)[k:])


def test_carried_runs_join_segments_only_across_known_input():
    x = np.arange(20.0)
    x[12] = np.nan
    assert carried_runs([(0, 5), (8, 10), (14, 20)], x) == [(0, 10), (14, 20)]
    assert carried_runs([], x) == []


@pytest.fixture(scope='module')
def explained(loop, tmp_path_factory):
    d = tmp_path_factory.mktemp('gaps')
    rows = np.column_stack([loop[c] for c in ('t', 'sp', 'op', 'mv', 'pv')])
    out = {}
    for name, blank in (('none', ()), *BLANKED.items()):
        lines = ['t,sp,op,mv,pv']
        for k, row in enumerate(rows):
            cells = [f'{v:.10g}' for v in row]
            if 300 <= k < 300 + GAP:
                for col in blank:
                    cells[('t', 'sp', 'op', 'mv', 'pv').index(col)] = ''
            lines.append(','.join(cells))
        path = d / f'{name.replace(" ", "_")}.csv'
        path.write_text('\n'.join(lines) + '\n')
        out[name] = analyze_file(AnalyzeOptions(str(path), model='kano', explain=True)).report
    return out


@pytest.mark.parametrize('blank', BLANKED)
@pytest.mark.slow
def test_explain_names_no_dead_time_for_a_gap(explained, blank):
    ref, rep = explained['none'], explained[blank]
    assert rep['excluded'] and not ref['excluded']
    m, m_ref = rep['mismatch'], ref['mismatch']
    # The answer is the gap-free record's: stiction, nothing missing from Kano's model.
    assert (m['effect'], m['friction'], m['friction_kind']) == (
        m_ref['effect'], m_ref['friction'], m_ref['friction_kind'])
    assert m['friction_kind'] == 'stiction'
    ids = [e['id'] for e in m.get('effects', [])]
    assert 'dead_time' not in ids, ids
    assert 'delay' not in m['model']['params']
    fit, fit_ref = rep['fits'][0], ref['fits'][0]
    assert abs(fit['S'] - fit_ref['S']) <= TOLERANCE and abs(fit['J'] - fit_ref['J']) <= TOLERANCE


def test_the_stuck_restart_sits_at_the_median_of_its_first_samples():
    rng = np.random.default_rng(11)
    for _ in range(300):
        n = int(rng.integers(1, 3 * RESTART_SAMPLES))
        y = np.round(rng.normal(50.0, 2.0, n), int(rng.integers(0, 4)))
        i0 = int(rng.integers(0, n))
        i1 = int(rng.integers(i0 + 1, n + 1))
        want = float(np.median(y[i0:min(i1, i0 + RESTART_SAMPLES)]))
        assert restart_position(y, i0, i1, 0) == want
        assert restart_position(y, i0, i1, 1) == y[i0]
