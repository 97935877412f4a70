"""
``--explain`` run blind on closed loops hiding instrument and timing effects.

Each case is a closed loop of ``stiction_ros.sim.instrument_cases`` (dead time,
response lag, positioner calibration, rate limit, travel stop, backlash,
transmitter quantisation, stiction, alone or in pairs, or nothing), written to
a CSV holding only what a plant historian gives (t, sp, pv, op, mv) and analysed by
``stiction-analyze --explain`` in a worker process that never sees the truth.
A case is right when the analyzer claims friction exactly when stiction is
hidden and names exactly the hidden instrument effects.

Seeds: 600000 and up are the development seeds (look at and tune on those);
700000 and up (the default) are the scoring seeds nobody tuned on.  Every case
name runs the same seeds, and a seed draws the same loop in samples for every
case, so the cases of one seed differ only in what is hidden.  Sample time and
noise cycle over the runs in order (case by case, seed by seed).

    python -m bench.instrument_bench [--per-case N] [--seeds-from S] [--jobs J]
                                     [--markdown docs/EXPLAIN_BENCHMARK.md]
"""

import argparse
from collections import Counter
from concurrent.futures import as_completed, ProcessPoolExecutor
import contextlib
import datetime
import io
import json
import math
import os
from pathlib import Path
import sys
import tempfile
import time

from bench import load_bench
import numpy as np

from stiction_ros.cli.study import machine_description
from stiction_ros.sim.instrument_cases import CASES, EFFECTS, instrument_case

ROOT = Path(__file__).resolve().parents[1]
SAMPLE_TIMES = (0.1, 0.5, 1.0, 2.0, 5.0)
NOISES = (0.5, 1.0, 2.0)
START, END = '<!-- instrument-bench:start -->', '<!-- instrument-bench:end -->'


def case_list(per_case: int, seeds_from: int = 700000) -> list[dict]:
    """Return every run as a dict: case, seed, sample_time, noise."""
    runs = []
    for case in CASES:
        for i in range(per_case):
            k = len(runs)
            runs.append({'case': case, 'seed': seeds_from + i,
                         'sample_time': SAMPLE_TIMES[k % len(SAMPLE_TIMES)],
                         'noise': NOISES[k % len(NOISES)]})
    return runs


def _holdout(section):
    value = section.get('mse_holdout') if isinstance(section, dict) else None
    return float(value) if isinstance(value, (int, float)) else None


def score(run: dict, truth: dict, report: dict) -> dict:
    """Return the scored row of one run from its truth and the analyzer's JSON report."""
    m = report.get('mismatch') if isinstance(report.get('mismatch'), dict) else {}
    friction = m.get('friction')
    friction = friction if isinstance(friction, bool) else None
    effects = m.get('effects')
    found = None
    if isinstance(effects, list) and all(isinstance(e, dict) and 'id' in e for e in effects):
        found = sorted({str(e['id']) for e in effects})
    # Missing keys score as wrong: an analysis that does not say cannot be right.
    correct = (friction is not None and found is not None and friction == truth['friction']
               and found == truth['effects'])
    false_alarm = None
    if not truth['effects']:
        false_alarm = (friction is None or found is None or bool(found)
                       or (friction and not truth['friction']))
    final = _holdout(m)
    refs = [v for v in (_holdout(report.get('baseline')), _holdout(report.get('frictionless')))
            if v is not None]
    ratio = final / min(refs) if final is not None and refs and min(refs) > 0 else None
    kano = _holdout(report.get('baseline'))
    vs_plain = final / kano if final is not None and kano else None
    return {**run, 'truth_friction': truth['friction'], 'truth_effects': truth['effects'],
            'sizes': truth['sizes'], 'friction': friction, 'found': found,
            'found_detail': effects if found is not None else None,
            'named': m.get('effect'), 'correct': correct, 'false_alarm': false_alarm,
            'kano_holdout': _holdout(report.get('baseline')),
            'frictionless_holdout': _holdout(report.get('frictionless')),
            'final_holdout': final, 'ratio': ratio, 'vs_plain': vs_plain,
            'explain_s': report.get('explain_seconds')}


