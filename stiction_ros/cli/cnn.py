"""
Train the detector's 1-D CNN on simulated loops (``make cnn``; needs PyTorch).

    python -m stiction_ros.cli.cnn [--out FILE] [--seeds N] [--epochs E] [--jobs J]
                                   [--batch B] [--device cpu|cuda] [--width C]
                                   [--hidden H] [--dilations D,D,...] [--corpus-file F]
                                   [--first-seed S] [--without-deadband-like]
                                   [--init FILE] [--peak-lr LR]
                                   [--hard-negatives FIRST-LAST]

Simulates the network's own corpus (seeds from 2000000, never used by the
detector's training, calibration or scoring sets), trains the network and
writes its weights as plain arrays.  After a new network, rebuild the
detector (``make detector``): the network's logit is one of its figures.
The calibration seeds' balanced accuracy is printed after each epoch and
chooses nothing; so does the whole-record log loss on the first 2 000
training records beside it (how far the network fits its corpus beyond what
it learns).  The shape options default to the shipped networks' (with
``--init``, to the starting network's); the header of the weights keeps the
shape.  ``--init`` continues from the weights of a
network (``--first-seed``: on a corpus of other seeds); the header names the
starting file.  ``--hard-negatives`` (with ``--init``) adds the healthy
records of another seed range that the starting network calls sticky.
After each epoch the network so far is kept beside the
output as ``NAME.partial.npz`` (its header says how many epochs it had), and
removed when the output is written: a run stopped by a time limit keeps
what it learned.  Real plant loops are never read.
"""

import argparse
import datetime
import importlib.util
import os
from pathlib import Path
import sys

from stiction_ros.analysis.detection import cnn, dataset
from stiction_ros.cli.text import description, pipe_safe
from stiction_ros.errors import DetectorFileError


def parser() -> argparse.ArgumentParser:
    """Return the command-line parser."""
    from stiction_ros.analysis.detection.cnn_train import ARCH, BATCH, CORPUS, EPOCHS, PEAK_LR
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
    p.add_argument('--width', type=int,
                   help=f'channels of every layer (default: {ARCH.width}, or the --init '
                        "network's)")
    p.add_argument('--hidden', type=int,
                   help=f'units of the hidden layer (default: {ARCH.hidden}, or the --init '
                        "network's)")
    p.add_argument('--dilations', type=_dilations,
                   help='dilation of each residual layer, comma-separated (default: '
                        f"{','.join(map(str, ARCH.dilations))}, or the --init network's)")
    p.add_argument('--corpus-file',
                   help='keep the simulated corpus here, or read it if it holds the same seeds '
                        '(several network shapes on one corpus)')
    p.add_argument('--first-seed', type=int, default=CORPUS.start,
                   help='first corpus seed (default: %(default)s); the detector seeds (training, '
                        'calibration, test) are refused')
    p.add_argument('--without-deadband-like', action='store_true',
                   help='leave out the sticky records OP and PV cannot tell from a deadband, '
                        'as the detector calibration and scoring do')
    p.add_argument('--init', metavar='FILE',
                   help='start from the weights of this network (same shape), not at random')
    p.add_argument('--peak-lr', type=float, default=PEAK_LR,
                   help='peak of the one-cycle learning rate (default: %(default)s)')
    p.add_argument('--hard-negatives', type=_seed_range, metavar='FIRST-LAST',
                   help='with --init: add the healthy records of these seeds that the starting '
                        'network calls sticky (whole record, logit above 0)')
    return p


def _seed_range(text: str) -> range:
    try:
        a, b = (int(v) for v in text.split('-'))
    except ValueError:
        raise argparse.ArgumentTypeError(f'not a seed range FIRST-LAST: {text!r}')
    if a < 0 or b < a:
        raise argparse.ArgumentTypeError(f'not a seed range FIRST-LAST: {text!r}')
    return range(a, b + 1)


def _dilations(text: str) -> tuple:
    try:
        out = tuple(int(v) for v in text.split(','))
    except ValueError:
        raise argparse.ArgumentTypeError(f'not a comma-separated list of integers: {text!r}')
    if not out or min(out) < 1 or max(out) > cnn.MAX_DILATION:
        raise argparse.ArgumentTypeError(f'dilations must be 1-{cnn.MAX_DILATION}: {text!r}')
    return out


def network_shape(width: int | None, hidden: int | None, dilations: tuple | None,
                  init: cnn.CnnModel | None = None):
    """
    Return the :class:`Arch` to train: the options given, the rest from ``init`` or the default.

    Training on from a network keeps its shape unless told otherwise, so a
    wider base needs no shape options on ``make cnn-large-tune``; a shape
    the starting weights cannot fill is refused here, before the corpus.
    """
    from stiction_ros.analysis.detection.cnn_train import ARCH, Arch
    base = ARCH if init is None else Arch(int(init.inp_w.shape[0]), int(init.fc1_b.shape[0]),
                                          tuple(int(d) for d in init.dilations))
    arch = Arch(base.width if width is None else width, base.hidden if hidden is None else hidden,
                base.dilations if dilations is None else dilations)
    if init is not None and arch != base:
        raise ValueError(f'the starting weights are of another network shape: '
                         f'{base.width} channels, {base.hidden} hidden units, dilations '
                         f'{",".join(map(str, base.dilations))}')
    return arch


def partial_path(out: str | Path) -> Path:
    """Return where training keeps its last finished epoch beside ``out`` until it ends."""
    out = Path(out)
    return out.with_name(f'{out.stem}.partial{out.suffix}')


