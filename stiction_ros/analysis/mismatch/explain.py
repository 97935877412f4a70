"""
``--explain``: fit the plain model, locate the mismatch, name the missing physics, show the gain.

Choosing an effect: every candidate nests Kano's plain model, so on the
fitted part each is compared with it by the likelihood ratio
``LR = N ln(MSE_plain / MSE_effect)``.  The threshold is calibrated per
record by a parametric bootstrap: the fitted plain model is run on the
recorded OP, noise of the plain fit's size is added, and everything (plain
fit and all candidates) is refitted; an effect is accepted only when its LR
exceeds ``MARGIN`` times the largest LR any candidate reached on those
effect-free replicates (and the chi-square 99.9 % point).  Held-out samples
(the last ``holdout`` share) are used for nothing but ``mse_holdout``.

When no candidate passes, the residual is called structured (``unexplained``)
when its lag-1 autocorrelation exceeds every bootstrap replicate's by more
than ``ACF_MARGIN``; otherwise the answer is ``none``.  A plain fit whose RMS
residual is at most ``NEGLIGIBLE_RMS`` leaves nothing to explain (``none``),
whatever the residual's structure.
"""

from concurrent.futures import ThreadPoolExecutor
import dataclasses
import math
import time

import numpy as np

from stiction_ros._jit import load_numba
from stiction_ros.analysis.identify import identify
from stiction_ros.analysis.mismatch import locate
from stiction_ros.analysis.mismatch.effects import BY_ID, Context, EFFECTS
from stiction_ros.analysis.mismatch.fit import as_plain, effect_errors, EffectsProblem, \
    fit_effect, plain_at_fits, plain_in_window, RESOLUTION, start_positions
from stiction_ros.analysis.mismatch.instrument import quantum
from stiction_ros.kernels import kano_effects as kk

HOLDOUT = 0.3
BOOTSTRAP = 3
MARGIN = 2.0
ACF_MARGIN = 0.1
CHI2_999 = {1: 10.83, 2: 13.82}
# A plain fit this close (RMS residual, % of span) leaves nothing to explain: it is the
# fits' own grid step in S and J, what moving a breakaway by one step costs, and below
# what a position transmitter resolves (16 bits: 0.0015 %).  The residual of such a fit
# (rounding, Choudhury's model read through Kano's) is structured, and white bootstrap
# noise of its size is not, so the autocorrelation test alone called it unexplained.
NEGLIGIBLE_RMS = RESOLUTION


# 95 % point of chi-square with one degree of freedom.
CHI2_95_1 = 3.84
HE_SENTENCE = (
    " With the threshold at J = {J:.3g} % per sample it fits as well: this is He et al.'s "
    '(2007) model, whose valve sticks again each sample the input moves less than J; a '
    'Kano valve sticks only when OP stops or reverses.')


def _he_like(problem, ctx, fit) -> bool:
    """
    Return whether the Stribeck fit is He's model: its threshold at J per sample fits as well.

    He's valve keeps moving only while each sample's input step exceeds
    ``fs - fd = J``, and it breaks away as Kano's does: Kano's model with
    that Stribeck threshold is He's model, sample for sample.
    """
    effect = BY_ID['stribeck_stick_slip']
    sse = problem.sse(fit.S, fit.J, effect.vector((fit.J / ctx.sample_time,), ctx))
    return fit.J > 0 and lr(fit.n, sse, fit.sse) < CHI2_95_1


def split_segments(segments, n_fit):
    """Return the parts of ``segments`` before sample ``n_fit``."""
    return [(a, min(b, n_fit)) for a, b in segments if a < n_fit and min(b, n_fit) - a >= 2]


