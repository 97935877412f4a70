"""
Cost per record of the learned stiction detector against the old vote (``make bench-detector``).

On the labelled plant loops (OP, PV and SP of about 750 samples), each
record's held stretch is timed three ways, best of three repeats each:
the old rule (oscillation and signatures alone, the baseline), the
detector's whole feature vector (signatures, stuck periods, a coarse
Hammerstein fit) with the model's probability, and the tree model alone.
The large network's logit (four sign conventions, NumPy) is timed with its
compiled convolution and with the einsum one it replaced (the same bits), and
beside a network of twice its width and the same depth, random weights, for
timing only: what a wider network (docs/DETECTION_LOG.md) would cost every analysis.
The Hammerstein fit's lag sums, most of its time, are timed on each record's
regression (one valve path) as the fits compute them and as first written,
row by row (the same bits, counted).  The prediction-error fits of each record's
valve paths are timed as computed (one Gram matrix per noise model shared by
every dead time) and with one least-squares solve per window, as first
written (the same residuals to 1e-12, counted).  Last, the full Hammerstein S/J fit the
analysis runs beside the verdict (``quantify``), which once had a timed
assertion in the tests; timings belong here.
Training time is in docs/ACCURACY.md (it comes with the model file).
"""

import datetime
import sys

from bench.load_bench import BENCH, ROOT, write_section
import numpy as np

from stiction_ros.analysis.detection import cnn, detect, extract, load_model, stack, timing
from stiction_ros.analysis.detection.features import HAM_MAX_DELAY
from stiction_ros.analysis.detection.output_error import sticky_paths, target
from stiction_ros.analysis.detection.prediction_error import _lags, _noise_filter, \
    _Predictor, NOISE_C, PE_DELAYS, SKIP
from stiction_ros.analysis.detection.timing import alignment
from stiction_ros.analysis.hammerstein import quantify
from stiction_ros.analysis.hammerstein.problem import HammersteinProblem
from stiction_ros.analysis.pipeline import held_signals, is_integrating, signature_window
from stiction_ros.analysis.readers import load_record
from stiction_ros.analysis.signatures.all import compute_signatures
from stiction_ros.cli.study import machine_description
from stiction_ros.kernels.hammerstein import lag_sums, lag_sums_reference, segment_path

MARKERS = ('<!-- detector-bench: start -->', '<!-- detector-bench: end -->')
LOOPS = ROOT.parent / 'shared' / 'data' / 'plant_loops'


STEPS = {'old_rule': 'old rule: oscillation + signatures (baseline)',
         'detector': 'learned detector: features + probability',
         'model_only': 'tree model alone (300 trees)',
         'clock_check': 'clock-skew check: the PI law at 11 shifts and through 5 lags (in '
                        'the detector)',
         'law_profile': "the law's R² at the 11 shifts, one compiled pass (in the check)",
         'law_profile_lstsq': 'the same with one least-squares call per shift, as first '
                              'written (same R²)',
         'network': 'large network alone (32 channels, 4 sign conventions; in the detector)',
         'network_einsum': 'the same with the einsum convolution it replaced (same bits)',
         'network_wide': 'a 64-channel network of the same depth (timing only)',
         'lag_sums': 'Hammerstein lag sums of one valve path, lag by lag (in the detector)',
         'lag_sums_rows': 'the same sums row by row, as first written (same bits)',
         'pe_fit': 'prediction-error fits of the 37 valve paths (in the detector)',
         'pe_fit_lstsq': 'the same with one least-squares call per window, as first written',
         'quantify': 'full Hammerstein S/J fit (the analysis runs it beside the verdict)'}


def lstsq_r2(d_op, d_e, e, free, known, k: int) -> float:
    """Return the R² of dOP on (dE, E, 1) at shift ``k`` by numpy's least squares."""
    n = len(d_op)
    lo, hi = max(0, -k), min(n, n - k)
    if hi - lo < timing.MIN_ROWS:
        return np.nan
    use = free[lo:hi] & known[lo + k:hi + k]
    y = d_op[lo:hi][use]
    if y.size < timing.MIN_ROWS or not np.var(y) > 0:
        return np.nan
    x = np.column_stack([d_e[lo + k:hi + k][use], e[lo + k:hi + k][use], np.ones(y.size)])
    coef, *_ = np.linalg.lstsq(x, y, rcond=None)
    return max(0.0, 1.0 - np.var(y - x @ coef) / np.var(y))