def run_case(run: dict) -> dict:
    """Simulate one run, analyse its CSV blind, return the scored row."""
    from stiction_ros.cli.analyze import main as analyze
    from stiction_ros.sim.closed_loop import write_csv
    t0 = time.perf_counter()
    record, truth = instrument_case(run['case'], run['seed'], sample_time=run['sample_time'],
                                    noise=run['noise'])
    sim = time.perf_counter() - t0
    with tempfile.TemporaryDirectory() as tmp:
        csv = Path(tmp) / 'loop.csv'
        write_csv(csv, {k: record[k] for k in ('t', 'sp', 'pv', 'op', 'mv')},
                  columns=('t', 'sp', 'pv', 'op', 'mv'))
        out = Path(tmp) / 'report.json'
        t0 = time.perf_counter()
        with contextlib.redirect_stdout(io.StringIO()):
            # One thread per case: the cases themselves run side by side.
            code = analyze([str(csv), '--explain', '--quiet', '--json', str(out), '--jobs', '1'])
        wall = time.perf_counter() - t0
        report = json.loads(out.read_text()) if code == 0 and out.exists() else {}
    row = score(run, truth, report)
    row.update(sim_s=round(sim, 3), wall_s=round(wall, 2), exit=code)
    if code != 0:
        row['found'] = row['friction'] = None
    return row


def finding(row: dict) -> str:
    """Return what the analyzer said of one run in words: friction and the effect ids."""
    if row['exit'] != 0:
        return f'error (exit {row["exit"]})'
    if row['friction'] is None or row['found'] is None:
        return 'keys missing'
    words = (['friction'] if row['friction'] else []) + row['found']
    return ' + '.join(words) or 'nothing'


def truth_words(row: dict) -> str:
    """Return what a run hid in words."""
    return ' + '.join((['friction'] if row['truth_friction'] else [])
                      + row['truth_effects']) or 'nothing'


def _num(x, fmt='.3f'):
    return '-' if x is None else format(x, fmt)


def coverage(rows: list[dict]) -> dict:
    """
    Return ``{effect: (within, named)}``: named sizes within two stated errors of the truth.

    A stated error holds the truth about 95 % of the time if it is honest; one
    far under that says the error is too narrow (a calibration is compared by
    its offset at OP 0, a rate limit by its rate in % per second).
    """
    out: dict = {}
    for r in rows:
        for e in r.get('found_detail') or ():
            truth, unc = r['sizes'].get(e.get('id')), e.get('uncertainty')
            if truth is None or unc is None or not math.isfinite(unc) or e.get('size') is None:
                continue
            if isinstance(truth, dict):
                truth = truth.get('offset', truth.get('rate_pct_s'))
            if not isinstance(truth, (int, float)):
                continue
            within, named = out.get(e['id'], (0, 0))
            out[e['id']] = (within + (abs(e['size'] - truth) <= 2.0 * unc), named + 1)
    return out