def model_output(op, mv, segments, S, J, p):
    """Return (position, resting flag) of the extended model over ``segments`` (NaN elsewhere)."""
    out = np.full(len(op), np.nan)
    rest = np.zeros(len(op))
    starts = np.array([a for a, _ in segments], dtype=np.int64)
    stops = np.array([b for _, b in segments], dtype=np.int64)
    y = np.ascontiguousarray(mv, dtype=np.float64)
    y0s = start_positions(y, starts, stops)
    kk.kano_effects_fit_output(np.ascontiguousarray(op, dtype=np.float64), y, starts, stops,
                               y0s, float(S), float(J), p, out, rest)
    # The model ran on through gaps where OP is known; it is shown (and scored) on the
    # segments alone.
    scored = np.zeros(len(op), dtype=bool)
    for a, b in segments:
        scored[a:b] = True
    out[~scored] = np.nan
    rest[~scored] = 0.0
    return out, rest


def scored_masks(segments, n: int, n_fit: int) -> tuple[np.ndarray, np.ndarray]:
    """Return the samples each model is scored on: (fitted part, held-out part)."""
    valid = np.zeros(n, dtype=bool)
    for a, b in segments:
        valid[a:b] = True
    before = np.arange(n) < n_fit
    return valid & before, valid & ~before


def without_start(mask: np.ndarray, segments) -> np.ndarray:
    """
    Return ``mask`` less the record's first sample, where the model starts.

    Its output there is the start state, set from the measured MV, not a
    prediction: a residual there says where the model began, not what it
    misses, so the regions and regimes are located without it (the MSEs keep
    it, as every fit and test scores it).
    """
    out = mask.copy()
    if len(segments):
        out[segments[0][0]] = False
    return out


def _acf1(x):
    x = x[np.isfinite(x)]
    x = x - x.mean()
    d = float(np.dot(x, x))
    return float(np.dot(x[1:], x[:-1]) / d) if d > 0 else 0.0


def prepare(op, mv, fit_segments, sample_time):
    """Return (plain Fit, problem, context, plain SSE) on the fitted segments."""
    base = identify(op, mv, 'kano', segments=fit_segments, sample_time=sample_time,
                    resolution=RESOLUTION, interval=False)
    starts = [a for a, _ in fit_segments]
    stops = [b for _, b in fit_segments]
    problem = EffectsProblem(op, mv, starts, stops)
    used = np.concatenate([np.arange(a, b) for a, b in fit_segments])
    ctx = Context(sample_time, int(max(stops)), float(np.mean(mv[used])))
    plain_sse = problem.sse(base.S, base.J, kk.plain_params())
    return base, problem, ctx, plain_sse


def _moved(base, problem, ctx, plain_sse, found):
    sse, S, J = found
    if sse >= plain_sse:
        return base, problem, ctx, plain_sse
    return dataclasses.replace(base, S=float(S), J=float(J), mse=sse / problem.n), problem, \
        ctx, sse


def settle(prepared, fits):
    """
    Return (prepared, fits), the plain fit moved where the candidates' search finds it better.

    The candidates are searched around the plain fit, over a wider window
    than its global grid resolves, and one may land in a basin where the
    plain model, tried there, fits as well.  So the plain model is searched
    over that window too and tried near each candidate's (S, J); a
    candidate no better than it becomes the plain model (its likelihood
    ratio zero).  The candidates keep the plain fit they were searched
    around, as a record's replicates do.
    """
    base, problem, ctx, plain_sse = prepared
    prepared = _moved(base, problem, ctx, plain_sse,
                      plain_in_window(problem, base.S, base.J, plain_sse))
    base, _, _, plain_sse = prepared
    prepared = _moved(base, problem, ctx, plain_sse,
                      plain_at_fits(problem, fits, base.S, base.J, plain_sse))
    base, _, _, plain_sse = prepared
    return prepared, [as_plain(f, base.S, base.J, plain_sse) for f in fits]


class Fitted(str):
    """
    A progress message that one candidate fit is done: the text, and its numbers.

    A ``str`` for whoever prints progress as text; ``effect``, ``done``,
    ``total`` and ``replicate`` (0 for the record itself, r for bootstrap
    replicate r of ``replicates``) for whoever counts.
    """

    effect: str
    done: int
    total: int
    replicate: int
    replicates: int

    @classmethod
    def of(cls, effect: str, done: int, total: int, replicate: int = 0,
           replicates: int = 0) -> 'Fitted':
        """Return the message of fit ``done`` of ``total`` (``effect``, on ``replicate``)."""
        label = f'bootstrap {replicate}/{replicates}: ' if replicate else ''
        msg = cls(f'{label}fitted {effect} ({done}/{total})')
        msg.effect, msg.done, msg.total = effect, done, total
        msg.replicate, msg.replicates = replicate, replicates
        return msg


