"""The text of docs/ACCURACY.md from the study dict that ``stiction_ros.cli.accuracy`` builds."""

from stiction_ros.analysis.detection import probability_text
from stiction_ros.cli.text import figure
from stiction_ros.study.accuracy import balanced_accuracy, confusion
from stiction_ros.study.accuracy_study import band_answer, BANDED, FORCED, SHIPPED, THRESHOLD
from stiction_ros.study.intervals import class_interval, DRAWS, exact_interval, LEVEL, \
    percentile_interval, SEED, tag_draws


def _f(v, digits=2):
    # Two decimals unless told: the accuracy page's own precision.
    return figure(v, digits)


HEAD = ('| method | TP | FN | FP | TN | cannot tell (sticky / healthy) | balanced accuracy | '
        'balanced accuracy on decided (share decided) |')
RULE = '|---|---|---|---|---|---|---|---|'


def table(rows: dict) -> list:
    """Return the markdown lines of a {method: score} table."""
    out = [HEAD, RULE]
    for name, s in rows.items():
        if s is None:
            continue
        out.append(f'| {name} | {s["tp"]} | {s["fn"]} | {s["fp"]} | {s["tn"]} | '
                   f'{s["cannot_tell_sticky"]} / {s["cannot_tell_healthy"]} | '
                   f'{_f(s["balanced_accuracy"])} | {_f(s["balanced_accuracy_decided"])} '
                   f'({100 * s["decided_share"]:.0f} %) |')
    return out


def _cnn_line(meta: dict | None, what: str = "The detector's 1-D CNN (`make cnn`)") -> list:
    if not meta:
        return []
    fig = meta.get('figures', {})
    seeds = meta.get('corpus_seeds', ['-', '-'])
    return [f'- {what}: {meta.get("records", "-")} simulated '
            f'records of seeds {seeds[0]}-{seeds[1] - 1 if isinstance(seeds[1], int) else "-"}, '
            f'{fig.get("epochs", "-")} epochs in {fig.get("train_s", "-")} s (PyTorch '
            f'{fig.get("torch", "-")}, {_where(fig)}).']


def _where(fig: dict) -> str:
    # Networks before 2026-11-27 were trained on the CPU and kept only the thread count.
    if 'device' in fig:
        return str(fig['device'])
    return f'cpu, {fig.get("torch_threads", "-")} threads'


def _p(v):
    return '-' if v is None else probability_text(v)


def _reliability(rel: dict | None) -> list:
    if not rel:
        return []
    return [
        "Does the probability mean what it says? The learned detector's stated probability "
        'on these records against the share of them that stick, at even odds (each class '
        f'weighing half, as in calibration). Class-balanced log loss {_f(rel["log_loss"], 3)}, '
        f'Brier score {_f(rel["brier"], 4)}.',
        '',
        '| stated probability | records | sticky | mean stated | observed at even odds |',
        '|---|---|---|---|---|',
        *[f'| {lo:g}-{hi:g} | {n} | {k} | {probability_text(s)} | {probability_text(o)} |'
          for lo, hi, n, k, s, o in rel['rows']],
        '',
    ]


def _deadband_like(study: dict) -> list:
    whole = study.get('sim_with_deadband_like')
    n = (study.get('sim_skipped') or {}).get('stiction_as_deadband')
    if not whole or n is None:
        return []
    return [
        f'Left out above: {n} sticky records whose slip moves PV by less than its noise '
        'against the nearest deadband (`deadband_like.py`): from OP and PV they are a '
        'deadband, which the issue counts as a look-alike. The detector called '
        f'{study["sim_deadband_like_called"]} of them stiction. Counted as sticky, as the '
        'scoring did until 2026-11-27: balanced accuracy '
        f'{_f(whole["balanced_accuracy"], 3)} ({whole["tp"]}/{whole["tp"] + whole["fn"]} '
        f'sticky found, {whole["fp"]}/{whole["fp"] + whole["tn"]} healthy flagged).',
        '',
    ]


def _by_tag(chosen: dict | None) -> list:
    if not chosen:
        return []
    values = sorted(set(chosen.values()))
    counts = {v: sum(c == v for c in chosen.values()) for v in values}
    folds = '; '.join(f'{v:.3g} ({n} fold{"s" * (n > 1)})' for v, n in counts.items())
    return [f'Probability thresholds the folds chose on the other tags: {folds}.', '']


def _span(lo: float, hi: float, digits: int = 2) -> str:
    return f'{100 * LEVEL:.0f} % interval {_f(lo, digits)}-{_f(hi, digits)}'


