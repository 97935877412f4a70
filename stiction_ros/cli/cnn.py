"""
Train the detector's 1-D CNN on simulated loops (``make cnn``; needs PyTorch).

    python -m stiction_ros.cli.cnn [--out FILE] [--seeds N] [--epochs E] [--jobs J]
                                   [--batch B] [--device cpu|cuda]

Simulates the network's own corpus (seeds from 2000000, never used by the
detector's training, calibration or scoring sets), trains the network and
writes its weights as plain arrays.  After a new network, rebuild the
detector (``make detector``): the network's logit is one of its figures.
The calibration seeds' balanced accuracy is printed after each epoch and
chooses nothing.  Real plant loops are never read.
"""

import argparse
import datetime
import importlib.util
import os
from pathlib import Path
import sys

from stiction_ros.analysis.detection import cnn, dataset
from stiction_ros.cli.text import description, pipe_safe


def parser() -> argparse.ArgumentParser:
    """Return the command-line parser."""
    from stiction_ros.analysis.detection.cnn_train import BATCH, CORPUS, EPOCHS
    p = argparse.ArgumentParser(prog='stiction-cnn', description=description(__doc__))
    p.add_argument('--out', default=str(cnn.DEFAULT_PATH),
                   help='weights file to write (default: the shipped one)')
    p.add_argument('--seeds', type=int, default=len(CORPUS),
                   help=f'corpus seeds from {CORPUS.start} (about 80 %% become records)')
    p.add_argument('--epochs', type=int, default=EPOCHS)
    p.add_argument('--jobs', type=int, default=min(os.cpu_count() or 1, 2),
                   help='processes simulating the corpus')
    p.add_argument('--batch', type=int, default=BATCH, help='records a training step')
    p.add_argument('--device', choices=('cpu', 'cuda'),
                   help='where to train (default: a CUDA GPU if PyTorch sees one)')
    return p


@pipe_safe
def main(argv=None) -> int:
    """Entry point."""
    args = parser().parse_args(argv)
    if args.seeds < 200 or args.epochs < 1 or args.batch < 1 or args.jobs < 1:
        print('stiction-cnn: error: at least 200 seeds, 1 epoch, a batch of 1 and 1 job',
              file=sys.stderr)
        return 2
    # Only looked up here: a parent holding torch's thread pool makes the
    # corpus workers it forks ten times slower.
    if importlib.util.find_spec('torch') is None:
        print('stiction-cnn: error: PyTorch is needed to train the network: '
              '.venv/bin/pip install -r requirements/train.txt', file=sys.stderr)
        return 2
    from stiction_ros.analysis.detection.cnn_train import CORPUS, corpus, export_error, \
        to_model, train_cnn

    def say(m):
        print(m, file=sys.stderr, flush=True)
    seeds = range(CORPUS.start, CORPUS.start + args.seeds)
    say(f'corpus: seeds {seeds.start}-{seeds.stop - 1}')
    data = corpus(seeds, args.jobs, say)
    say(f'check set: calibration seeds {dataset.CALIBRATION.start}-'
        f'{dataset.CALIBRATION.stop - 1} (reported, not used)')
    check = corpus(dataset.CALIBRATION, args.jobs, say)
    net, figures = train_cnn(data, check, args.epochs, say, args.batch, args.device)
    meta = {'version': cnn.VERSION, 'file': Path(args.out).name,
            'corpus_seeds': [seeds.start, seeds.stop], 'records': int(len(data['y'])),
            'sticky_share': round(float(data['y'].mean()), 4),
            'date': datetime.date.today().isoformat(), 'figures': figures}
    model = to_model(net, meta)
    meta['figures']['max_abs_export_error'] = export_error(net, model, check)
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    arrays = {k: getattr(model, k) for k in cnn.ARRAYS}
    cnn.save(args.out, arrays, meta)
    cnn.load(args.out)
    print(f'wrote {args.out} ({Path(args.out).stat().st_size / 1024:.0f} KiB, '
          f'{len(data["y"])} records, {args.epochs} epochs, {figures["train_s"]} s); '
          f'largest torch/NumPy logit difference {meta["figures"]["max_abs_export_error"]:.2g}; '
          f'rebuild the detector next: make detector')
    return 0


if __name__ == '__main__':
    sys.exit(main())
