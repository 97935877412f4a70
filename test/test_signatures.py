"""OP/PV-only stiction signatures on synthetic records whose answer is known."""

import json
import math

import numpy as np
import pytest

from stiction_ros.analysis.oscillation import detect_oscillation
from stiction_ros.analysis.signatures.all import compute_signatures
from stiction_ros.analysis.signatures.bicoherence import bicoherence, hos_with_pv_op
from stiction_ros.analysis.signatures.ellipse import (conic_to_matrix, ellipse, fit_ellipse,
                                                      geometry)
from stiction_ros.analysis.signatures.he_curve_fit import he_curve_fit
from stiction_ros.analysis.signatures.horch import horch
from stiction_ros.analysis.signatures.result import Signature
from stiction_ros.analysis.signatures.yamashita import yamashita
from stiction_ros.resources import config_file
from stiction_ros.sim.closed_loop import build_controller, build_plant, build_valve, simulate_loop
from stiction_ros.sim.loop_config import load_loop
from stiction_ros.sim.sources import triangle_wave
from stiction_ros.viz.signature_plots import signature_figure

LOOP = config_file('concentration_loop.yaml')
NOISE = {'noise': {'pv_std': 0.02, 'seed': 3}}
# Self-regulating FOPTD loop of the chapter's Table 2.1, sticky valve S = 5, J = 2.
STICKY = {}
# A fast integrating plant under PI: the sticky valve makes PV triangular.
INTEGRATING = {'plant.num': [0.1], 'plant.den': [1.0, 1.0, 0.0], 'plant.delay': 2.0,
               'controller.Kc': 1.0, 'controller.Ti': 100.0}
# Linear valve, gain just above the ultimate gain: a slowly growing linear oscillation.
AGGRESSIVE = {'valve': {'model': 'linear'}, 'controller.Kc': 0.72, 'controller.Ti': 100.0}
LINEAR = {'valve': {'model': 'linear'}}
# Sticky valve with an equal-percentage characteristic: an asymmetric limit cycle.
STICKY_EQP = {'valve': {'model': 'choudhury', 'S': 5.0, 'J': 2.0,
                        'characteristic': 'equal_percentage'}}


_RECORDS = {}


def loop(case, disturbance=(0.0, 1.0), duration=4000, discard=500):
    """
    Return a record of loop ``case`` at 1 s as a dict of arrays sp, op, pv (cached).

    ``disturbance`` = (amplitude, period s) of a sinusoid added to PV.
    """
    key = repr((sorted(case.items()), disturbance, duration, discard))
    if key not in _RECORDS:
        _RECORDS[key] = _run(case, disturbance, duration, discard)
    return _RECORDS[key]


def _run(case, disturbance, duration, discard):
    cfg = load_loop(LOOP, overrides={**case, **NOISE})
    amp, period = disturbance
    if amp == 0.0:
        d = simulate_loop(cfg, duration - 1)
        return {k: d[k][discard:] for k in ('sp', 'op', 'pv')}
    # simulate_loop has no additive PV disturbance, so step the same objects here.
    valve, plant = build_valve(cfg), build_plant(cfg)
    pid, sp_src, _ = build_controller(cfg)
    valve.reset(y0=plant.mv0)
    out = {k: np.empty(duration) for k in ('sp', 'op', 'pv')}
    for k in range(duration):
        pv = plant.output() + amp * math.sin(2 * math.pi * k / period)
        sp = sp_src(float(k))
        op = pid.update(sp, pv)
        plant.update(valve.step(op))
        out['sp'][k], out['op'][k], out['pv'][k] = sp, op, pv
    return {k: v[discard:] for k, v in out.items()}


# -- oscillation (Thornhill et al. 2003) --------------------------------------------------------

def test_noisy_sine_period_within_two_percent():
    t = np.arange(0, 3000, 0.5)
    rng = np.random.default_rng(0)
    x = 2.0 * np.sin(2 * np.pi * t / 73.0) + 0.5 * rng.standard_normal(t.size) + 0.01 * t
    osc = detect_oscillation(x, 0.5)
    assert osc.oscillating and osc.regularity > 10
    assert osc.period_s == pytest.approx(73.0, rel=0.02)
    assert osc.amplitude == pytest.approx(2.0, rel=0.05)
    assert osc.n_cycles == pytest.approx(3000 / 73.0, rel=0.02)
    json.dumps(osc.to_json(), allow_nan=False)