def fit_shifts_lstsq(rows, first: int, last: int) -> np.ndarray:
    """Return what ``timing._fit_shifts`` returns, one least-squares call per shift."""
    if rows is None:
        return np.full(last - first + 1, np.nan)
    return np.array([lstsq_r2(*rows, k) for k in range(first, last + 1)])


def rss_lstsq(fit: _Predictor, path: np.ndarray) -> float:
    """Return ``fit.rss(path)[0]`` with one least-squares solve per noise model and delay."""
    path = path - path.mean()
    rows = fit.n - SKIP
    best = np.inf
    for c in NOISE_C:
        lag = _lags(_noise_filter(path, c))
        for d in PE_DELAYS:
            x = np.column_stack([lag[SKIP - d:fit.n - d], np.ones(rows)])
            r = fit.ys[c] - x @ np.linalg.lstsq(x, fit.ys[c], rcond=None)[0]
            best = min(best, float(r @ r))
    return best


def _pe_paths(op, pv, integrating):
    # The fit and the valve paths prediction_error_figures compares: linear, then sticky.
    y, u = target(op, pv, integrating)
    return _Predictor(y), [u] + [p for _, p in sticky_paths(u, np.asarray(op))]


def law_profile_lstsq(op, pv, sp) -> np.ndarray:
    """Return :func:`timing.law_profile` fitted by :func:`fit_shifts_lstsq`."""
    return fit_shifts_lstsq(timing._law_rows(op, pv, sp, 0.0), -timing.MAX_SHIFT,
                            timing.MAX_SHIFT)


def wider(net: cnn.CnnModel, width: int = 64, hidden: int = 64) -> cnn.CnnModel:
    """Return a network of ``net``'s depth and kernels at another width, random weights."""
    rng = np.random.default_rng(0)
    layers, _, _, k = net.conv_w.shape

    def w(*shape):
        return rng.normal(0.0, 1.0 / np.sqrt(np.prod(shape[1:])), shape)
    return cnn.CnnModel(w(width, net.inp_w.shape[1], net.inp_w.shape[2]), np.zeros(width),
                        w(layers, width, width, k), np.zeros((layers, width)), net.dilations,
                        w(hidden, 2 * width + 1), np.zeros(hidden), w(1, hidden), np.zeros(1),
                        {})


def bench_detector(best_time, folder=LOOPS):
    """Return per-record seconds of each step (see :data:`STEPS`), and samples."""
    model = load_model()
    large = stack.network()
    wide = wider(large)
    out: dict = {k: [] for k in STEPS}
    out['samples'], out['same_logit'], out['same_sums'] = [], [], []
    out['same_profile'], out['same_pe'] = [], []
    regressions, held = [], []
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
        out['clock_check'].append(best_time(lambda: alignment(*args[:3]), repeats=20))
        out['law_profile'].append(best_time(lambda: timing.law_profile(*args[:3]),
                                            repeats=20))
        out['law_profile_lstsq'].append(best_time(lambda: law_profile_lstsq(*args[:3]),
                                                  repeats=20))
        out['same_profile'].append(bool(np.allclose(
            timing.law_profile(*args[:3]), law_profile_lstsq(*args[:3]), rtol=1e-12,
            atol=1e-12, equal_nan=True)))
        ch = cnn.channels(x['op'], x['pv'], x['sp'])
        out['network'].append(best_time(lambda: cnn.symmetric_logit(large, ch, integ)))
        out['network_einsum'].append(best_time(
            lambda: cnn.symmetric_logit(large, ch, integ, cnn.conv1d_reference)))
        out['same_logit'].append(cnn.symmetric_logit(large, ch, integ) == cnn.symmetric_logit(
            large, ch, integ, cnn.conv1d_reference))
        out['network_wide'].append(best_time(lambda: cnn.symmetric_logit(wide, ch, integ)))
        regressions.append(_lag_sum_args(x['op'], x['pv'], integ))
        held.append((x['op'], x['pv'], rec.sample_time, integ))
        fit, paths = _pe_paths(x['op'], x['pv'], integ)
        out['pe_fit'].append(best_time(lambda: [fit.rss(p)[0] for p in paths]))
        out['pe_fit_lstsq'].append(best_time(lambda: [rss_lstsq(fit, p) for p in paths]))
        out['same_pe'].append(bool(np.allclose([fit.rss(p)[0] for p in paths],
                                               [rss_lstsq(fit, p) for p in paths],
                                               rtol=1e-12, atol=0.0)))
        out['samples'].append(len(x['op']))
    # Last: both are built ahead of time, as the detector's kernels are, but an
    # argument off their signatures would load numba, whose code for this
    # processor would speed every kernel timed after it beyond what an analysis gets.
    for sums in regressions:
        out['lag_sums'].append(best_time(lambda: lag_sums(*sums), repeats=20))
        out['lag_sums_rows'].append(best_time(lambda: lag_sums_reference(*sums), repeats=20))
        out['same_sums'].append(all(a.tobytes() == b.tobytes() for a, b in zip(
            lag_sums(*sums), lag_sums_reference(*sums))))
    for op, pv, ts, integ in held:
        out['quantify'].append(best_time(lambda: quantify(op, pv, ts, integrating=integ)))
    return out


