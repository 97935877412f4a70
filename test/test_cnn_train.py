"""Training the detector's networks: shapes, the kept corpus, the loss it reports, the export."""

from pathlib import Path

import numpy as np
import pytest

from stiction_ros.analysis.detection import cnn
from stiction_ros.analysis.detection.cnn_train import ARCH, Arch, balanced_log_loss, \
    corpus_file, subset


def test_the_default_shape_is_the_shipped_networks():
    for name in ('stiction_cnn.npz', 'stiction_cnn_large_base.npz', 'stiction_cnn_large.npz'):
        path = cnn.DEFAULT_PATH.with_name(name)
        m = cnn.load(path)
        assert m.inp_w.shape[0] == ARCH.width
        assert m.fc1_b.shape[0] == ARCH.hidden
        assert tuple(int(d) for d in m.dilations) == ARCH.dilations


@pytest.mark.parametrize('bad', [{'width': 0}, {'hidden': 0}, {'dilations': ()},
                                 {'dilations': (1, 0)}])
def test_a_shape_that_cannot_be_built_is_refused(bad):
    with pytest.raises(ValueError):
        Arch(**bad)


def test_the_balanced_log_loss_weighs_each_class_half():
    y = np.array([True, False, False, False])
    assert balanced_log_loss(np.zeros(4), y) == pytest.approx(np.log(2.0))
    z = np.array([2.0, -1.0, 0.5, -3.0])
    # Repeating the healthy records changes nothing: each class counts half.
    assert balanced_log_loss(np.r_[z, z[1:]], np.r_[y, y[1:]]) == pytest.approx(
        balanced_log_loss(z, y))
    # A confident wrong answer costs more than a hesitant one.
    assert balanced_log_loss(np.array([-5.0, -1.0]), np.array([True, False])) > \
        balanced_log_loss(np.array([-0.5, -1.0]), np.array([True, False]))


def test_a_kept_corpus_is_read_back_the_same_and_another_seed_range_is_refused(tmp_path):
    seeds = range(2_000_000, 2_000_200)
    path = tmp_path / 'corpus.npz'
    said = []
    made = corpus_file(seeds, path, jobs=1, say=said.append)
    assert path.exists() and not path.with_name('corpus.npz.part').exists()
    read = corpus_file(seeds, path, jobs=1, say=said.append)
    assert 'read from' in said[-1]
    for k in ('seed', 'x', 'off', 'y', 'integ'):
        np.testing.assert_array_equal(made[k], read[k])
    with pytest.raises(ValueError, match='another corpus'):
        corpus_file(range(2_000_000, 2_000_300), path, jobs=1, say=said.append)
    part = subset(made, 3)
    assert part['x'].shape[1] == part['off'][-1] == made['off'][3]
    assert len(part['y']) == 3


def test_a_network_of_another_shape_exports_the_logit_pytorch_gives(tmp_path):
    torch = pytest.importorskip('torch')   # requirements/train.txt; CI runs without it
    from stiction_ros.analysis.detection.cnn_train import _network, to_model
    arch = Arch(width=12, hidden=5, dilations=(1, 3, 9))
    torch.manual_seed(1)
    net = _network(arch)
    net.eval()
    model = to_model(net, {'arch': arch.to_json()})
    cnn.save(tmp_path / 'w12.npz', {k: getattr(model, k) for k in cnn.ARRAYS}, model.meta)
    back = cnn.load(tmp_path / 'w12.npz')
    rng = np.random.default_rng(5)
    for n, integ in ((9, True), (640, False)):
        x = cnn.channels(np.cumsum(rng.normal(size=n)), rng.normal(size=n), None)
        with torch.no_grad():
            ref = net(torch.from_numpy(x)[None], torch.tensor([float(integ)])).item()
        assert abs(ref - back.logit(x, integ)) < 1e-4


@pytest.mark.parametrize('argv,message', [
    (['--dilations', '1,x'], 'comma-separated'),
    (['--dilations', '1,0'], 'dilations must be'),
    (['--width', '0'], '1 channel'),
    (['--hidden', '0'], '1 hidden unit'),
])
def test_the_training_command_refuses_a_shape_it_cannot_build(argv, message, capsys):
    from stiction_ros.cli.cnn import main
    try:
        # A refusal that broke would train on the smallest corpus, not hang the suite.
        rc = main(argv + ['--seeds', '200', '--epochs', '1', '--jobs', '1',
                          '--out', '/nonexistent/x.npz'])
    except SystemExit as stop:
        rc = stop.code
    assert rc == 2
    assert message in capsys.readouterr().err