@pytest.mark.parametrize('seed', range(5))
def test_white_noise_is_not_a_regular_oscillation(seed):
    osc = detect_oscillation(np.random.default_rng(seed).standard_normal(4000), 1.0)
    assert not osc.oscillating and osc.regularity < 1.0


def test_noise_free_sine_gives_finite_json():
    t = np.arange(2000.0)
    osc = detect_oscillation(np.sin(2 * np.pi * t / 50.0), 1.0)
    assert osc.oscillating and osc.period_s == pytest.approx(50.0, rel=1e-3)
    json.dumps(osc.to_json(), allow_nan=False)


# -- Horch (1999) ------------------------------------------------------------------------------

@pytest.mark.parametrize('phi, verdict', [(0, False), (20, False), (45, None), (80, True),
                                          (90, True), (110, True), (130, None), (180, False)])
def test_horch_phase_of_sines(phi, verdict):
    # CCF = cos(w tau - phi): dphi = 2 phi for |phi| <= 90, 2 (180 - phi) beyond.
    t = np.arange(3000.0)
    th = 2 * np.pi * t / 60.0
    sig = horch(50 + 3 * np.cos(th), 2 * np.cos(th - math.radians(phi)), 1.0)
    assert sig.value == pytest.approx(2 * min(phi, 180 - phi), abs=2.0)
    assert sig.stiction is verdict


def test_horch_sticky_self_regulating_loop_is_stiction():
    d = loop(STICKY)
    sig = horch(d['op'], d['pv'], 1.0)
    assert sig.stiction is True, sig.reason
    assert abs(sig.details['ccf_at_lag0']) < 0.5 * sig.details['ccf_max_abs']


def test_horch_aggressive_linear_loop_is_not_stiction():
    d = loop(AGGRESSIVE)
    sig = horch(d['op'], d['pv'], 1.0)
    assert sig.stiction is False, sig.reason


def test_horch_external_sinusoidal_disturbance_is_not_stiction():
    d = loop(LINEAR, disturbance=(1.0, 30.0))
    sig = horch(d['op'], d['pv'], 1.0)
    assert sig.stiction is False, sig.reason


def test_horch_does_not_apply_to_integrating_loops():
    d = loop(INTEGRATING)
    sig = horch(d['op'], d['pv'], 1.0, integrating=True)
    assert sig.stiction is None and 'integrating' in sig.reason


# -- He et al. (2007) ---------------------------------------------------------------------------

def test_he_triangle_and_sine():
    t = np.arange(4000.0)
    tri = 3 * triangle_wave(2 * np.pi * t / 80.0) + 40
    sine = 3 * np.sin(2 * np.pi * t / 80.0) + 40
    s_tri = he_curve_fit(tri, tri, 1.0, period_s=80.0)
    s_sine = he_curve_fit(sine, sine, 1.0, period_s=80.0)
    assert s_tri.value > 0.9 and s_tri.stiction is True
    assert s_sine.value < 0.1 and s_sine.stiction is False
    assert s_tri.details['half_cycles'] >= 95


def test_he_uses_pv_when_integrating():
    t = np.arange(4000.0)
    tri = triangle_wave(2 * np.pi * t / 80.0)
    sine = np.sin(2 * np.pi * t / 80.0)
    assert he_curve_fit(sine, tri, 1.0, integrating=True).stiction is True
    assert he_curve_fit(sine, tri, 1.0, integrating=False).stiction is False


def test_he_sticky_self_regulating_loop_op_is_triangular():
    d = loop(STICKY)
    sig = he_curve_fit(d['op'], d['pv'], 1.0)
    assert sig.stiction is True, sig.reason


def test_he_sticky_integrating_loop_pv_is_triangular():
    d = loop(INTEGRATING)
    sig = he_curve_fit(d['op'], d['pv'], 1.0, integrating=True)
    assert sig.stiction is True, sig.reason