def fit_many(prepared, jobs=1, progress=None, replicates=0, counted=(0, None)):
    """
    Fit every candidate on every prepared record; return one list of fits per record.

    With ``replicates`` > 0 the records are bootstrap replicates 1 to
    ``replicates``, so named in the :class:`Fitted` progress messages.
    ``counted``: (fits done before, fits in all) for those messages, where this
    call is one part of a larger count.

    The fits are independent and their kernels release the GIL, so ``jobs``
    threads run them side by side; the results do not depend on ``jobs``.
    """
    tasks = [(i, effect) for i in range(len(prepared)) for effect in EFFECTS]
    done = [counted[0]]
    total = counted[1] or len(tasks)

    def one(task):
        i, effect = task
        base, problem, ctx, plain_sse = prepared[i]
        fit = fit_effect(problem, effect, ctx, base.S, base.J, plain_sse)
        done[0] += 1
        if progress is not None:
            progress(Fitted.of(effect.eid, done[0], total, i + 1 if replicates else 0,
                               replicates))
        return fit

    if jobs > 1 and len(tasks) > 1:
        # Threads share the GIL unless the kernels are numba's own (nogil); the
        # ahead-of-time builds hold it.
        load_numba()
        with ThreadPoolExecutor(max_workers=jobs) as pool:
            fits = list(pool.map(one, tasks))
    else:
        fits = [one(task) for task in tasks]
    k = len(EFFECTS)
    return [fits[i * k:(i + 1) * k] for i in range(len(prepared))]


def fit_all(op, mv, fit_segments, sample_time, progress=None, jobs=1):
    """Return (plain Fit, problem, context, plain SSE, [CandidateFit]) on the fitted segments."""
    prepared = prepare(op, mv, fit_segments, sample_time)
    prepared, fits = settle(prepared, fit_many([prepared], jobs, progress)[0])
    return (*prepared, fits)


def lr(n, plain_sse, sse):
    """Return the likelihood-ratio statistic of a nested fit."""
    return n * math.log(plain_sse / sse) if sse > 0 and plain_sse > 0 else 0.0


def replicates(op, mv, fit_segments, base, plain_sse, n, reps, seed):
    """
    Return ``reps`` effect-free records: the plain model on the recorded OP, plus noise.

    A reading in steps of a quantum is read so in the replicates too (with
    the noise less the steps' own q^2/12): rounding a stuck position is not
    white noise, and a fit of the steps may gain on it what no effect causes.
    """
    rng = np.random.default_rng(seed)
    sigma = math.sqrt(plain_sse / n)
    idx = np.concatenate([np.arange(a, b) for a, b in fit_segments])
    q = quantum(mv, idx)
    if q > 0.0:
        origin = float(np.median(np.mod(mv[idx], q)))
        sigma = math.sqrt(max(sigma ** 2 - q ** 2 / 12.0, 0.0))
    out = []
    for _ in range(reps):
        # A real valve's S and J are not on the fit's grid, and the breakaway flips
        # that costs are part of what noise alone produces: replicates get the same.
        S = max(base.S + rng.uniform(-0.5, 0.5) * RESOLUTION, 0.0)
        J = min(max(base.J + rng.uniform(-0.5, 0.5) * RESOLUTION, 0.0), S)
        # Each replicate starts where the plain model starts: at the measured position.
        clean, _ = model_output(op, mv, fit_segments, S, J, kk.plain_params())
        y = clean + sigma * rng.standard_normal(len(op))
        out.append(origin + q * np.round((y - origin) / q) if q > 0.0 else y)
    return out