def test_a_corpus_without_deadband_like_records_drops_the_sticky_ones_a_deadband_explains(
        tmp_path):
    from stiction_ros.analysis.detection.cnn_train import corpus
    from stiction_ros.analysis.detection.dataset import MIN_FOOTPRINT
    from stiction_ros.analysis.detection.deadband_like import slip_footprint
    from stiction_ros.sim.corpus import draw_scenario, simulate
    seeds = range(2_000_000, 2_000_080)
    whole = corpus(seeds, jobs=1, say=lambda m: None)
    lean = corpus(seeds, jobs=1, say=lambda m: None, without_deadband_like=True)
    dropped = sorted(set(whole['seed']) - set(lean['seed']))
    assert set(lean['seed']) <= set(whole['seed']) and dropped
    for seed in whole['seed'][whole['y']]:
        sc = draw_scenario(int(seed))
        # The physics of the split: what a slip adds over the nearest deadband.
        assert (slip_footprint(sc, simulate(sc)) < MIN_FOOTPRINT) == (seed in dropped)
    assert set(dropped) <= set(whole['seed'][whole['y']])   # healthy records all stay
    path = tmp_path / 'c.npz'
    corpus_file(seeds, path, jobs=1, say=lambda m: None)
    with pytest.raises(ValueError, match='without deadband-like records'):
        corpus_file(seeds, path, jobs=1, say=lambda m: None, without_deadband_like=True)


def test_starting_weights_go_into_the_network_unchanged_and_another_shape_is_refused():
    pytest.importorskip('torch')   # requirements/train.txt; CI runs without it
    from stiction_ros.analysis.detection.cnn_train import _network, load_weights, to_model
    large = cnn.load(cnn.DEFAULT_PATH.with_name('stiction_cnn_large.npz'))
    net = _network()
    load_weights(net, large)
    back = to_model(net, {})
    for k in cnn.ARRAYS:
        np.testing.assert_array_equal(getattr(back, k), getattr(large, k))
    with pytest.raises(ValueError, match='another network shape'):
        load_weights(_network(Arch(width=8)), large)


def test_the_training_command_refuses_the_detectors_own_seeds(capsys):
    from stiction_ros.analysis.detection import dataset
    from stiction_ros.cli.cnn import main
    for first in (dataset.TRAIN.start, dataset.CALIBRATION.start + 10, dataset.TEST.start):
        assert main(['--first-seed', str(first), '--seeds', '200',
                     '--out', '/nonexistent/x.npz']) == 2
        assert 'overlap' in capsys.readouterr().err


CANDIDATES = Path(__file__).resolve().parents[1] / 'docs' / 'candidates'


@pytest.mark.parametrize('where', [cnn.DEFAULT_PATH.parent, CANDIDATES / 'b64'],
                         ids=['shipped', 'candidate-b64'])
def test_a_large_network_names_the_network_it_was_trained_on_from(where):
    base = cnn.load(where / 'stiction_cnn_large_base.npz')
    large = cnn.load(where / 'stiction_cnn_large.npz')
    assert large.meta['init'] == {'file': 'stiction_cnn_large_base.npz', 'sha256': base.sha256}
    assert large.meta['without_deadband_like'] is True
    from stiction_ros.analysis.detection import dataset
    first, stop = large.meta['corpus_seeds']
    for used in (dataset.TRAIN, dataset.CALIBRATION, dataset.TEST):
        assert stop <= used.start or used.stop <= first