@pytest.mark.parametrize('case, disturbance', [(AGGRESSIVE, (0.0, 1.0)),
                                               (LINEAR, (1.0, 30.0))])
def test_he_linear_oscillations_are_sinusoidal(case, disturbance):
    d = loop(case, disturbance=disturbance)
    sig = he_curve_fit(d['op'], d['pv'], 1.0)
    assert sig.stiction is False, sig.reason


# -- bicoherence (Choudhury, Shah and Thornhill 2004) ---------------------------------------------

def test_gaussian_noise_is_not_nonlinear():
    sigs = [bicoherence(np.random.default_rng(s).standard_normal(4096), 1.0) for s in range(20)]
    flagged = sum(s.details['nonlinear'] for s in sigs)
    # The paper's test at alpha = 0.05 with its 0.001 margin; a few false alarms are expected.
    assert flagged <= 4
    assert np.mean([s.details['ngi'] for s in sigs]) < 0.0
    assert all(s.stiction is False for s in sigs if not s.details['nonlinear'])


def _three_tones(coupled, seed=0, n=4096):
    rng = np.random.default_rng(seed)
    t = np.arange(n)
    p1, p2 = rng.uniform(0, 2 * np.pi, 2)
    f1, f2 = 0.12, 0.19
    # The sum tone's phase either is locked to p1 + p2 or wanders (same spectrum, no coupling).
    p3 = p1 + p2 if coupled else np.cumsum(rng.normal(0.0, 0.3, n))
    return (np.cos(2 * np.pi * f1 * t + p1) + np.cos(2 * np.pi * f2 * t + p2)
            + 0.5 * np.cos(2 * np.pi * (f1 + f2) * t + p3) + 0.5 * rng.standard_normal(n))


def test_quadratic_phase_coupling_is_nonlinear():
    sig = bicoherence(_three_tones(coupled=True), 1.0)
    assert sig.details['nonlinear'] and sig.stiction is None
    assert sig.details['ngi'] > 0.001 and sig.value > 0.3
    f = sig.curves['freq_hz']
    i, j = np.unravel_index(np.nanargmax(sig.curves['bic2']), sig.curves['bic2'].shape)
    # The largest bicoherence sits at the coupled pair, within a bin of 1/128.
    assert sorted([f[i], f[j]]) == pytest.approx([0.12, 0.19], abs=1.0 / 128)


def test_same_spectrum_without_phase_coupling_is_not_nonlinear():
    sig = bicoherence(_three_tones(coupled=False), 1.0)
    assert not sig.details['nonlinear'] and sig.stiction is False


def test_hos_and_pv_op_map_find_an_asymmetric_sticky_loop():
    d = loop(STICKY_EQP)
    osc, sigs = compute_signatures(d['op'], d['pv'], d['sp'], 1.0)
    assert sigs['bicoherence'].details['nonlinear']
    assert sigs['hos_pv_op'].stiction is True, sigs['hos_pv_op'].reason


def test_hos_and_pv_op_map_clear_a_linear_loop_with_a_disturbance():
    d = loop(LINEAR, disturbance=(1.0, 30.0))
    osc, sigs = compute_signatures(d['op'], d['pv'], d['sp'], 1.0)
    assert not sigs['bicoherence'].details['nonlinear']
    assert sigs['hos_pv_op'].stiction is False


@pytest.mark.parametrize('nonlinear, width, verdict', [
    (True, 3.0, True), (True, 0.5, False), (False, 3.0, False), (True, None, None),
    (None, 3.0, None)])
def test_hos_with_pv_op_needs_both_nonlinearity_and_width(nonlinear, width, verdict):
    bic = Signature('bicoherence', 0.1, 0.01, None, 'r', 'ref',
                    {} if nonlinear is None else {'nonlinear': nonlinear, 'ngi': 0.0, 'nli': 0.1})
    ell = Signature('ellipse', width, 1.0, None, 'r', 'ref')
    assert hos_with_pv_op(bic, ell).stiction is verdict


# -- PV-OP ellipse (Choudhury et al. 2006) --------------------------------------------------------