def calibrate(op, fit_segments, replicate_fits):
    """Return (largest LR per effect, lag-1 autocorrelations) over the replicates' fits."""
    worst = {e.eid: 0.0 for e in EFFECTS}
    acfs = []
    for y, (b_base, b_problem, _, b_plain), b_fits in replicate_fits:
        for f in b_fits:
            worst[f.effect] = max(worst[f.effect], lr(b_problem.n, b_plain, f.sse))
        res, _ = model_output(op, y, fit_segments, b_base.S, b_base.J, kk.plain_params())
        acfs.append(_acf1((y - res)[np.isfinite(res)]))
    return worst, acfs


def masked_mse(a, b, mask):
    """Return the MSE of ``a`` against ``b`` where ``mask`` and both are finite."""
    m = mask & np.isfinite(a) & np.isfinite(b)
    return float(np.mean((a[m] - b[m]) ** 2)) if np.any(m) else float('nan')


def explain(t, op, mv, segments, sample_time, holdout=HOLDOUT, reps=BOOTSTRAP, seed=0,
            progress=None, jobs=1):
    """
    Return the ``--explain`` report sections (a dict) and the arrays behind the figures.

    ``segments``: the valid stretches (start, stop) of the record; ``jobs``: threads
    for the candidate fits (the result does not depend on it).
    """
    t0 = time.perf_counter()
    op = np.asarray(op, dtype=np.float64)
    mv = np.asarray(mv, dtype=np.float64)
    n = len(op)
    if not 0.0 <= holdout < 0.9:
        raise ValueError(f'--holdout must be in [0, 0.9), got {holdout}')
    n_fit = int(round(n * (1.0 - holdout)))
    fit_segments = split_segments(segments, n_fit)
    if not fit_segments:
        raise ValueError('no valid samples before the held-out part to fit on')
    say = progress or (lambda msg: None)
    say('fitting the plain model')
    prepared = prepare(op, mv, fit_segments, sample_time)
    counted = (len(EFFECTS), len(EFFECTS) * (1 + reps))
    prepared, fits = settle(prepared, fit_many([prepared], jobs, say, 0, (0, counted[1]))[0])
    base, problem, ctx, plain_sse = prepared
    n_used = problem.n
    # The bootstrap's effect-free replicates of the plain model as settled, refitted
    # from scratch like the record; every candidate on every one of them, side by
    # side on ``jobs`` threads.
    ys = replicates(op, mv, fit_segments, base, plain_sse, n_used, reps, seed)
    records = [prepare(op, y, fit_segments, sample_time) for y in ys]
    settled = [settle(r, f) for r, f in zip(records, fit_many(records, jobs, say, reps,
                                                              counted))]
    stats = {f.effect: lr(n_used, plain_sse, f.sse) for f in fits}
    worst, acfs = calibrate(op, fit_segments, [(y, r, f) for y, (r, f) in zip(ys, settled)])
    thresholds = {e.eid: max(CHI2_999[len(e.names)], MARGIN * worst[e.eid]) for e in EFFECTS}

    fit_mask, hold_mask = scored_masks(segments, n, n_fit)
    plain = kk.plain_params()
    mv_base, rest_base = model_output(op, mv, segments, base.S, base.J, plain)
    candidates = []
    outputs = {}
    for f in fits:
        out, _ = model_output(op, mv, segments, f.S, f.J, f.vector)
        outputs[f.effect] = out
        candidates.append({
            'effect': f.effect, 'params': {k: round(v, 6) for k, v in f.params.items()},
            'S': f.S, 'J': f.J, 'mse_fit': masked_mse(out, mv, fit_mask),
            'mse_holdout': masked_mse(out, mv, hold_mask),
            'score': round(stats[f.effect] / thresholds[f.effect], 4),
            'lr': round(stats[f.effect], 3), 'threshold': round(thresholds[f.effect], 3)})
    negligible = math.sqrt(plain_sse / n_used) <= NEGLIGIBLE_RMS
    passing = [] if negligible else [c for c in candidates if c['score'] > 1.0]

    def residual_of(f):
        return (outputs[f.effect] - mv)[fit_mask]
    residual = mv - mv_base
    acf = _acf1(residual[fit_mask])
    if passing:
        chosen = max(passing, key=lambda c: c['score'])
        effect = chosen['effect']
        fit = next(f for f in fits if f.effect == effect)
        chosen['standard_errors'] = {
            k: round(v, 6) for k, v in effect_errors(problem, BY_ID[effect], ctx, fit,
                                                     _acf1(residual_of(fit)))
            .items()}
        explanation = BY_ID[effect].sentence(chosen['params'], chosen['S'], chosen['J'])
        if effect == 'stribeck_stick_slip' and _he_like(problem, ctx, fit):
            chosen['he_model'] = True
            explanation += HE_SENTENCE.format(J=fit.J)
        confidence = 1.0 - 1.0 / chosen['score']
        mv_explained = outputs[effect]
        params = {'S': chosen['S'], 'J': chosen['J'], **chosen['params']}
        model = {'name': f'kano+{effect}', 'params': params}
    else:
        structured = not negligible and bool(acfs) and acf > max(acfs) + ACF_MARGIN
        effect = 'unexplained' if structured else 'none'
        if structured:
            explanation = (
                f'The residual of the plain model is structured (lag-1 autocorrelation '
                f'{acf:.2f} against at most {max(acfs):.2f} on effect-free replicates) but '
                'no candidate explains it; see the regions.')
        elif negligible:
            explanation = (
                f'Nothing is left to explain: the plain model fits the valve to an RMS error '
                f"of {math.sqrt(plain_sse / n_used):.2g} % of span, no more than the fit's own "
                f'{RESOLUTION:g} % step in S and J.')
        else:
            explanation = (
                'Nothing is missing: the plain model explains the valve up to noise, and no '
                'candidate improves the fit beyond what noise alone produces.')
        best = max(candidates, key=lambda c: c['score'])
        confidence = max(0.0, 1.0 - best['score'])
        mv_explained = mv_base
        model = {'name': 'kano', 'params': {'S': base.S, 'J': base.J}}
    labels = locate.regime_labels(op, np.where(np.isfinite(mv_base), mv_base, mv), rest_base)
    labels.update(locate.time_thirds(n, fit_mask))
    report = {
        'baseline': {'model': 'kano', 'S': base.S, 'J': base.J,
                     'mse_fit': masked_mse(mv_base, mv, fit_mask),
                     'mse_holdout': masked_mse(mv_base, mv, hold_mask)},
        'mismatch': {
            'effect': effect, 'confidence': round(float(confidence), 4),
            'explanation': explanation,
            'regions': locate.regions(t, residual, labels, without_start(fit_mask, segments)),
            'regimes': locate.regime_shares(residual, labels,
                                            without_start(fit_mask, segments)),
            'model': model,
            'mse_fit': masked_mse(mv_explained, mv, fit_mask),
            'mse_holdout': masked_mse(mv_explained, mv, hold_mask),
            'residual_acf1': round(acf, 4),
            'bootstrap': {'replicates': len(acfs),
                          'largest_lr': {k: round(v, 3) for k, v in worst.items()},
                          'acf1': [round(a, 4) for a in acfs], 'margin': MARGIN}},
        'candidates': sorted(candidates, key=lambda c: -c['score']),
        'holdout': {'share': holdout, 'first_sample': n_fit,
                    't_start': float(t[n_fit]) if n_fit < n else None,
                    'fit_samples': int(np.sum(fit_mask)),
                    'holdout_samples': int(np.sum(hold_mask))},
        'series': {'t': t.tolist(), 'op': _json(op), 'mv': _json(mv),
                   'mv_baseline': _json(mv_base), 'mv_explained': _json(mv_explained)},
        'explain_seconds': round(time.perf_counter() - t0, 3),
    }
    arrays = {'t': t, 'op': op, 'mv': mv, 'mv_baseline': mv_base, 'resting': rest_base,
              'mv_explained': mv_explained, 'fit_mask': fit_mask, 'hold_mask': hold_mask,
              'breakaways': locate.breakaways(t, op, mv, mv_base, rest_base, sample_time)}
    return report, arrays


def _json(x):
    return [None if not math.isfinite(v) else float(v) for v in x]