def _lag_sum_args(op, pv, integ):
    # The detector's regression of this record, and one valve path (S 2 % of OP's
    # travel, J half of it) through it.
    op, pv = np.asarray(op, dtype=np.float64), np.asarray(pv, dtype=np.float64)
    prob = HammersteinProblem(op, pv, [(0, len(op))], integ, (2, 2), 1, HAM_MAX_DELAY)
    s = 0.02 * float(np.ptp(op))
    v = segment_path(np.ascontiguousarray(prob.op), s, 0.5 * s, 0, 0.5) - prob.ubar
    nl = prob.dhi - prob.dlo + prob.nb
    return (v, prob.rows, prob.row_seg, prob.qy, prob.tres, prob.dlo, nl, prob.nb,
            len(prob.seg_rows))


def _ratio(v: float) -> str:
    return f'{v:.2g}' if v < 10 else f'{v:.0f}'


def markdown(r):
    """Return the section's lines."""
    med = {k: float(np.median(r[k])) for k in STEPS}
    mx = {k: float(np.max(r[k])) for k in STEPS}
    same = sum(r['same_logit'])
    return [MARKERS[0], '## Stiction detector: cost per record', '',
            f'`make bench-detector`, {datetime.date.today().isoformat()}, '
            f'{machine_description()}. {len(r["samples"])} plant loops of median '
            f'{int(np.median(r["samples"]))} samples, one core, best of 3.', '',
            '| step | median ms | max ms | ratio to the old rule (median) |',
            '|---|---|---|---|',
            *[f'| {name} | {1e3 * med[k]:.3g} | {1e3 * mx[k]:.3g} | '
              f'{_ratio(med[k] / med["old_rule"])} |' for k, name in STEPS.items()],
            '', 'The clock-skew check costs '
            f'{med["clock_check"] / med["detector"]:.1%} of the detector (median); its '
            "law's R² at the 11 shifts, fitted in one compiled pass, takes "
            f'{med["law_profile"] / med["law_profile_lstsq"]:.2f} of the time one '
            'least-squares call per shift took (median; the same R² to 1e-12 on '
            f'{sum(r["same_profile"])} of {len(r["same_profile"])} records). '
            'Most of the time of the detector is its coarse Hammerstein fit (a sticky valve '
            'before an ARX plant), which was the strongest single separator on simulated '
            'loops. The compiled convolution makes the network '
            f'{med["network_einsum"] / med["network"]:.1f} times as fast as with einsum '
            f'(median; the same logit to the bit on {same} of the {len(r["same_logit"])} '
            'records). Summed lag by lag, the Hammerstein lag sums take '
            f'{med["lag_sums"] / med["lag_sums_rows"]:.2f} of the time they took row by row '
            f'(median; the same sums to the bit on {sum(r["same_sums"])} of '
            f'{len(r["same_sums"])} records). The prediction-error fits take '
            f'{med["pe_fit"] / med["pe_fit_lstsq"]:.2f} of the time one least-squares call per '
            f'window took (median; the same residuals to 1e-12 on {sum(r["same_pe"])} of '
            f'{len(r["same_pe"])} records). The wider network would cost '
            f'{med["network_wide"] / med["network"]:.1f} times the shipped one (median), in '
            "every analysis and in the study's network logits.", MARKERS[1]]


def main():
    """Run the benchmark and write its section of docs/BENCHMARKS.md."""
    from bench.run_all import best_time
    lines = markdown(bench_detector(best_time))
    write_section(lines, BENCH, MARKERS)
    print('\n'.join(lines))
    return 0


if __name__ == '__main__':
    sys.exit(main())