def section(rows: list[dict], elapsed: float, jobs: int, per_case: int,
            seeds_from: int) -> str:
    """Return the markdown text to put between the markers, for the rows."""
    ids = list(EFFECTS) + sorted({i for r in rows for i in (r['found'] or ())} - set(EFFECTS))
    right = sum(r['correct'] for r in rows)
    lines = [
        START, '## Instrument and timing effects (`bench/instrument_bench.py`)', '',
        f'Machine: {machine_description()}. Date: {datetime.date.today().isoformat()}.',
        f'Command: `python -m bench.instrument_bench --per-case {per_case} --seeds-from '
        f'{seeds_from} --jobs {jobs}` ({len(rows)} runs, {elapsed / 60:.1f} min in all).',
        f'Seeds {seeds_from} to {seeds_from + per_case - 1} for every case (scoring seeds '
        'from 700000 are never tuned on; 600000 and up are the development seeds).', '',
        'Each run is an 8 641-sample closed loop from `stiction_ros/sim/instrument_cases.py`: a '
        'random FOPDT or integrating plant under SIMC PI, set-point and load steps, noise on '
        'PV and MV (0.5, 1 or 2 times: MV noise 0.05, 0.1, 0.2 %), at a sample time of 0.1, '
        '0.5, 1, 2 or 5 s (the loop scaled to look alike in samples). The instrument effects '
        'are drawn in seconds or % (dead time 0.5-3 s, at least 0.5 sample; lag 1-5 s, at '
        'least 0.7 sample; offset 0.5-3 %, gain error 2-6 %; backlash 1-4 %; resolution '
        '0.25-1 %; rate limit 0.15-0.4 of the largest OP change in a sample; travel stop at '
        'the 95-99 % quantile of the position, high or low); stiction is Kano S 2-5 %, J '
        '0.2-0.6 S. Right: friction claimed exactly '
        'when hidden and exactly the hidden effects named.', '',
        '### What was found (rows: hidden; counts over the runs; bold: hidden there)', '',
        '| case | hidden | runs | friction | ' + ' | '.join(f'`{i}`' for i in ids)
        + ' | missing/error | right |', '|---|---|---|---|' + '---|' * len(ids) + '---|---|']
    for case in dict.fromkeys(r['case'] for r in rows):
        sub = [r for r in rows if r['case'] == case]
        hidden = set(sub[0]['truth_effects']) | ({'friction'} if sub[0]['truth_friction']
                                                 else set())
        counts = Counter(i for r in sub for i in (r['found'] or ()))
        counts['friction'] = sum(bool(r['friction']) for r in sub)
        cells = [(f'**{counts[i]}**' if i in hidden else str(counts[i])) if counts[i] or
                 i in hidden else '.' for i in ['friction'] + ids]
        bad = sum(r['found'] is None or r['friction'] is None for r in sub)
        ok = sum(r['correct'] for r in sub)
        lines.append(f'| `{case}` | {truth_words(sub[0])} | {len(sub)} | ' + ' | '.join(cells)
                     + f' | {bad or "."} | {ok}/{len(sub)} |')
    clean = [r for r in rows if r['false_alarm'] is not None]
    lines += ['', '### Summary', '',
              f'- Right overall: {right}/{len(rows)} ({100 * right / max(len(rows), 1):.0f} %).']
    for case in ('clean_linear', 'clean_sticky'):
        sub = [r for r in clean if r['case'] == case]
        if sub:
            lines.append(f'- False alarms on `{case}`: {sum(r["false_alarm"] for r in sub)}/'
                         f'{len(sub)} (an effect named, friction claimed where there is none, '
                         'or no answer).')
    vs_f = [r['final_holdout'] <= r['frictionless_holdout'] * (1 + 1e-9) for r in rows
            if r.get('final_holdout') is not None and r.get('frictionless_holdout')]
    lines.append(f'- Final model no worse on held-out data than the best valve without '
                 f'friction: {sum(vs_f)}/{len(vs_f)} runs.')
    hidden = [r['vs_plain'] for r in rows if (r['truth_effects'] or r['truth_friction'])
              and r.get('vs_plain') is not None]
    if hidden:
        lines.append(f'- Held-out MSE against the plain Kano model, runs that hide something: '
                     f'median {np.median(hidden):.3f} (best {min(hidden):.3f}, worst '
                     f'{max(hidden):.3f}).')
    cov = coverage(rows)
    if cov:
        lines.append('- Named sizes within two stated standard errors of the hidden value '
                     '(about 95 % if the errors are honest): ' + ', '.join(
                         f'{k} {w}/{n}' for k, (w, n) in sorted(cov.items())) + '.')
    ex = [r['explain_s'] for r in rows if r.get('explain_s') is not None]
    if ex:
        lines.append(f'- `--explain` time per run: median {np.median(ex):.1f} s, max '
                     f'{max(ex):.1f} s (one thread, two runs side by side on 2 cores).')
    lines += ['', '### Per case: right share, held-out MSE ratio and time', '',
              'Ratio: held-out MSE of the final model over the better of the plain Kano model '
              'and the best frictionless valve (above 1: worse than a baseline). Against '
              'plain Kano: over the plain Kano model alone, what a stiction-only tool would '
              'give. Time: `--explain` alone and the whole analyzer (main fits, detection, '
              'report), one thread, two runs side by side on 2 cores.', '',
              '| case | right | median ratio | worst ratio | median against plain Kano | '
              'median `--explain` s | max `--explain` s | median analyzer s |',
              '|---|---|---|---|---|---|---|---|']
    for case in dict.fromkeys(r['case'] for r in rows):
        sub = [r for r in rows if r['case'] == case]
        ratios = [r['ratio'] for r in sub if r['ratio'] is not None]
        secs = [r['wall_s'] for r in sub]
        plain = [r['vs_plain'] for r in sub if r.get('vs_plain') is not None]
        ex = [r['explain_s'] for r in sub if r.get('explain_s') is not None]
        lines.append(f'| `{case}` | {sum(r["correct"] for r in sub)}/{len(sub)} | '
                     f'{_num(np.median(ratios) if ratios else None)} | '
                     f'{_num(max(ratios) if ratios else None)} | '
                     f'{_num(np.median(plain) if plain else None)} | '
                     f'{_num(np.median(ex) if ex else None)} | '
                     f'{_num(max(ex) if ex else None)} | {np.median(secs):.1f} |')
    lines += ['', '### Every run', '',
              '| case | seed | Ts s | noise | hidden sizes | found | found sizes | right | ratio '
              '| s |', '|---|---|---|---|---|---|---|---|---|---|']
    for r in rows:
        sizes = ', '.join(f'{k} {_sizes(v)}' for k, v in r['sizes'].items()) or '-'
        found = ', '.join(f'{e.get("id")} {_sizes(e.get("size"))} {e.get("unit") or ""}'.strip()
                          for e in r['found_detail'] or ()) or '-'
        lines.append(f'| `{r["case"]}` | {r["seed"]} | {r["sample_time"]} | {r["noise"]} | '
                     f'{sizes} | {finding(r)} | {found} | {"yes" if r["correct"] else "no"} | '
                     f'{_num(r["ratio"])} | {r["wall_s"]:.1f} |')
    return '\n'.join(lines + [END]) + '\n'


