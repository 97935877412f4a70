"""The detector's 1-D CNN: NumPy layers against naive loops, invariances, its file, its reach."""

import json

import numpy as np
import pytest

from stiction_ros.analysis.detection import cnn, dataset
from stiction_ros.errors import DetectorFileError


def naive_conv(x, w, b, d):
    c_out, c_in, k = w.shape
    pad = d * (k - 1) // 2
    n = x.shape[1]
    out = np.zeros((c_out, n))
    for o in range(c_out):
        for t in range(n):
            acc = float(b[o])
            for i in range(c_in):
                for j in range(k):
                    s = t + j * d - pad
                    if 0 <= s < n:
                        acc += float(w[o, i, j]) * float(x[i, s])
            out[o, t] = acc
    return out


@pytest.mark.parametrize('conv', [cnn.conv1d, cnn.conv1d_reference])
@pytest.mark.parametrize('k,d', [(5, 1), (5, 3), (7, 1), (3, 8)])
def test_the_dilated_convolution_equals_a_loop_over_taps(k, d, conv):
    rng = np.random.default_rng(k * 10 + d)
    x = rng.normal(size=(3, 40))
    w, b = rng.normal(size=(4, 3, k)), rng.normal(size=4)
    np.testing.assert_allclose(conv(x, w, b, d), naive_conv(x, w, b, d), atol=1e-10)


def test_the_compiled_convolution_gives_einsums_bits():
    # Same bits, not merely close: the cached figures of the study and the
    # calibration map were computed with einsum.  Channel counts on both sides
    # of a multiple of four, taps 1-7, dilations up to the network's largest.
    rng = np.random.default_rng(11)
    for _ in range(40):
        c_in, c_out = (int(v) for v in rng.integers(1, 70, size=2))
        k, d = int(rng.choice([1, 3, 5, 7])), int(rng.choice([1, 2, 8, 64, 1024]))
        # From 2 samples: with one, einsum sums the channels with SIMD (kernels/conv.py).
        x = rng.normal(size=(c_in, int(rng.integers(2, 1200))))
        x[rng.random(x.shape) < 0.1] = 0.0
        w = rng.normal(size=(c_out, c_in, k)).astype(np.float32).astype(np.float64)
        b = rng.normal(size=c_out)
        got = cnn.conv1d(x, w, b, d)
        assert got.shape == (c_out, x.shape[1])
        assert got.tobytes() == cnn.conv1d_reference(x, w, b, d).tobytes()   # -0.0 too


def test_a_convolution_of_the_wrong_shape_is_refused_not_read_past_its_end():
    x, b = np.ones((3, 50)), np.zeros(4)
    for w in (np.ones((4, 3, 4)), np.ones((4, 2, 5)), np.ones((4, 3))):
        with pytest.raises(ValueError, match='odd k'):
            cnn.conv1d(x, w, b, 2)
    with pytest.raises(ValueError, match='odd k'):
        cnn.conv1d(x, np.ones((4, 3, 5)), np.zeros(3), 2)


@pytest.mark.parametrize('path', [None, 'large'])
def test_both_shipped_networks_give_the_same_logit_with_either_convolution(path):
    from stiction_ros.analysis.detection import stack
    net = cnn._shipped(str(stack.LARGE_PATH) if path else None)
    rng = np.random.default_rng(6)
    op = 50 + np.cumsum(rng.normal(size=900)) * 0.3
    x = cnn.channels(op, np.convolve(op, np.full(15, 1 / 15))[:900], None)
    for integrating in (False, True):
        assert (cnn.symmetric_logit(net, x, integrating)
                == cnn.symmetric_logit(net, x, integrating, cnn.conv1d_reference))


def test_the_input_does_not_see_units_offsets_or_the_set_points_own_scale():
    rng = np.random.default_rng(1)
    op = 50 + np.cumsum(rng.normal(size=600)) * 0.1
    pv = np.cumsum(rng.normal(size=600)) * 0.2
    sp = np.where(np.arange(600) > 300, 1.0, 0.0)
    ref = cnn.channels(op, pv, sp)
    # PV and SP in other units (t/h instead of %, an offset), OP in other units.
    moved = cnn.channels(3.0 * op - 7.0, 250.0 * pv + 1e4, 250.0 * sp + 1e4)
    np.testing.assert_allclose(moved, ref, atol=2e-5)
    assert ref.shape == (cnn.N_CHANNELS, 600) and ref.dtype == np.float32
    assert np.abs(cnn.channels(op, pv, sp * 1e9)).max() <= cnn.CLIP


