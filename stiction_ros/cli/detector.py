"""
Rebuild the learned stiction detector from simulated loops (``make detector``).

    python -m stiction_ros.cli.detector [--out FILE] [--train N] [--calibration N] [--jobs J]

Draws and simulates the training and calibration records from their seeds
(``stiction_ros.analysis.detection.dataset``), leaves out of both the sticky
records that OP and PV cannot tell from a deadband (``deadband_like``), trains
the boosted trees on the first, weighs their out-of-fold score with the large
network's logit (``stiction_ros.analysis.detection.stack``) on the same
records, calibrates the weighed score's probability on the second, and
writes the model file.
The same seeds, code and networks give the same trees, stack and calibration
(the header keeps the date and timings).  Real plant loops are never read.
"""

import argparse
from dataclasses import replace
import datetime
import os
from pathlib import Path
import sys
import time

import numpy as np

from stiction_ros._blas import kernels
from stiction_ros.analysis.detection import cnn, dataset, deadband_like, model_file, stack
from stiction_ros.analysis.detection.features import FEATURE_NAMES
from stiction_ros.cli.text import description, pipe_safe
from stiction_ros.errors import TrainingSetError
from stiction_ros.study.accuracy import balanced_accuracy, confusion


def parser() -> argparse.ArgumentParser:
    """Return the command-line parser."""
    p = argparse.ArgumentParser(prog='stiction-detector', description=description(__doc__))
    p.add_argument('--out', default=str(model_file.DEFAULT_PATH),
                   help='model file to write (default: the shipped one)')
    p.add_argument('--train', type=int, default=len(dataset.TRAIN),
                   help=f'training records, seeds from {dataset.TRAIN.start}')
    p.add_argument('--calibration', type=int, default=len(dataset.CALIBRATION),
                   help=f'calibration records, seeds from {dataset.CALIBRATION.start}')
    p.add_argument('--jobs', type=int, default=os.cpu_count() or 1)
    p.add_argument('--cache', default='out/detector_cache',
                   help='folder keeping the features of each simulated set, reused while the '
                        'seeds and the code are unchanged ("" for none)')
    return p


# A floor against a typing slip; what the trees need is checked on the sets drawn.
MIN_TRAIN, MIN_CALIBRATION = 30, 20


def enough_of_each(y: np.ndarray, least: int, what: str) -> None:
    """Raise TrainingSetError unless ``y`` holds ``least`` records of each label."""
    sticky = int(np.sum(y))
    healthy = len(y) - sticky
    if min(sticky, healthy) < least:
        raise TrainingSetError(
            f'the {what} set keeps {sticky} sticky and {healthy} healthy records once the '
            f'sticky ones a deadband explains are left out; it needs {least} of each: '
            'give it more records')