def _sizes(v):
    if isinstance(v, dict):
        return '/'.join(_sizes(x) for x in v.values())
    return f'{v:.3g}' if isinstance(v, (int, float)) else '?'


def write_section(path: str | Path, text: str) -> None:
    """Put ``text`` between the markers of ``path``: replace the old section, else append."""
    load_bench.write_section(text.rstrip('\n').splitlines(), Path(path), (START, END))


def main(argv: list[str] | None = None) -> int:
    """Run every case over the seeds (in parallel) and write the section and the rows."""
    p = argparse.ArgumentParser(description=__doc__.split('\n')[1])
    p.add_argument('--per-case', type=int, default=4, help='seeds per case (default 4)')
    p.add_argument('--seeds-from', type=int, default=700000,
                   help='first seed (default 700000, the scoring seeds; 600000+: development)')
    p.add_argument('--jobs', type=int, default=os.cpu_count() or 1)
    p.add_argument('--cases', nargs='*', choices=CASES, help='only these cases (default: all)')
    p.add_argument('--markdown', default=str(ROOT / 'docs' / 'EXPLAIN_BENCHMARK.md'))
    p.add_argument('--json', dest='json_path',
                   default=str(ROOT / 'docs' / 'instrument_bench.json'))
    args = p.parse_args(argv)
    if args.per_case < 1 or args.jobs < 1 or args.seeds_from < 0:
        p.error('--per-case and --jobs must be at least 1, --seeds-from at least 0')
    runs = case_list(args.per_case, args.seeds_from)
    if args.cases:
        runs = [r for r in runs if r['case'] in args.cases]
    t0 = time.perf_counter()
    rows = []
    with ProcessPoolExecutor(max_workers=args.jobs) as pool:
        futures = {pool.submit(run_case, run): i for i, run in enumerate(runs)}
        for future in as_completed(futures):
            row = {**future.result(), 'order': futures[future]}
            rows.append(row)
            print(f'[{len(rows)}/{len(runs)}] {row["case"]} seed {row["seed"]} Ts '
                  f'{row["sample_time"]} noise {row["noise"]}: {finding(row)} '
                  f'{"ok" if row["correct"] else "MISS"} ratio {_num(row["ratio"])} '
                  f'({row["wall_s"]:.1f} s)', file=sys.stderr, flush=True)
    elapsed = time.perf_counter() - t0
    rows.sort(key=lambda r: r.pop('order'))
    Path(args.json_path).write_text(json.dumps(rows, indent=1) + '\n')
    write_section(args.markdown, section(rows, elapsed, args.jobs, args.per_case,
                                         args.seeds_from))
    print(f'wrote {args.markdown} and {args.json_path} ({elapsed / 60:.1f} min)')
    return 0


if __name__ == '__main__':
    sys.exit(main())