def plant_calls(study: dict) -> dict:
    """
    Return {plant table row: per-file calls} for the rows the page gives intervals.

    Recomputed from the per-file answers in ``study['cases']`` (so the page
    can be rebuilt from the JSON alone); a refusal is not a call.
    """
    cases = study['cases']
    p = [c['probability'] for c in cases]
    out = {}
    for key in study['plant']:
        if FORCED in key and 'trained on simulation only' in key:
            out[key] = [v is not None and v >= THRESHOLD for v in p]
        elif key.endswith(BANDED):
            out[key] = [v is not None and band_answer(v) is True for v in p]
        elif key == 'old rule (signature vote, published weights)':
            out[key] = [bool(c['old_rule']) for c in cases]
    return out


def _plant_intervals(study: dict, healthy: int, flagged: int) -> list:
    cases = study['cases']
    y = [bool(c['label']) for c in cases]
    groups = [c['group'] for c in cases]
    parts, no_false_alarm = [], True
    for key, called in plant_calls(study).items():
        values = tag_draws(y, called, groups)
        lo, hi = percentile_interval(values)
        full = ' (the full range of the draws)' if (lo, hi) == (values.min(), values.max()) \
            else ''
        parts.append(f'{key.replace("**", "")}: '
                     f'{_f(balanced_accuracy(confusion(y, called)))}, {_span(lo, hi)}{full}')
        no_false_alarm &= not any(c and not lab for c, lab in zip(called, y))
    n_sticky = len({g for g, lab in zip(groups, y) if lab})
    left_alone = healthy - flagged
    lo, hi = exact_interval(left_alone, healthy) if healthy else (float('nan'),) * 2
    return [f'How much these figures say about other valves: whole valve tags resampled '
            f'({DRAWS} draws, seed {SEED}; a draw without a sticky valve is drawn again), '
            f'since the records of one valve move together. ' + '; '.join(parts) + '. '
            f'The sticky records come from {n_sticky} valves'
            + (', and none of these rows flags a healthy record, so resampling shows no '
               'spread on the healthy side' if no_false_alarm else '')
            + f'. Healthy valves not flagged on most of their records: {left_alone} of '
            f'{healthy}, which puts the share of healthy valves left alone at '
            f'{_f(lo)}-{_f(hi)} (exact, Clopper-Pearson, {100 * LEVEL:.0f} %). A figure '
            'anywhere inside these intervals is consistent with these loops.', '']


def _sim_intervals(study: dict) -> list:
    parts = [f'{name}: {_f(s["balanced_accuracy"], 3)} '
             f'({_span(*class_interval(s), digits=3)})'
             for name, s in study['sim'].items() if s is not None and name.startswith(
                 ('learned detector', 'old rule'))]
    return [f'How far they could move on another draw of as many records ({DRAWS} bootstrap '
            f'draws, each class resampled on its own, seed {SEED}; a class scored without '
            'a miss would show no spread): ' + '; '.join(parts)
            + '.', '']


