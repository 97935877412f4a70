"""
Score the stiction verdict on held-out data and write docs/ACCURACY.md (``make accuracy``).

    python -m stiction_ros.cli.accuracy [DATA_DIR] [--reports out/plant_loops]
                                        [--markdown docs/ACCURACY.md] [--sim-test N]
                                        [--json docs/accuracy.json] [--render-only]

DATA_DIR holds ``stiction/`` and ``no_stiction/`` folders of recordings (by
default the shared plant loops).  Every file is analysed by the same code as
``stiction-analyze`` and its JSON and HTML reports are written under
``--reports``.  Then the simulated test set (seeds never used for training
or tuning) is drawn and scored.  See ``stiction_ros.study.accuracy_study``
for the protocol.  ``--render-only`` scores nothing: it rewrites the page
from the JSON a previous run wrote (after a change to how the page reads).
"""

import argparse
import datetime
import json
import os
from pathlib import Path
import platform
import re
import sys
import time

import numpy as np

from stiction_ros._blas import kernels
from stiction_ros.analysis.detection import cnn, dataset, deadband_like, FEATURE_NAMES, \
    load_model, stack
from stiction_ros.app.analyze import analyze_file, AnalyzeOptions
from stiction_ros.cli.accuracy_markdown import markdown
from stiction_ros.cli.text import description, pipe_safe
from stiction_ros.study.accuracy import cross_validate, signature_alone, SIGNATURES
from stiction_ros.study.accuracy_study import (
    band_answer, BANDED, best_threshold, by_kind, FORCED, per_tag, reliability, score,
    SHIPPED, sim_rows, THRESHOLD, threshold_by_tag)

# Beside a checkout of the project, where the shared data live.
DEFAULT_DATA = Path(__file__).resolve().parents[3] / 'shared' / 'data' / 'plant_loops'


def loop_group(name):
    """Return the loop tag that groups files of the same valve (the historian tag)."""
    return re.sub(r'^(RHT\.|2#)?', '', name or '')


def analyse_all(data_dir, reports):
    """Return a list of cases: label, group, file, report and signatures of every file."""
    cases = []
    files = [(lab, f) for lab in ('stiction', 'no_stiction')
             for f in sorted((Path(data_dir) / lab).glob('*')) if f.is_file()
             and f.suffix.lower() in ('.txt', '.csv')]
    for i, (lab, f) in enumerate(files, 1):
        print(f'[{i}/{len(files)}] {lab}/{f.name}', file=sys.stderr, flush=True)
        out = Path(reports) / lab / f.stem
        options = AnalyzeOptions(input=str(f), json_path=str(out) + '.json',
                                 html_path=str(out) + '.html')
        t0 = time.perf_counter()
        a = analyze_file(options)
        cases.append({'label': lab == 'stiction', 'group': loop_group(a.record.name),
                      'file': f.name, 'report': a.report, 'seconds': time.perf_counter() - t0,
                      'oscillation': a.oscillation, 'signatures': a.signatures})
    return cases


def _stuck_answers(cases, threshold):
    out = []
    for c in cases:
        det = c['report']['stiction'].get('detector') or {}
        v = (det.get('features') or {}).get('stuck_op_share')
        out.append(None if v is None else bool(v >= threshold))
    return out


def plant_thresholds(cases) -> tuple:
    """Return (answers, {tag: threshold}) of the detector's threshold chosen on the other tags."""
    probability = [c['report']['stiction'].get('probability') for c in cases]
    return threshold_by_tag([c['group'] for c in cases], [c['label'] for c in cases],
                            probability)


def plant_rows(cases, cv_pred, stuck_threshold, by_tag_pred=None):
    """Return {method: score} on the plant loops."""
    truth = [c['label'] for c in cases]
    # A record the detector judged has a probability; one it could not has none.
    p = [c['report']['stiction'].get('probability') for c in cases]
    old = [bool(c['report']['stiction'].get('signature_vote', {}).get('detected'))
           for c in cases]
    # The row of the answers the analyzer prints is in bold.
    name = {k: (f'**learned detector**, {k}' if k == SHIPPED else f'learned detector, {k}')
            for k in (FORCED, BANDED)}
    rows = {name[FORCED] + ' (trained on simulation only)':
            score(truth, [None if v is None else bool(v >= THRESHOLD) for v in p]),
            name[BANDED]: score(truth, [None if v is None else band_answer(v) for v in p]),
            'old rule (signature vote, published weights)': score(truth, old),
            'old rule, voters and threshold chosen leave-one-tag-out': score(truth, cv_pred),
            **({} if by_tag_pred is None else {
                'learned detector, probability threshold chosen leave-one-tag-out':
                score(truth, by_tag_pred)}),
            f'stuck-period test alone (OP share >= {stuck_threshold:.3g}, set on simulation)':
            score(truth, _stuck_answers(cases, stuck_threshold))}
    for name in SIGNATURES:
        rows[f'{name} alone (published threshold)'] = score(truth,
                                                            signature_alone(cases, name))
    return rows