def test_a_training_run_stopped_mid_way_keeps_its_last_epoch_and_a_finished_one_cleans_up(
        tmp_path):
    pytest.importorskip('torch')   # requirements/train.txt; CI runs without it
    import signal
    import subprocess
    import sys
    import time
    from stiction_ros.cli.cnn import partial_path
    out = tmp_path / 'tiny.npz'
    partial = partial_path(out)
    assert partial.name == 'tiny.partial.npz'
    argv = [sys.executable, '-m', 'stiction_ros.cli.cnn', '--seeds', '200', '--batch', '16',
            '--jobs', '2', '--width', '4', '--hidden', '2', '--dilations', '1',
            '--out', str(out)]
    # A time limit stops a long run: what it finished is kept, the output is not claimed.
    run = subprocess.Popen(argv + ['--epochs', '1000'], stdout=subprocess.DEVNULL,
                           stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 300
        while not partial.exists() and run.poll() is None and time.monotonic() < deadline:
            time.sleep(0.5)
        assert partial.exists(), run.stderr.read() if run.poll() is not None else 'too slow'
    finally:
        run.send_signal(signal.SIGKILL)
        run.wait()
    kept = cnn.load(partial)
    done = kept.meta['figures']['epochs_done']
    assert 1 <= done < 1000 and kept.meta['figures']['epochs'] == 1000
    assert len(kept.meta['figures']['check_balanced_accuracy']) == done
    assert kept.inp_w.shape[0] == 4 and not out.exists()
    # A finished run writes its output and removes the kept epoch.
    ok = subprocess.run(argv + ['--epochs', '1'], capture_output=True, text=True)
    assert ok.returncode == 0, ok.stderr
    assert cnn.load(out).meta['figures']['epochs'] == 1 and not partial.exists()


def _save_shape(path, width, hidden, dilations):
    rng = np.random.default_rng(3)
    layers, k = len(dilations), 5
    arrays = {'inp_w': rng.normal(size=(width, cnn.N_CHANNELS, 7)), 'inp_b': np.zeros(width),
              'conv_w': rng.normal(size=(layers, width, width, k)),
              'conv_b': np.zeros((layers, width)), 'dilations': np.array(dilations),
              'fc1_w': rng.normal(size=(hidden, 2 * width + 1)), 'fc1_b': np.zeros(hidden),
              'fc2_w': rng.normal(size=(1, hidden)), 'fc2_b': np.zeros(1)}
    cnn.save(path, arrays, {})
    return cnn.load(path)


def test_training_on_from_a_network_keeps_its_shape_and_refuses_another(tmp_path, capsys):
    from stiction_ros.cli.cnn import main, network_shape
    assert network_shape(None, None, None) == ARCH
    assert network_shape(16, None, (1, 2)) == Arch(16, ARCH.hidden, (1, 2))
    w12 = _save_shape(tmp_path / 'w12.npz', 12, 5, (1, 3, 9))
    # A wider base goes on training as it is, with no shape options.
    assert network_shape(None, None, None, w12) == Arch(12, 5, (1, 3, 9))
    assert network_shape(12, 5, (1, 3, 9), w12) == Arch(12, 5, (1, 3, 9))
    for other in ((8, None, None), (None, 6, None), (None, None, (1, 3))):
        with pytest.raises(ValueError, match='another network shape'):
            network_shape(*other, w12)
    # Refused before the corpus is simulated (and without PyTorch).
    assert main(['--init', str(tmp_path / 'w12.npz'), '--width', '8', '--seeds', '200',
                 '--out', str(tmp_path / 'x.npz')]) == 2
    err = capsys.readouterr().err
    assert 'another network shape: 12 channels, 5 hidden units, dilations 1,3,9' in err
    assert 'corpus' not in err and not (tmp_path / 'x.npz').exists()


def _records(data):
    off = data['off']
    return {int(s): (data['x'][:, off[i]:off[i + 1]], bool(data['y'][i]), bool(data['integ'][i]))
            for i, s in enumerate(data['seed'])}


def test_records_taken_and_joined_are_the_records_they_were():
    from stiction_ros.analysis.detection.cnn_train import corpus, join, take
    data = corpus(range(2_000_000, 2_000_060), jobs=1, say=lambda m: None)
    keep = np.arange(len(data['y'])) % 3 == 0
    back = join(take(data, keep), take(data, ~keep))
    assert back['off'][-1] == back['x'].shape[1] == data['x'].shape[1]
    assert sorted(back['seed']) == sorted(data['seed'])
    want, got = _records(data), _records(back)
    for seed, (x, y, integ) in want.items():
        np.testing.assert_array_equal(got[seed][0], x)
        assert got[seed][1:] == (y, integ)
    none = take(data, np.zeros(len(data['y']), dtype=bool))
    assert len(none['y']) == 0 and none['off'].tolist() == [0] and none['x'].shape[1] == 0


def test_hard_negatives_are_the_healthy_records_the_network_calls_sticky():
    from stiction_ros.analysis.detection.cnn_train import corpus, hard_negatives
    seeds = range(2_000_000, 2_000_120)
    whole = corpus(seeds, jobs=1, say=lambda m: None)
    healthy = corpus(seeds, jobs=1, say=lambda m: None, healthy_only=True)
    # Sticky records are left out before they are simulated; the healthy ones stay as they were.
    assert not healthy['y'].any()
    assert healthy['seed'].tolist() == whole['seed'][~whole['y']].tolist()
    net = cnn.load(cnn.DEFAULT_PATH)
    hard = hard_negatives(whole, net, say=lambda m: None)
    assert not hard['y'].any()
    rec = _records(whole)
    called = {s for s, (x, y, integ) in rec.items() if not y and net.logit(x, integ) > 0.0}
    assert set(hard['seed'].tolist()) == called
    # The small network flags some healthy records and not all: the test can fail both ways.
    assert 0 < len(called) < len(healthy['y'])


@pytest.mark.parametrize('argv, message', [
    (['--hard-negatives', '3210000-3210999'], 'needs --init'),        # nothing to find them
    (['--init', 'x.npz', '--hard-negatives', '2000100-2000999'], 'needs --init'),  # in corpus
    (['--init', 'x.npz', '--hard-negatives', 'TEST'], "overlap the detector's test seeds"),
])
def test_the_training_command_refuses_hard_negatives_it_cannot_draw_apart(argv, message, capsys):
    from stiction_ros.analysis.detection import dataset
    from stiction_ros.cli.cnn import main
    if argv[-1] == 'TEST':
        argv = argv[:-1] + [f'{dataset.TEST.start}-{dataset.TEST.start + 999}']
    assert main(['--first-seed', '2000000', '--seeds', '200', '--out', '/nonexistent/x.npz',
                 *argv]) == 2
    assert message in capsys.readouterr().err
