"""
Cost per record of the learned stiction detector against the old vote (``make bench-detector``).

On the labelled plant loops (OP, PV and SP of about 750 samples), each
record's held stretch is timed three ways, best of three repeats each:
the old rule (oscillation and signatures alone, the baseline), the
detector's whole feature vector (signatures, stuck periods, a coarse
Hammerstein fit) with the model's probability, and the tree model alone.
Training time is in docs/ACCURACY.md (it comes with the model file).
"""

import datetime
import sys

from bench.load_bench import BENCH, ROOT, write_section
import numpy as np

from stiction_ros.analysis.detection import detect, extract, load_model
from stiction_ros.analysis.pipeline import held_signals, is_integrating, signature_window
from stiction_ros.analysis.readers import load_record
from stiction_ros.analysis.signatures.all import compute_signatures
from stiction_ros.cli.study import machine_description

MARKERS = ('<!-- detector-bench: start -->', '<!-- detector-bench: end -->')
LOOPS = ROOT.parent / 'shared' / 'data' / 'plant_loops'


def bench_detector(best_time, folder=LOOPS):
    """Return per-record seconds: {'old_rule', 'detector', 'model_only'} lists, and samples."""
    model = load_model()
    out = {'old_rule': [], 'detector': [], 'model_only': [], 'samples': []}
    for f in sorted(folder.glob('*/*.txt')):
        rec = load_record(f)
        win = signature_window(rec)
        if win is None:
            continue
        x = held_signals(rec, win[0], win[1])
        integ, _ = is_integrating(rec, 'auto')
        args = (x['op'], x['pv'], x['sp'], rec.sample_time)
        detect(*args, integ)  # compile and load once
        vec, _ = extract(*args, integ)
        out['old_rule'].append(best_time(lambda: compute_signatures(*args, integrating=integ)))
        out['detector'].append(best_time(lambda: detect(*args, integ)))
        logit = None if model.stack is None else 0.0
        out['model_only'].append(best_time(lambda: model.probability(vec, logit), repeats=20))
        out['samples'].append(len(x['op']))
    return out


def markdown(r):
    """Return the section's lines."""
    med = {k: float(np.median(v)) for k, v in r.items() if k != 'samples'}
    mx = {k: float(np.max(v)) for k, v in r.items() if k != 'samples'}
    return [MARKERS[0], '## Stiction detector: cost per record', '',
            f'`make bench-detector`, {datetime.date.today().isoformat()}, '
            f'{machine_description()}. {len(r["samples"])} plant loops of median '
            f'{int(np.median(r["samples"]))} samples, one core, best of 3.', '',
            '| step | median ms | max ms | ratio to the old rule (median) |',
            '|---|---|---|---|',
            *[f'| {name} | {1e3 * med[k]:.1f} | {1e3 * mx[k]:.1f} | '
              f'{med[k] / med["old_rule"]:.1f} |'
              for k, name in (('old_rule', 'old rule: oscillation + signatures (baseline)'),
                              ('detector', 'learned detector: features + probability'),
                              ('model_only', 'tree model alone (300 trees)'))],
            '', 'Most of the time of the detector is its coarse Hammerstein fit (a sticky valve '
            'before an ARX plant), which was the strongest single separator on simulated '
            'loops.', MARKERS[1]]


def main():
    """Run the benchmark and write its section of docs/BENCHMARKS.md."""
    from bench.run_all import best_time
    lines = markdown(bench_detector(best_time))
    write_section(lines, BENCH, MARKERS)
    print('\n'.join(lines))
    return 0


if __name__ == '__main__':
    sys.exit(main())