def build_model(n_train: int, n_cal: int, jobs: int, say=print, cache=None) -> tuple:
    """Return (TreeModel, figures) trained and calibrated on fresh simulated records."""
    import sklearn
    from stiction_ros.analysis.detection.train import FOLDS, fit_calibration, fit_stack, \
        out_of_fold_scores, PARAMS, train
    t0 = time.perf_counter()
    tr_seeds = range(dataset.TRAIN.start, dataset.TRAIN.start + n_train)
    ca_seeds = range(dataset.CALIBRATION.start, dataset.CALIBRATION.start + n_cal)
    say(f'figures computed with: {kernels()}')
    say(f'training set: {n_train} simulated records (seeds {tr_seeds.start}-{tr_seeds.stop - 1})')
    tr = dataset.build(tr_seeds, jobs, cache=cache)
    # Taught as sticky, they teach "a deadband is stiction", and backlash is healthy.
    say('training records that OP and PV cannot tell from a deadband: left out')
    tr = deadband_like.leave_out(deadband_like.mark(tr, jobs, cache))
    # Each of the stack's folds holds a record of each label.
    enough_of_each(tr['y'], FOLDS, 'training')
    say(f'calibration set: {n_cal} records (seeds {ca_seeds.start}-{ca_seeds.stop - 1})')
    ca = dataset.build(ca_seeds, jobs, cache=cache)
    # The logits are kept under the whole set's seeds; the map is fitted on the
    # records make accuracy scores: without the sticky ones OP and PV cannot
    # tell from a deadband, so the probability is that of a stick-slip they show.
    ca['large_logit'] = stack.seed_logits(ca['seed'], jobs, cache=cache)
    say('calibration records that OP and PV cannot tell from a deadband: left out of the map')
    whole = deadband_like.mark(ca, jobs, cache)
    ca = deadband_like.leave_out(whole)
    enough_of_each(ca['y'], 2, 'calibration')
    t1 = time.perf_counter()
    meta = {'version': model_file.VERSION, 'file': 'stiction_detector.npz',
            'trained_on': (f'{len(tr["y"])} simulated closed loops (seeds {tr_seeds.start}-'
                           f'{tr_seeds.stop - 1}), calibrated on {len(ca["y"])} more (seeds '
                           f'{ca_seeds.start}-{ca_seeds.stop - 1}); no plant data'),
            'train_seeds': [tr_seeds.start, tr_seeds.stop],
            'calibration_seeds': [ca_seeds.start, ca_seeds.stop],
            'skipped': {'train': tr['skipped'], 'calibration': ca['skipped']},
            'sklearn': sklearn.__version__, 'params': PARAMS, 'cnn_sha256': cnn.load().sha256,
            'date': datetime.date.today().isoformat(),
            # What the figures ran on: the same on two hosts, the same trees.
            'kernels': kernels()}
    large = stack.network()
    model, clf = train(tr['x'], tr['y'], ca['x'], ca['y'], FEATURE_NAMES, meta)
    trees_only = balanced_accuracy(confusion(ca['y'], model.probability(ca['x']) >= 0.5))
    say(f'stack: the trees out of {FOLDS} folds, the large network on both sets')
    oof = out_of_fold_scores(tr['x'], tr['y'], PARAMS)
    lt = stack.seed_logits(tr['seed'], jobs, cache=cache)
    lc = ca['large_logit']
    coef = fit_stack(oof, lt, tr['y'])
    meta['stack'] = {'coef': coef, 'folds': FOLDS, 'network': stack.LARGE_PATH.name,
                     'network_sha256': large.sha256, 'views': [list(v) for v in stack.VIEWS]}
    model = replace(model, meta=meta)
    calib_x, calib_y = fit_calibration(model.score(ca['x'], lc), ca['y'])
    model = replace(model, calib_x=calib_x, calib_y=calib_y)
    t2 = time.perf_counter()
    pred = model.probability(ca['x'], lc) >= 0.5
    c = confusion(ca['y'], pred)
    counted = confusion(whole['y'], model.probability(whole['x'], whole['large_logit']) >= 0.5)
    # Features as first computed (a cached set reports the time it took then).
    figures = {'features_s': round(tr['seconds'] + ca['seconds'], 1), 'fit_s': round(t2 - t1, 1),
               'wall_s': round(t1 - t0, 1),
               'calibration_balanced_accuracy': round(balanced_accuracy(c), 4),
               'calibration_balanced_accuracy_deadband_like_counted':
               round(balanced_accuracy(counted), 4),
               'trees_alone_calibration_balanced_accuracy': round(trees_only, 4),
               'trees': int(len(model.tree_start)), 'nodes': int(len(model.feature)),
               'max_abs_export_error': float(np.max(np.abs(
                   model.raw_score(ca['x']) - clf.decision_function(ca['x']))))}
    model.meta['figures'] = figures
    return model, figures


@pipe_safe
def main(argv=None) -> int:
    """Entry point."""
    args = parser().parse_args(argv)
    if args.train < MIN_TRAIN or args.calibration < MIN_CALIBRATION:
        print(f'stiction-detector: error: at least {MIN_TRAIN} training and {MIN_CALIBRATION} '
              'calibration records', file=sys.stderr)
        return 2
    try:
        model, figures = build_model(args.train, args.calibration, args.jobs,
                                     lambda m: print(m, file=sys.stderr, flush=True),
                                     args.cache or None)
    except TrainingSetError as e:
        print(f'stiction-detector: error: {e}', file=sys.stderr)
        return 2
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    model_file.save(args.out, model)
    model_file.load(args.out, FEATURE_NAMES)
    size = Path(args.out).stat().st_size
    print(f'wrote {args.out} ({size / 1024:.0f} KiB, {figures["trees"]} trees, '
          f'{figures["nodes"]} nodes); calibration-set balanced accuracy '
          f'{figures["calibration_balanced_accuracy"]:.3f}; features {figures["features_s"]} s, '
          f'fit {figures["fit_s"]} s')
    return 0


if __name__ == '__main__':
    sys.exit(main())
