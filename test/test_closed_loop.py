"""The offline loop: Table 2.1 behaviour, config errors that name the key, the CLI."""

from pathlib import Path

import numpy as np
import pytest

from stiction_ros.analysis.measures.limit_cycle import measure_oscillation
from stiction_ros.cli import sim
from stiction_ros.models import Linear
from stiction_ros.sim.closed_loop import build_valve, simulate_loop
from stiction_ros.sim.loop_config import ConfigError, load_loop
from stiction_ros.study.describing_function import predict_limit_cycle, valve_describing_function

CONFIG = Path(__file__).resolve().parents[1] / 'config' / 'concentration_loop.yaml'


def run(case=None, **overrides):
    return simulate_loop(load_loop(CONFIG, case, overrides))


def test_healthy_valve_settles_on_the_setpoint():
    d = run(**{'valve': {'model': 'linear'}})
    assert abs(d['pv'][-1] - d['sp'][-1]) < 1e-6
    assert not measure_oscillation(d['op'], 1.0).oscillating


@pytest.mark.parametrize('case', ['undershoot', 'no_offset', 'overshoot'])
def test_stiction_cases_give_a_limit_cycle_and_pv_averages_to_setpoint(case):
    d = run(case)
    osc = measure_oscillation(d['op'], 1.0)
    assert osc.oscillating and osc.regularity > 3
    # integral action: the mean PV over whole cycles sits at the set point
    pv = d['pv'][1000:]
    assert abs(pv.mean() - 1.0) < 0.2 * np.ptp(pv)


def test_limit_cycle_is_faster_and_larger_as_the_slip_jump_grows():
    periods, amps = [], []
    for case in ('undershoot', 'no_offset', 'overshoot'):
        osc = measure_oscillation(run(case)['pv'], 1.0)
        periods.append(osc.period)
        amps.append(osc.amplitude)
    assert periods[0] > periods[1] > periods[2]
    assert amps[0] < amps[1] < amps[2]


def test_kano_and_choudhury_give_the_same_closed_loop():
    a = run('undershoot', **{'valve.model': 'kano'})
    b = run('undershoot', **{'valve.model': 'choudhury'})
    np.testing.assert_allclose(a['mv'], b['mv'], atol=1e-9)


def test_describing_function_of_ideal_valve_is_one_and_predicts_no_cycle():
    assert valve_describing_function(Linear(), 5.0) == pytest.approx(1.0, abs=1e-9)
    cfg = load_loop(CONFIG, None, {'valve': {'model': 'linear'}})
    assert predict_limit_cycle(cfg, build_valve(cfg), n_amplitudes=20) == []


def test_describing_function_and_simulation_agree_on_the_no_offset_case():
    cfg = load_loop(CONFIG, 'no_offset')
    pred = predict_limit_cycle(cfg, build_valve(cfg), n_amplitudes=60)
    assert len(pred) == 1
    osc = measure_oscillation(simulate_loop(cfg)['op'], 1.0)
    # harmonic balance assumes a sinusoidal valve input; OP is triangular, so
    # only rough agreement is expected (see docs/REPRODUCTION.md)
    assert pred[0]['period'] == pytest.approx(osc.period, rel=0.25)
    assert pred[0]['amplitude'] == pytest.approx(osc.amplitude, rel=0.3)


def test_open_loop_source_drives_the_valve():
    d = run(None, **{'controller.mode': 'open_loop', 'duration': 400.0,
                     'controller.op': {'type': 'sine', 'offset': 50, 'amplitude': 10,
                                       'period': 200}})
    assert d['op'].max() == pytest.approx(60.0, abs=0.01)
    assert np.ptp(d['mv']) > 10.0  # it moves, with stiction, around the sine


HIDDEN = Path(__file__).resolve().parents[1] / 'config' / 'hidden_effect_loop.yaml'