def _write(path: Path, model, meta: dict) -> None:
    part = path.with_name(path.name + '.part')
    cnn.save(part, {k: getattr(model, k) for k in cnn.ARRAYS}, meta)
    part.replace(path)
    cnn.load(path)


@pipe_safe
def main(argv=None) -> int:
    """Entry point."""
    args = parser().parse_args(argv)
    if (args.seeds < 200 or args.epochs < 1 or args.batch < 1 or args.jobs < 1
            or any(v is not None and v < 1 for v in (args.width, args.hidden))
            or args.first_seed < 0
            or not 0 < args.peak_lr < 1):
        print('stiction-cnn: error: at least 200 seeds, 1 epoch, a batch of 1, 1 job, '
              '1 channel and 1 hidden unit; a first seed of 0 or more; a peak learning rate '
              'in (0, 1)', file=sys.stderr)
        return 2
    seeds = range(args.first_seed, args.first_seed + args.seeds)
    hard = args.hard_negatives
    for drawn in (seeds, hard or range(0)):
        for name in ('TRAIN', 'CALIBRATION', 'TEST'):
            used = getattr(dataset, name)
            if drawn and drawn.start < used.stop and used.start < drawn.stop:
                print(f'stiction-cnn: error: seeds {drawn.start}-{drawn.stop - 1} overlap the '
                      f"detector's {name.lower()} seeds {used.start}-{used.stop - 1}",
                      file=sys.stderr)
                return 2
    if hard and (not args.init or (hard.start < seeds.stop and seeds.start < hard.stop)):
        print('stiction-cnn: error: --hard-negatives needs --init (the network that finds '
              'them) and seeds apart from the corpus', file=sys.stderr)
        return 2
    init = None
    if args.init:
        try:
            init = cnn.load(args.init)
        except DetectorFileError as err:
            print(f'stiction-cnn: error: {err}', file=sys.stderr)
            return 2
    try:
        arch = network_shape(args.width, args.hidden, args.dilations, init)
    except ValueError as err:
        print(f'stiction-cnn: error: {err}', file=sys.stderr)
        return 2
    # Only looked up here: a parent holding torch's thread pool makes the
    # corpus workers it forks ten times slower.
    if importlib.util.find_spec('torch') is None:
        print('stiction-cnn: error: PyTorch is needed to train the network: '
              '.venv/bin/pip install -r requirements/train.txt', file=sys.stderr)
        return 2
    from stiction_ros.analysis.detection.cnn_train import corpus, corpus_file, export_error, \
        hard_negatives, join, to_model, train_cnn

    def say(m):
        print(m, file=sys.stderr, flush=True)
    say(f'corpus: seeds {seeds.start}-{seeds.stop - 1}'
        f'{", deadband-like sticky records left out" * args.without_deadband_like}')
    if args.corpus_file:
        try:
            data = corpus_file(seeds, args.corpus_file, args.jobs, say,
                               args.without_deadband_like)
        except ValueError as err:
            print(f'stiction-cnn: error: {err}', file=sys.stderr)
            return 2
    else:
        data = corpus(seeds, args.jobs, say, args.without_deadband_like)
    if hard:
        say(f'hard negatives: healthy records of seeds {hard.start}-{hard.stop - 1} that '
            f'{Path(args.init).name} calls sticky')
        try:
            extra = hard_negatives(corpus(hard, args.jobs, say, healthy_only=True), init,
                                   say=say)
        except ValueError as err:
            print(f'stiction-cnn: error: {err}', file=sys.stderr)
            return 2
        data = join(data, extra)
    say(f'check set: calibration seeds {dataset.CALIBRATION.start}-'
        f'{dataset.CALIBRATION.stop - 1} (reported, not used)')
    check = corpus(dataset.CALIBRATION, args.jobs, say)
    say(f'network: {arch.width} channels, {arch.hidden} hidden units, dilations '
        f'{",".join(map(str, arch.dilations))}')
    meta = {'version': cnn.VERSION, 'file': Path(args.out).name,
            'corpus_seeds': [seeds.start, seeds.stop], 'records': int(len(data['y'])),
            'without_deadband_like': bool(args.without_deadband_like),
            'hard_negatives': (None if not hard else
                               {'seeds': [hard.start, hard.stop], 'logit_above': 0.0,
                                'records': int(len(extra['y']))}),
            'init': (None if init is None else
                     {'file': Path(args.init).name, 'sha256': init.sha256}),
            'sticky_share': round(float(data['y'].mean()), 4),
            'date': datetime.date.today().isoformat()}
    out, partial = Path(args.out), partial_path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)

    def keep(net, figures):
        # The last finished epoch, so that a run a time limit stops (a GPU
        # lease) leaves a network to measure or to go on from (--init).
        kept = {**meta, 'file': partial.name, 'figures': figures}
        _write(partial, to_model(net, kept), kept)
    try:
        net, figures = train_cnn(data, check, args.epochs, say, args.batch, args.device, arch,
                                 init, args.peak_lr, on_epoch=keep)
    except ValueError as err:
        print(f'stiction-cnn: error: {err}', file=sys.stderr)
        return 2
    meta['figures'] = figures
    model = to_model(net, meta)
    meta['figures']['max_abs_export_error'] = export_error(net, model, check)
    _write(out, model, meta)
    partial.unlink(missing_ok=True)
    print(f'wrote {args.out} ({Path(args.out).stat().st_size / 1024:.0f} KiB, '
          f'{len(data["y"])} records, {args.epochs} epochs, {figures["train_s"]} s); '
          f'largest torch/NumPy logit difference {meta["figures"]["max_abs_export_error"]:.2g}; '
          f'rebuild the detector next: make detector')
    return 0


if __name__ == '__main__':
    sys.exit(main())