@pipe_safe
def main(argv=None):
    """Entry point."""
    p = argparse.ArgumentParser(prog='stiction-accuracy', description=description(__doc__))
    p.add_argument('data', nargs='?', default=str(DEFAULT_DATA))
    p.add_argument('--reports', default='out/plant_loops')
    p.add_argument('--markdown', default='docs/ACCURACY.md')
    p.add_argument('--json', default='docs/accuracy.json')
    p.add_argument('--sim-test', type=int, default=len(dataset.TEST),
                   help=f'simulated test records (seeds from {dataset.TEST.start})')
    p.add_argument('--sim-calibration', type=int, default=len(dataset.CALIBRATION),
                   help='simulated records on which the stuck-period threshold is set')
    p.add_argument('--jobs', type=int, default=os.cpu_count() or 1)
    p.add_argument('--cache', default='out/detector_cache',
                   help='folder of cached simulated features (shared with make detector)')
    p.add_argument('--render-only', action='store_true',
                   help='score nothing: rewrite --markdown from the study in --json '
                        '(the data and scoring options are then ignored)')
    args = p.parse_args(argv)
    if args.render_only:
        return _render(args.json, args.markdown)
    if not Path(args.data).is_dir():
        print(f'stiction-accuracy: error: {args.data} is not a folder', file=sys.stderr)
        return 2
    model = load_model()
    say = (lambda m: print(m, file=sys.stderr, flush=True))
    say(f'simulated calibration records for the single-test thresholds: {args.sim_calibration}')
    cal = dataset.build(range(dataset.CALIBRATION.start,
                              dataset.CALIBRATION.start + args.sim_calibration), args.jobs,
                        cache=args.cache or None)
    stuck_th = best_threshold(cal['x'][:, FEATURE_NAMES.index('stuck_op_share')], cal['y'])
    cases = analyse_all(args.data, args.reports)
    cv_pred, _ = cross_validate(cases)
    by_tag_pred, by_tag_threshold = plant_thresholds(cases)
    say(f'simulated test set: {args.sim_test} records (seeds {dataset.TEST.start}-'
        f'{dataset.TEST.start + args.sim_test - 1})')
    test = dataset.build(range(dataset.TEST.start, dataset.TEST.start + args.sim_test),
                         args.jobs, cache=args.cache or None)
    if model.stack is not None:
        say('the large network on the simulated test set')
        test['large_logit'] = stack.seed_logits(test['seed'], args.jobs,
                                                cache=args.cache or None)
    say('sticky test records that OP and PV cannot tell from a deadband (left out, counted)')
    whole = deadband_like.mark(test, args.jobs, cache=args.cache or None)
    test = deadband_like.leave_out(whole)
    called = model.probability(whole['x'], whole.get('large_logit')) >= 0.5
    study = {
        'date': datetime.date.today().isoformat(),
        'machine': f'{platform.node()} ({platform.machine()}, {os.cpu_count()} cores, '
                   f'Python {platform.python_version()})',
        # What this run's figures ran on (the Makefile pins NumPy's code).
        'kernels': kernels(),
        'data': str(args.data), 'model': model.meta, 'cnn': cnn.load().meta,
        'cnn_large': None if model.stack is None else stack.network().meta,
        'stuck_threshold': stuck_th,
        'plant': plant_rows(cases, cv_pred, stuck_th, by_tag_pred),
        'plant_threshold_by_tag': by_tag_threshold,
        'plant_tags': per_tag(cases, [c['report']['stiction']['detected'] for c in cases]),
        'plant_seconds': [round(c['seconds'], 3) for c in cases],
        'sim': sim_rows(test, model, stuck_th), 'sim_kinds': by_kind(test, model),
        'sim_reliability': reliability(test['y'], model.probability(
            test['x'], test.get('large_logit'))) if len(test['y']) else None,
        'sim_skipped': test['skipped'], 'sim_records': int(len(test['y'])),
        # The definition before 2026-11-27 counted deadband-like records as sticky.
        'sim_with_deadband_like': score(whole['y'], list(called)),
        'sim_deadband_like_called': int(called[whole['deadband_like']].sum()),
        'sim_seconds': round(test['seconds'], 1), 'sim_jobs': args.jobs,
        'sim_seeds': [dataset.TEST.start, dataset.TEST.start + args.sim_test],
        'cases': [{'file': c['file'], 'label': c['label'], 'group': c['group'],
                   'answer': c['report']['stiction'].get('answer'),
                   'probability': c['report']['stiction'].get('probability'),
                   'old_rule': (c['report']['stiction'].get('signature_vote') or {})
                   .get('detected'), 'cv_old_rule': p_,
                   'reason': c['report']['stiction'].get('reason'),
                   'evidence': c['report']['stiction'].get('evidence', [])[:3]}
                  for c, p_ in zip(cases, cv_pred)],
    }
    Path(args.markdown).write_text(markdown(study), encoding='utf-8')
    Path(args.json).write_text(json.dumps(study, indent=2, default=_plain) + '\n',
                               encoding='utf-8')
    print(Path(args.markdown).read_text(encoding='utf-8'))
    return 0


def _render(json_path: str, markdown_path: str) -> int:
    try:
        study = json.loads(Path(json_path).read_text(encoding='utf-8'))
        if not (isinstance(study, dict) and isinstance(study.get('plant'), dict)
                and study['plant'] and isinstance(study.get('sim'), dict)
                and isinstance(study.get('cases'), list)):
            raise ValueError('not a study written by make accuracy (plant, sim, cases)')
        page = markdown(study)
    except (OSError, ValueError, KeyError, TypeError, IndexError, AttributeError) as e:
        print(f'stiction-accuracy: error: cannot render {json_path}: '
              f'{type(e).__name__}: {e}', file=sys.stderr)
        return 2
    out = Path(markdown_path)
    # Whole or not at all: the page is replaced only once written.
    tmp = out.with_name(out.name + '.tmp')
    try:
        tmp.write_text(page, encoding='utf-8')
        tmp.replace(out)
    except OSError as e:
        print(f'stiction-accuracy: error: cannot write {markdown_path}: {e}', file=sys.stderr)
        return 2
    print(f'wrote {markdown_path} from {json_path}')
    return 0


def _plain(v):
    if isinstance(v, (np.integer, np.floating, np.bool_)):
        return v.item()
    raise TypeError(f'not JSON-able: {type(v)}')


if __name__ == '__main__':
    sys.exit(main())