def markdown(study: dict) -> str:
    """Return the whole page."""
    plant = study['plant']
    first = next(iter(plant.values()))
    n_sticky = first['tp'] + first['fn']
    n_healthy = first['fp'] + first['tn']
    tags = study['plant_tags']
    healthy_tags = [t for t in tags if not t[1]]
    flagged = [t for t in healthy_tags if t[3] > t[2] / 2]
    meta = study['model']
    fig = meta.get('figures', {})
    secs = study['plant_seconds']
    lines = [
        '# Accuracy of the stiction verdict',
        '',
        f'Generated by `make accuracy` on {study["date"]} on {study["machine"]}. '
        f'Detector: `{meta.get("file")}` version {meta.get("version")}, trained '
        f'{meta.get("date")} on {meta.get("trained_on")}. Figures computed with: '
        f'{study.get("kernels", "not recorded")} (the detector\'s: '
        f'{meta.get("kernels", "not recorded")}).',
        '',
        'Positive class = stiction. On the plant loops balanced accuracy counts `cannot '
        'tell` as "no stiction" (a refusal earns nothing), and the last column scores '
        'only the records the method decided on; the simulated set leaves out the records '
        'that cannot be judged (or whose stiction is hidden under the noise, or shows only '
        'as a deadband) and lists them.',
        '',
        f'The learned detector is scored two ways on the same records: its answer at '
        f'{FORCED} (every judgeable record decided), and `{BANDED}`: cannot tell where the '
        'evidence is balanced, an answer only at odds of 3:1 or more (docs/DETECTION.md, '
        f'section 3). The analyzer prints the answers of `{SHIPPED}`.',
        '',
        '## Held out 1: the shared plant loops, by valve tag',
        '',
        f'`{study["data"]}`: {n_sticky} sticky and {n_healthy} healthy records of '
        f'{len(tags)} valves (historian tags). No plant record is used to train, '
        'calibrate or set a threshold of the learned detector or of the stuck-period '
        'test, so each tag is scored by a model that never saw it (leave-one-tag-out '
        'holds by construction). The cross-validated row of the old rule chooses its voters '
        "and threshold on the other tags, fold by fold; so does the learned detector's "
        'cross-validated row for its probability threshold (one number fitted on plant '
        'loops, to measure how far the simulated probability is off there; the verdict '
        'does not use it). Caveat: the features were '
        'designed by engineers who had looked at these trends (not at any score on them); '
        'the plant loops that were never shared are the truly unseen test.',
        '',
        *table(plant),
        '',
        *_plant_intervals(study, len(healthy_tags), len(flagged)),
        *_by_tag(study.get('plant_threshold_by_tag')),
        f'Healthy valves flagged on most of their records: {len(flagged)} of '
        f'{len(healthy_tags)}' + (f' ({", ".join(t[0] for t in flagged)})' if flagged else '')
        + '.',
        '',
        '| tag | label | records | called stiction | cannot tell |',
        '|---|---|---|---|---|',
        *[f'| {t[0]} | {"sticky" if t[1] else "healthy"} | {t[2]} | {t[3]} | {t[4]} |'
          for t in tags],
        '',
        '## Held out 2: simulated loops the detector never saw',
        '',
        f'{study["sim_records"]} judgeable records of seeds {study["sim_seeds"][0]}-'
        f'{study["sim_seeds"][1] - 1}, drawn by `stiction_ros/sim/corpus.py` like the '
        f'training set but never used for training, calibration or any threshold '
        f'(left out as `cannot tell`: {study["sim_skipped"] or "none"}).',
        '',
        *table(study['sim']),
        '',
        *_sim_intervals(study),
        *_deadband_like(study),
        'Share of records called stiction, by valve or look-alike:',
        '',
        f'| kind | label | records | called stiction ({FORCED}) | {BANDED}: stiction | '
        f'{BANDED}: cannot tell |',
        '|---|---|---|---|---|---|',
        *[f'| {k} | {"sticky" if lab else "healthy"} | {n} | {100 * r[0]:.1f} % | '
          f'{100 * r[1]:.1f} % | {100 * r[2]:.1f} % |'
          for k, lab, n, *r in study['sim_kinds']],
        '',
        *_reliability(study.get('sim_reliability')),
        '## Time',
        '',
        f'- Simulated test set: {study["sim_records"]} records simulated and turned into '
        f'features in {study["sim_seconds"]} s on {study["sim_jobs"]} processes.',
        f'- Training (`make detector`): features {fig.get("features_s", "-")} s, fit '
        f'{fig.get("fit_s", "-")} s; {fig.get("trees", "-")} trees, {fig.get("nodes", "-")} '
        f'nodes; calibration-set balanced accuracy '
        f'{_f(fig.get("calibration_balanced_accuracy"), 3)}'
        + (f' (the trees alone {_f(fig["trees_alone_calibration_balanced_accuracy"], 3)})'
           if 'trees_alone_calibration_balanced_accuracy' in fig else '') + '.',
        *_cnn_line(study.get('cnn')),
        *_cnn_line(study.get('cnn_large'), 'The large network the stack weighs in '
                   '(`make cnn-large`, then `make cnn-large-tune`)'),
        f'- Whole analysis of one plant file (reading, fits, signatures, detector, '
        f'Hammerstein, HTML): median {sorted(secs)[len(secs) // 2]:.2f} s, max {max(secs):.2f} s.',
        '',
        '## Per file',
        '',
        '| label | file | answer | probability | old rule | old rule (CV) | first evidence |',
        '|---|---|---|---|---|---|---|',
    ]
    for c in study['cases']:
        ev = (c['evidence'] or [c['reason'] or ''])[0].replace('|', '/')
        lines.append(f'| {"sticky" if c["label"] else "healthy"} | {c["file"]} | '
                     f'{c["answer"]} | {_p(c["probability"])} | '
                     f'{"stiction" if c["old_rule"] else "-"} | '
                     f'{"stiction" if c["cv_old_rule"] else "-"} | {ev[:140]} |')
    lines.append('')
    return '\n'.join(lines)