@pytest.mark.parametrize('config, overrides', [
    (CONFIG, {'valve': {'model': 'choudhury', 'S': 5.0, 'J': 2.0}}),
    (CONFIG, {'valve': {'model': 'kano', 'S': 5.0, 'J': 7.0, 'tau': 2.0}}),
    (CONFIG, {'valve': {'model': 'he', 'S': 4.0, 'J': 1.0}}),
    (CONFIG, {'valve': {'model': 'stenman', 'S': 3.0}}),
    (CONFIG, {'valve': {'model': 'linear'}}),
    (CONFIG, {'valve': {'model': 'physical'}}),
    (CONFIG, {'valve': {'model': 'physical', 'integrator': 'substep', 'substep': 0.002}}),
    (HIDDEN, {}),
    # A second-order plant with a fractional dead time, a disturbance, derivative action
    # on direct-acting control, and an integrating plant.
    (CONFIG, {'plant': {'num': [1.0, 2.0], 'den': [20.0, 9.0, 1.0], 'delay': 2.5,
                        'mv0': 50.0, 'disturbance_steps': [[300.0, -0.4], [900.0, 0.3]]},
              'controller': {'Kc': -0.5, 'Ti': 15.0, 'Td': 2.0, 'action': 'direct',
                             'setpoint': {'type': 'sine', 'offset': 0.0, 'amplitude': 1.0,
                                          'period': 400.0}}}),
    (CONFIG, {'plant': {'num': [0.05], 'den': [1.0, 0.0], 'delay': 0.0, 'mv0': 50.0},
              'controller': {'Kc': 2.0, 'Ti': 0.0,
                             'setpoint': {'type': 'sine', 'offset': 0.0, 'amplitude': 4.0,
                                          'period': 300.0}}}),
    (CONFIG, {'controller': {'mode': 'open_loop',
                             'op': {'type': 'triangle', 'offset': 50, 'amplitude': 10,
                                    'period': 250}}}),
])
def test_compiled_loop_is_the_python_loop_sample_for_sample(config, overrides):
    """
    The compiled loop (loop_kernel) and the per-sample Python loop give the same bits.

    Same arithmetic in the same order, the same valve kernels and the same noise
    stream: any difference (a breakaway one sample early) would show in every
    column from there on, so equality is required, not closeness.
    """
    cfg = load_loop(config, None, {'duration': 1500.0, 'noise': {'pv_std': 0.05, 'seed': 4},
                                   **overrides})
    progress = []
    fast = simulate_loop(cfg, progress=lambda k, n: progress.append(k))
    ref = simulate_loop(cfg, compiled=False)
    assert np.ptp(ref['mv']) > 0.2
    for key in ref:
        assert np.array_equal(fast[key], ref[key]), key
    assert progress[-1] == len(ref['t']) and progress == sorted(progress)


@pytest.mark.parametrize('overrides,match', [
    ({'valve.SS': 3}, "valve.SS: unknown key; did you mean 'S'"),
    ({'controller.setpont': 3}, "did you mean 'setpoint'"),
    ({'valve.model': 'kanno'}, "did you mean 'kano'"),
    ({'sample_time': 0}, 'sample_time: must be a positive'),
    ({'controller.mode': 'open_loop'}, 'controller.op: missing'),
    # Caught when the file is loaded, not when the run reaches them:
    ({'plant.den': [1.0, -1.0]}, r'plant.den has poles \[1.0\].*unstable'),
    ({'plant.num': [1.0, 2.0, 3.0]}, 'plant is not proper.*add poles or remove zeros'),
    ({'plant.delay': -1}, r'plant.delay = -1.0 is outside \[0.0'),
    ({'valve': {'model': 'physical', 'Fs': 100.0, 'Fc': 700.0}},
     'valve: physical: static friction Fs = 100.0 N is below Coulomb friction'),
    ({'controller.op_min': 100.0}, r'controller.op_min \(100.0\) must be below op_max'),
])
def test_config_errors_name_the_key_and_the_fix(overrides, match):
    with pytest.raises(ConfigError, match=match):
        load_loop(CONFIG, None, overrides)


@pytest.mark.parametrize('model', ['stenman', 'linear', 'physical', 'kano'])
def test_a_model_set_on_the_command_line_drops_the_files_keys_it_lacks(model):
    from stiction_ros.models import MODELS
    cfg = load_loop(CONFIG, 'undershoot', {'valve.model': model})
    assert cfg['valve']['model'] == model
    assert set(cfg['valve']) <= set(MODELS[model].PARAMS) | {'model'}
    # A key given on the command line is kept, so a wrong one is still named.
    with pytest.raises(ConfigError, match='valve.J: unknown key'):
        load_loop(CONFIG, 'undershoot', {'valve.model': 'stenman', 'valve.J': 2.0})
    # A model set in the file's own mapping keeps the file's rule: every key is checked.
    with pytest.raises(ConfigError, match='unknown key'):
        load_loop(CONFIG, 'undershoot', {'valve': {'model': 'stenman', 'S': 5.0, 'J': 1.0}})


def test_cli_writes_csv_and_reports_errors_in_one_line(tmp_path, capsys):
    out = tmp_path / 'x.csv'
    assert sim.main([str(CONFIG), '--case', 'overshoot', '--duration', '50', '-o', str(out),
                     '--quiet']) == 0
    data = np.genfromtxt(out, delimiter=',', names=True)
    assert data.dtype.names == ('t', 'sp', 'op', 'mv', 'pv') and len(data) == 51
    assert sim.main([str(CONFIG), '--set', 'plant.den=[1, -1]']) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and 'unstable' in err[0]