@pytest.mark.parametrize('a, b, phi', [(3.0, 0.5, 30.0), (3.0, 50.0, 100.0), (1.0, 2.0, 60.0),
                                       (5.0, 1.0, 170.0)])
def test_ellipse_width_of_phase_shifted_sines(a, b, phi):
    # OP = A cos t, PV = B cos(t - phi): at the PV centre OP = -+A sin phi, width 2 A |sin phi|.
    t = np.arange(3000.0)
    th = 2 * np.pi * t / 61.3
    sig = ellipse(50 + a * np.cos(th), 7 + b * np.cos(th - math.radians(phi)), 1.0,
                  period_s=61.3)
    assert sig.value == pytest.approx(2 * a * abs(math.sin(math.radians(phi))), rel=0.01)
    assert sig.details['op_extent'] == pytest.approx(2 * a, rel=0.01)
    assert sig.details['centre_op'] == pytest.approx(50.0, abs=0.05)
    assert sig.stiction is None


def test_ellipse_width_with_noise_and_unknown_period():
    t = np.arange(4000.0)
    th = 2 * np.pi * t / 61.3
    rng = np.random.default_rng(4)
    op = 50 + 3 * np.cos(th) + 0.3 * rng.standard_normal(t.size)
    pv = 7 + 0.5 * np.cos(th - 1.0) + 0.05 * rng.standard_normal(t.size)
    sig = ellipse(op, pv, 1.0)
    assert sig.value == pytest.approx(6 * math.sin(1.0), rel=0.05)


def test_ellipse_in_phase_map_has_no_width():
    t = np.arange(3000.0)
    th = 2 * np.pi * t / 61.3
    assert ellipse(np.cos(th), 2 * np.cos(th), 1.0, 61.3).stiction is False
    thin = ellipse(np.cos(th), 2 * np.cos(th - math.radians(4.0)), 1.0, 61.3)
    assert thin.stiction is False and thin.value < thin.threshold


def test_ellipse_integrating_uses_the_pv_rate():
    t = np.arange(3000.0)
    w = 2 * np.pi / 61.3
    phi = math.radians(40.0)
    # PV integrates B cos(t - phi), so dPV/dt is that cosine again.
    pv = 2.0 * np.sin(w * t - phi) / w
    sig = ellipse(3 * np.cos(w * t), pv, 1.0, 61.3, integrating=True)
    assert sig.value == pytest.approx(6 * math.sin(phi), rel=0.01)


def test_fit_ellipse_recovers_a_rotated_ellipse():
    s = np.linspace(0, 2 * np.pi, 50, endpoint=False)
    m, n, ang = 4.0, 1.5, math.radians(25.0)
    x = 2 + m * np.cos(s) * math.cos(ang) - n * np.sin(s) * math.sin(ang)
    y = -1 + m * np.cos(s) * math.sin(ang) + n * np.sin(s) * math.cos(ang)
    centre, q = conic_to_matrix(fit_ellipse(x, y))
    major, minor, angle = geometry(q)
    assert centre == pytest.approx([2.0, -1.0], abs=1e-8)
    assert sorted([major, minor]) == pytest.approx([n, m], rel=1e-8)
    # The paper's width formula through the centre, along x.
    width = 2 * m * n / math.sqrt(m ** 2 * math.sin(ang) ** 2 + n ** 2 * math.cos(ang) ** 2)
    assert 2 / math.sqrt(q[0, 0]) == pytest.approx(width, rel=1e-8)


# -- all signatures together, and the figure -----------------------------------------------------

def test_compute_signatures_on_a_sticky_loop(tmp_path):
    d = loop(STICKY)
    osc, sigs = compute_signatures(d['op'], d['pv'], d['sp'], 1.0)
    assert osc.oscillating and osc.period_s == pytest.approx(144, rel=0.05)
    assert list(sigs) == ['horch', 'he_curve_fit', 'bicoherence', 'ellipse', 'hos_pv_op',
                          'yamashita', 'slip_events']
    assert sigs['horch'].stiction is True and sigs['he_curve_fit'].stiction is True
    assert sigs['ellipse'].value > sigs['ellipse'].threshold
    json.dumps({k: s.to_json() for k, s in sigs.items()}, allow_nan=False)
    png = tmp_path / 'signatures.png'
    signature_figure(d['op'], d['pv'], 1.0, sigs, png)
    assert png.read_bytes()[:8] == b'\x89PNG\r\n\x1a\n' and png.stat().st_size > 20000