@pytest.mark.parametrize('path', [None, 'large'])
def test_the_logit_does_not_depend_on_the_loops_sign_conventions(path):
    from stiction_ros.analysis.detection import stack
    path = str(stack.LARGE_PATH) if path else None
    rng = np.random.default_rng(4)
    op = 40 + np.cumsum(rng.normal(size=700)) * 0.2
    pv = 3.0 + np.cumsum(rng.normal(size=700)) * 0.05
    sp = np.where(np.arange(700) > 350, 3.5, 3.0)
    ref = cnn.cnn_logit(op, pv, sp, False, path)
    # A transmitter ranged the other way, an air-to-close valve, both: one loop.
    for o, p, s in [(op, -pv, -sp), (100.0 - op, pv, sp), (100.0 - op, -pv, -sp)]:
        assert cnn.cnn_logit(o, p, s, False, path) == pytest.approx(ref, abs=1e-9)
    # The network alone does tell the four apart: the mean is what makes them one.
    net, x = cnn._shipped(path), cnn.channels(op, pv, sp)
    one = [net.logit(x * np.array([a, a, b, a, b], np.float32)[:, None], False)
           for a, b in cnn.SIGNS]
    assert np.ptp(one) > 1e-3 and ref == pytest.approx(np.mean(one), abs=1e-12)


def test_the_shipped_network_never_saw_a_seed_the_detector_trains_calibrates_or_scores_on():
    from stiction_ros.analysis.detection.cnn_train import CORPUS
    model = cnn.load()
    lo, hi = model.meta['corpus_seeds']
    # What make cnn would draw now is what the shipped network was drawn from.
    assert (lo, hi) == (CORPUS.start, CORPUS.stop)
    for r in (dataset.TRAIN, dataset.CALIBRATION, dataset.TEST):
        assert hi <= r.start or lo >= r.stop, r
    assert model.meta['figures']['max_abs_export_error'] < 1e-3


def test_any_record_length_gives_a_finite_logit():
    rng = np.random.default_rng(2)
    for n in (200, 751, 20_000):
        op = np.cumsum(rng.normal(size=n))
        pv = op + rng.normal(size=n)
        assert np.isfinite(cnn.cnn_logit(op, pv, None, False))


def _auc(score, y):
    ranks = np.argsort(np.argsort(score)) + 1.0
    pos = y.sum()
    return (ranks[y].sum() - pos * (pos + 1) / 2) / (pos * (len(y) - pos))


def test_it_ranks_sticky_loops_above_healthy_ones_on_seeds_no_set_uses():
    from stiction_ros.analysis.detection.cnn_train import _record
    logits, labels = [], []
    for seed in range(2_900_000, 2_900_160):   # beyond every corpus, set and scoring range
        r = _record(seed)
        if r is not None:
            logits.append(cnn.load().logit(r[1], r[3]))
            labels.append(r[2])
    y = np.array(labels)
    assert 20 <= y.sum() <= len(y) - 20
    # Training and the calibration check gave AUCs of 0.92; a random ranking 0.5.
    assert _auc(np.array(logits), y) > 0.75


def _copy(tmp_path, change=None):
    with np.load(cnn.DEFAULT_PATH) as z:
        a = {k: z[k] for k in z.files}
    if change:
        change(a)
    p = tmp_path / 'net.npz'
    np.savez(p, **a)
    return p


def test_a_missing_damaged_or_edited_file_is_a_clear_error(tmp_path):
    with pytest.raises(DetectorFileError, match='no CNN model file.*make cnn'):
        cnn.load(tmp_path / 'absent.npz')
    cut = tmp_path / 'cut.npz'
    cut.write_bytes(cnn.DEFAULT_PATH.read_bytes()[:5000])
    with pytest.raises(DetectorFileError, match='not a readable CNN file'):
        cnn.load(cut)

    def edit(a):
        a['fc2_b'] = a['fc2_b'] + np.float32(1.0)
    with pytest.raises(DetectorFileError, match='checksum'):
        cnn.load(_copy(tmp_path, edit))

    def drop(a):
        del a['conv_w']
    with pytest.raises(DetectorFileError, match='missing arrays'):
        cnn.load(_copy(tmp_path, drop))