def test_without_oscillation_the_signatures_abstain():
    rng = np.random.default_rng(5)
    pv = rng.standard_normal(3000)
    op = 50 - 0.5 * pv + 0.1 * rng.standard_normal(3000)
    osc, sigs = compute_signatures(op, pv, 0.0, 1.0)
    assert not osc.oscillating
    for name in ('horch', 'he_curve_fit', 'ellipse', 'hos_pv_op'):
        assert sigs[name].stiction is None
        assert sigs[name].reason.startswith('no regular oscillation')
    assert sigs['bicoherence'].value is not None


def test_integrating_loop_through_compute_signatures():
    d = loop(INTEGRATING)
    osc, sigs = compute_signatures(d['op'], d['pv'], d['sp'], 1.0, integrating=True)
    assert osc.oscillating
    assert sigs['horch'].stiction is None
    assert sigs['he_curve_fit'].stiction is True
    assert sigs['he_curve_fit'].details['signal'] == 'pv'
    assert sigs['ellipse'].details['pv_signal'] == 'dPV/dt'


# -- Yamashita (2006) qualitative shapes ----------------------------------------------------------

@pytest.mark.parametrize('case, integrating', [(STICKY, False), (INTEGRATING, True)])
def test_yamashita_sticky_loop_moves_op_while_the_valve_stays(case, integrating):
    d = loop(case)
    sig = yamashita(d['op'], d['pv'], 1.0, integrating=integrating)
    assert sig.stiction is True and sig.value > 0.5, sig.reason


@pytest.mark.parametrize('case, disturbance', [(AGGRESSIVE, (0.0, 1.0)),
                                               (LINEAR, (1.0, 30.0))])
def test_yamashita_linear_valve_never_leaves_op_moving_alone(case, disturbance):
    d = loop(case, disturbance=disturbance)
    sig = yamashita(d['op'], d['pv'], 1.0)
    assert sig.stiction is False and sig.value <= 0.25, sig.reason


def test_yamashita_noise_alone_is_not_informative():
    rng = np.random.default_rng(4)
    sig = yamashita(rng.normal(50, 0.01, 2000), rng.normal(0, 0.01, 2000), 1.0)
    assert sig.stiction is not True


def test_the_figure_reads_in_words_on_the_records_clock():
    from stiction_ros.viz.signature_plots import headline, signature_panels
    d = loop(STICKY)
    _, sigs = compute_signatures(d['op'], d['pv'], d['sp'], 1.0)
    assert '\u00b0 (stiction \u2265 ' in headline(sigs['horch'])
    # The stretch read starts 500 s into the record: the time axes say so.
    fig = signature_panels(d['op'], d['pv'], 1.0, sigs, t0=500.0)
    titles = [ax.get_title() for ax in fig.axes]
    slips = fig.axes[[t.startswith('slip_events') for t in titles].index(True)]
    x = slips.get_lines()[0].get_xdata()
    assert x[0] == 500.0 and x[-1] == 500.0 + len(d['pv']) - 1
    he = fig.axes[[t.startswith('he_curve_fit') for t in titles].index(True)]
    assert he.get_lines()[0].get_xdata()[-1] > 500.0
    # Half-cycles the fit skipped are left open: the fitted lines carry breaks, no chords.
    from stiction_ros.viz.signature_plots import _broken
    t, y = _broken(np.array([0.0, 1.0, 2.0, 9.0, 10.0]), np.arange(5.0), step=1.0)
    assert np.array_equal(np.isnan(t), [False, False, False, True, False, False])
    assert np.isnan(y[3]) and y[4] == 3.0
    # Signatures without curves share one panel that names each.
    text = [ax for ax in fig.axes if ax.get_title() == 'signatures without a picture']
    assert len(text) == 1 and 'hos_pv_op' in text[0].texts[0].get_text()