def test_weights_that_do_not_fit_together_are_refused_even_with_a_good_checksum(tmp_path):
    with np.load(cnn.DEFAULT_PATH) as z:
        a = {k: z[k] for k in cnn.ARRAYS}
        header = str(z['header'])
    a['fc1_w'] = a['fc1_w'][:, :-1]
    meta = json.loads(header)['meta']
    p = tmp_path / 'bad.npz'
    cnn.save(p, a, meta)
    with pytest.raises(DetectorFileError, match='fc1_w has shape'):
        cnn.load(p)


def test_the_training_command_refuses_a_corpus_too_small_to_learn_from(capsys):
    from stiction_ros.cli.cnn import main
    assert main(['--seeds', '10', '--out', '/nonexistent/x.npz']) == 2
    assert 'at least 200 seeds' in capsys.readouterr().err


def test_numpy_gives_the_logit_pytorch_gives_for_the_same_weights():
    torch = pytest.importorskip('torch')   # requirements/train.txt; CI runs without it
    from stiction_ros.analysis.detection.cnn_train import _network, DILATIONS
    m = cnn.load()
    net = _network()
    sd = {'inp.weight': m.inp_w, 'inp.bias': m.inp_b, 'fc1.weight': m.fc1_w,
          'fc1.bias': m.fc1_b, 'fc2.weight': m.fc2_w, 'fc2.bias': m.fc2_b}
    for i in range(len(DILATIONS)):
        sd[f'convs.{i}.weight'], sd[f'convs.{i}.bias'] = m.conv_w[i], m.conv_b[i]
    net.load_state_dict({k: torch.from_numpy(v.astype(np.float32)) for k, v in sd.items()})
    net.eval()
    rng = np.random.default_rng(3)
    for n, integ in ((7, False), (333, True), (900, False)):
        x = cnn.channels(np.cumsum(rng.normal(size=n)), rng.normal(size=n), None)
        with torch.no_grad():
            ref = net(torch.from_numpy(x)[None], torch.tensor([float(integ)])).item()
        assert abs(ref - m.logit(x, integ)) < 1e-4


def test_the_training_windows_are_the_corpus_slices_they_start_at():
    torch = pytest.importorskip('torch')   # requirements/train.txt; CI runs without it
    from stiction_ros.analysis.detection.cnn_train import cut_windows
    x = np.random.default_rng(4).normal(size=(cnn.N_CHANNELS, 3000)).astype(np.float32)
    starts = np.array([0, 17, 2499, 1200])
    got = cut_windows(torch.from_numpy(x), starts, 500).numpy()
    want = np.stack([x[:, s:s + 500] for s in starts])
    assert got.shape == (4, cnn.N_CHANNELS, 500)
    np.testing.assert_array_equal(got, want)


def test_a_dilation_too_large_to_run_is_refused(tmp_path):
    with np.load(cnn.DEFAULT_PATH) as z:
        a = {k: z[k] for k in cnn.ARRAYS}
        meta = json.loads(str(z['header']))['meta']
    a['dilations'] = a['dilations'].copy()
    a['dilations'][-1] = 2 ** 30
    cnn.save(tmp_path / 'wide.npz', a, meta)
    with pytest.raises(DetectorFileError, match='dilations'):
        cnn.load(tmp_path / 'wide.npz')


def test_trees_trained_with_another_network_are_refused(tmp_path):
    from dataclasses import replace
    from stiction_ros.analysis.detection import model_file
    from stiction_ros.analysis.detection.detect import load_model
    shipped = model_file.load()
    assert shipped.meta['cnn_sha256'] == cnn.load().sha256
    other = replace(shipped, meta={**shipped.meta, 'cnn_sha256': '0' * 64})
    model_file.save(tmp_path / 'other.npz', other)
    with pytest.raises(DetectorFileError, match='another CNN'):
        load_model(str(tmp_path / 'other.npz'))
