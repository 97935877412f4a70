"""
From a loaded record to the analyzer's report: fits, signatures and the verdict.

``analyze(record, options)`` returns a :class:`Analysis`: the JSON report
(documented field by field in the README) plus the arrays the figures need.
Nothing here reads files or draws; ``stiction_ros.app.analyze`` does both.
"""

from collections.abc import Callable
from dataclasses import dataclass, field, replace
import re

import numpy as np

from stiction_ros.analysis.caution import sampling_caution, slips, step_while_moving, \
    valve_sampling_caution
from stiction_ros.analysis.detection import detect, Detection, Judgeable, probability_text
from stiction_ros.analysis.detection.detect import answer_of, reason_of
from stiction_ros.analysis.detection.resolve import robust_noise
from stiction_ros.analysis.detection.stretches import pooled_probability
from stiction_ros.analysis.detection.timing import Alignment
from stiction_ros.analysis.frictionless_valve import plausible
from stiction_ros.analysis.identify import (given_fit, identify, IdentifyError, SearchProgress,
                                            ValveProblem)
from stiction_ros.analysis.measures.still import set_point_test
from stiction_ros.analysis.record import Record, runs
from stiction_ros.analysis.stick_slip_behind import fit_behind
from stiction_ros.analysis.verdict import behind_bar, combine, from_fits, NOISE_FIT, \
    refuse_still
from stiction_ros.analysis.without_friction import calibrated, fit_without_friction, \
    indices, still_reading

MODEL_CHOICES = ('kano', 'choudhury', 'both')
LOOP_TYPES = ('auto', 'self-regulating', 'integrating')
# Historian tags name the measured variable: LIC/LC = level, an integrating loop.
_LEVEL_TAG = re.compile(r'(^|[^A-Z])L[IDR]*C', re.IGNORECASE)
MIN_SIGNATURE_SAMPLES = 100
# What ``analyze`` tells its ``stage`` callback before each part, in order; a
# long record spends seconds in each.
STAGES = ('learned detector', 'signatures', 'Hammerstein fit')
# Longest run of invalid samples the signatures (never the fits) bridge.
MAX_BRIDGE = 2


@dataclass
class Options:
    """What the engineer asked for (command-line options or node parameters)."""

    model: str = 'both'
    S: float | None = None
    J: float | None = None
    fit_filter: bool = False
    loop_type: str = 'auto'
    hammerstein: bool = True
    detector: str | None = None

    def __post_init__(self):
        if self.model not in MODEL_CHOICES:
            raise ValueError(f'model must be one of {MODEL_CHOICES}, got {self.model!r}')
        if self.loop_type not in LOOP_TYPES:
            raise ValueError(f'loop type must be one of {LOOP_TYPES}, got {self.loop_type!r}')
        if (self.S is None) != (self.J is None):
            raise ValueError('give both S and J, or neither (then they are identified)')
        for name in ('S', 'J'):
            v = getattr(self, name)
            if v is not None and not 0.0 <= v <= 100.0:
                raise ValueError(f'{name} = {v} is outside [0, 100] % of span')

    @property
    def models(self):
        """Return the model names to fit."""
        return ('kano', 'choudhury') if self.model == 'both' else (self.model,)


@dataclass
class Analysis:
    """The report and the arrays behind its figures."""

    report: dict
    record: object
    fits: list = field(default_factory=list)
    predictions: dict = field(default_factory=dict)
    oscillation: object = None
    signatures: dict = field(default_factory=dict)
    signature_window: tuple | None = None
    signature_inputs: dict | None = None
    landscape: dict | None = None
    explain_arrays: dict | None = None
    detection: object = None


def is_integrating(record, loop_type):
    """Return whether to treat the loop as integrating (level) and why."""
    if loop_type != 'auto':
        return loop_type == 'integrating', f'loop type {loop_type} (given)'
    if _LEVEL_TAG.search(record.name or ''):
        return True, f'loop type integrating (level tag {record.name})'
    return False, 'loop type self-regulating (assumed; give --loop-type for a level loop)'


# Kano's air-chamber time constants tried when the filter is identified, in samples.
FILTER_TAUS = (0.0, 0.5, 1.0, 1.5, 2.0, 3.0, 4.0, 6.0, 8.0, 12.0)


def fit_models(record, options, progress=None):
    """Return (fits, predictions): each model's Fit and its predicted MV."""
    op, mv = record.signals['op'], record.signals['mv']
    segs = record.valve_segments(min_samples=2)
    ts = record.sample_time
    fits, predictions = [], {}
    ideal, noise = ideal_valve_mse(op, mv, segs), mv_noise_var(mv, segs)
    for model in options.models:
        if options.S is not None:
            fit = given_fit(op, mv, model, options.S, options.J, segs, ts)
        else:
            fv = None
            if options.fit_filter:
                fv = ([t * ts for t in FILTER_TAUS] if model == 'kano'
                      else [1.0, 0.8, 0.6, 0.5, 0.4, 0.3, 0.2, 0.1])
            fit = identify(op, mv, model, segs, ts, filter_values=fv, progress=progress)
        fit.extra['ideal_valve_mse'] = ideal
        fit.extra['mv_noise_var'] = noise
        fit.extra['improvement'] = 1.0 - fit.mse / ideal if ideal > 0 else 0.0
        fits.append(fit)
        predictions[model] = predict(model, fit, op, mv, segs, ts)
        fit.extra['op_step'] = step_while_moving(op, predictions[model], segs)
        fit.extra['slips'] = slips(predictions[model], segs)
    told = from_fits([f.to_json() for f in fits]) if fits and options.S is None else None
    if told is not None and (told.detected or told.code == 'few_slips' or (
            told.code in (None, 'slip_unresolved') and 0 < NOISE_FIT * noise < ideal)):
        # A claim of friction (one the fitted valve moves too seldom to make too) must beat
        # the best valve without it, which real readings call for first (dead time, lag,
        # calibration); so must a claim of none where an ideal valve leaves more than
        # MV's noise, and play or an unresolved slip, which a dead time in the reading
        # imitates.  Not where the user gave S and J: that model is theirs to weigh.
        # Stick-slip gets the chain's calibration too (an offset and gain on its MV).
        chain = fit_without_friction(op, mv, segs, ts)
        idx = indices(segs)
        for fit in fits:
            fit.extra['frictionless'] = chain
            pred = predictions[fit.model]
            if np.all(np.isfinite(pred[idx])):
                offset, gain, sse = calibrated(pred, mv, idx)
                # Held to the calibration the valve without friction is held to.
                if plausible({'offset': offset, 'gain': gain}):
                    fit.extra['calibrated_mse'] = sse / len(idx)
        if from_fits([f.to_json() for f in fits]).detected is not True:
            # Friction may hide behind that valve's timing, and a claim of none that rests
            # on the valve must beat stick-slip read behind the same timing.
            best = min(fits, key=lambda f: f.mse)
            behind = fit_behind(op, mv, segs, ts, chain, best.model,
                                min(behind_bar(best.to_json())))
            if behind is not None:
                best.extra['behind'] = behind
    return fits, predictions


def ideal_valve_mse(op, mv, segments):
    """Return the MSE of an ideal valve (MV = OP within 0-100 %): the fits' yardstick."""
    err = np.concatenate([np.clip(op[a:b], 0, 100) - mv[a:b] for a, b in segments])
    return float(np.mean(err ** 2))


def mv_noise_var(mv, segments):
    """Return MV's white-noise variance from its sample-to-sample changes (MAD)."""
    return robust_noise(np.concatenate([mv[a:b] for a, b in segments])) ** 2


def predict(model, fit, op, mv, segments, sample_time):
    """
    Return the model's MV over the record (NaN outside the valid segments).

    Sample for sample what the fit scored: the valve runs on through gaps
    where OP is known, and restarts after a gap in OP (``fit_core``).
    """
    problem = ValveProblem(model, op, mv, segments, fit.filter_value, sample_time)
    return problem.output(fit.S, fit.J)


def bridged_valid(record, max_gap=MAX_BRIDGE):
    """
    Return the valid mask with interior runs of at most ``max_gap`` invalid samples bridged.

    Only the OP/PV signatures use this: correlation, curve fitting and
    spectra need contiguous samples, and historian exports flag single
    samples every few minutes.  A bridged sample holds the last valid
    value; the fits never bridge anything.
    """
    valid = record.valid.copy()
    for a, b in runs(~record.valid):
        if 0 < a and b < len(valid) and b - a <= max_gap:
            valid[a:b] = True
    return valid


def stretches(record):
    """Return (start, stop, samples held) of every stretch OP and PV are read on, longest first."""
    if not (record.has('op') and record.has('pv')):
        return []
    found = [(a, b, int(np.sum(~record.valid[a:b]))) for a, b in runs(bridged_valid(record))
             if b - a >= MIN_SIGNATURE_SAMPLES]
    # A stable sort: of two as long, the earlier first.
    return sorted(found, key=lambda w: w[1] - w[0], reverse=True)


def short_stretches(record) -> dict:
    """Return how many valid samples lie in stretches too short to read, and in how many."""
    if not (record.has('op') and record.has('pv')):
        return {}
    short = [(a, b) for a, b in runs(bridged_valid(record)) if b - a < MIN_SIGNATURE_SAMPLES]
    n = int(sum(np.sum(record.valid[a:b]) for a, b in short))
    return {'stretches': len(short), 'valid_samples': n} if n else {}


def signature_window(record):
    """Return (start, stop, samples held) of the longest stretch for the signatures, or None."""
    found = stretches(record)
    return found[0] if found else None


def held_signals(record, a, b):
    """Return op, pv, sp on [a, b) with bridged samples holding the last valid value."""
    out = {}
    ok = record.valid[a:b]
    for name in ('op', 'pv', 'sp'):
        if not record.has(name):
            out[name] = None
            continue
        x = record.signals[name][a:b].copy()
        for k in np.flatnonzero(~ok):
            x[k] = x[k - 1]
        out[name] = x
    return out


def run_signatures(held, sample_time, integrating):
    """Return (oscillation, signatures) of ``held`` (None and {} without a stretch)."""
    from stiction_ros.analysis.signatures.all import compute_signatures
    if held is None:
        return None, {}
    return compute_signatures(held['op'], held['pv'], held['sp'], sample_time,
                              integrating=integrating)


def run_hammerstein(held, sample_time, integrating):
    """Return the Hammerstein quantification on the signatures' stretch."""
    from stiction_ros.analysis.hammerstein import quantify
    return quantify(held['op'], held['pv'], sample_time, integrating=integrating)


def _plain(value):
    """Return ``value`` as JSON holds it: mappings and lists kept as such, the rest as text."""
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if value is None or isinstance(value, (bool, int, float)):
        return value
    return str(value)


def realigned_rows(detection) -> int:
    """Return the rows PV was read late against OP (negative: early; 0 when not realigned)."""
    if detection is None:
        return 0
    return int(detection.details.get('timing', {}).get('shift_rows', 0) or 0)


def realigned_lag(detection) -> float:
    """Return the rows of lag PV was read back through (0 when none)."""
    if detection is None:
        return 0.0
    return float(detection.details.get('timing', {}).get('lag_rows', 0.0) or 0.0)


def realigned(held, detection):
    """Return the signals as the detection read them: PV against OP by its skew or lag."""
    shift, lag = realigned_rows(detection), realigned_lag(detection)
    if not (shift or lag):
        return held
    how = Alignment(shift, 1.0, 1.0, shift, lag=lag)
    op, pv, sp, _ = how.apply(held['op'], held['pv'], held['sp'])
    return {**held, 'op': op, 'pv': pv, 'sp': sp}


def pool_stretches(record, detection, integrating, model_path=None):
    """
    Return ``detection`` (the longest stretch's) pooled with the record's other stretches.

    Each stretch is judged alone and the judged ones are pooled
    (:func:`stretches.pooled_probability`); the evidence is the longest judged
    stretch's, under a line that names every stretch.  ``details['stretches']``
    lists them.  A record of one stretch keeps ``detection`` as it is.
    """
    wins = stretches(record)
    if len(wins) < 2:
        return detection
    read = [(wins[0], detection)] + [
        (w, run_detection(record, w, held_signals(record, w[0], w[1]), integrating, model_path))
        for w in wins[1:]]
    table = [{'start_s': float(record.t[a]), 'end_s': float(record.t[b - 1]), 'samples': b - a,
              'probability': d.probability, 'not_judged': '' if d.judge.ok else d.judge.code,
              'held_rows': int(d.details.get('held_rows', 0))}
             for (a, b, _), d in read]
    judged = [(w, d) for w, d in read if d.probability is not None]
    if not judged or (len(judged) == 1 and judged[0][1] is detection):
        return replace(detection, details={**detection.details, 'stretches': table})
    (a, b, _), base = judged[0]
    # Decided on the pooled value itself, as detect decides on its own; one stretch
    # judged alone keeps its own probability.
    p = (base.probability if len(judged) == 1 else
         pooled_probability([d.probability for _, d in judged], [w[1] - w[0] for w, _ in judged]))
    # In the order they were recorded; a stretch not judged says why.
    parts = ', '.join(f'{t["start_s"]:g}-{t["end_s"]:g} s ({t["samples"]} samples) '
                      + (probability_text(t['probability']) if t['probability'] is not None
                         else f'not judged ({t["not_judged"].replace("_", " ")})')
                      for t in sorted(table, key=lambda t: t['start_s']))
    line = (f'{len(wins)} stretches between gaps, each judged alone: {parts}; the judged ones '
            f'pooled, their log-odds weighed by their samples: {probability_text(p)} (the '
            f'evidence below is from {record.t[a]:g}-{record.t[b - 1]:g} s)')
    answer = answer_of(p)
    return replace(base, answer=answer, probability=round(p, 4), reason=reason_of(p),
                   evidence=[line, *base.evidence],
                   details={**base.details, 'stretches': table,
                            'balanced': answer == 'cannot tell'})


def run_detection(record, win, held, integrating, model_path=None):
    """Return the :class:`Detection` on the signatures' stretch (cannot tell without one)."""
    if win is None:
        n = int(np.sum(record.valid))
        judge = Judgeable(False, 'too_short',
                          f'too short: no stretch of {MIN_SIGNATURE_SAMPLES} contiguous valid '
                          f'samples with OP and PV ({n} valid samples in all)')
        return Detection('cannot tell', None, judge.reason, judge)
    return detect(held['op'], held['pv'], held['sp'], record.sample_time, integrating,
                  model_path, first_row=win[0])


def analyze(record: Record, options: Options | None = None,
            progress: Callable[[SearchProgress], object] | None = None,
            stage: Callable[[str, tuple], object] | None = None) -> Analysis:
    """
    Return the :class:`Analysis` of ``record``.

    ``progress`` hears each level of a model search; ``stage`` the name (one
    of :data:`STAGES`) of each other part as it starts, and the parts this
    record runs (with MV the fits decide, and only the signatures follow them).
    """
    options = options or Options()
    say_stage = stage or (lambda name, plan: None)
    notes = list(record.notes)
    report = {
        'input': {str(k): _plain(v) for k, v in record.source.items()},
        'name': record.name, 'start_time': record.start_time,
        'samples': int(record.samples), 'sample_time': float(record.sample_time),
        'valid_samples': int(np.sum(record.valid)),
        'signals': [s for s in ('op', 'mv', 'pv', 'sp') if record.has(s)],
        'excluded': record.excluded, 'fits': [],
    }
    analysis = Analysis(report, record)
    if record.has('mv'):
        try:
            analysis.fits, analysis.predictions = fit_models(record, options, progress)
            report['fits'] = [f.to_json() for f in analysis.fits]
        except IdentifyError as exc:
            notes.append(f'no model fit: {exc}')
    else:
        notes.append('no valve position (mv): fits skipped; the verdict rests on OP and PV')
    plan = (('signatures',) if analysis.fits else
            STAGES if options.hammerstein else STAGES[:-1])

    def stage(name: str) -> None:
        say_stage(name, plan)
    integrating, why = is_integrating(record, options.loop_type)
    report['loop_type'] = 'integrating' if integrating else 'self-regulating'
    notes.append(why)
    win = signature_window(record)
    short = {} if analysis.fits else short_stretches(record)
    if short:
        # Said, so that no valid sample is dropped without a word (the fits, with MV,
        # read across gaps).
        report['short_stretches'] = short
    held = None if win is None else held_signals(record, win[0], win[1])
    detection = None
    if not analysis.fits:
        # No MV, or an MV no model could be fitted to: OP and PV decide.
        stage('learned detector')
        detection = run_detection(record, win, held, integrating, options.detector)
        # The verdict pools every stretch; the signatures and the size read the longest.
        analysis.detection = pool_stretches(record, detection, integrating, options.detector)
    # The signatures read the record as the detector did: PV paired again with the OP of
    # its own scan where the clock-skew check found the two tags stamped apart.
    read = held if detection is None or held is None else realigned(held, detection)
    if win is not None:
        stage('signatures')
    osc, sigs = run_signatures(read, record.sample_time, integrating)
    analysis.oscillation, analysis.signatures = osc, sigs
    analysis.signature_window, analysis.signature_inputs = win, read
    if win is None:
        notes.append(f'signatures skipped: they need OP and PV over at least '
                     f'{MIN_SIGNATURE_SAMPLES} contiguous valid samples')
    else:
        # Times name OP's rows: a realigned record keeps fewer of them (PV early: not the
        # first ones), so that slip times count from the row the signatures start on.
        shift = realigned_rows(detection)
        first, last = win[0] + max(0, -shift), win[1] - 1 - max(0, shift)
        if 'slip_events' in sigs:
            from stiction_ros.analysis.signatures.slip_events import on_record_clock
            # Counted on the stretch read; said on the record's clock, as all else is.
            sigs['slip_events'] = on_record_clock(sigs['slip_events'],
                                                  float(record.t[first] - record.t[0]))
        report['signature_window'] = {'start_s': float(record.t[first]),
                                      'end_s': float(record.t[last]),
                                      'samples': int(last + 1 - first), 'held': win[2]}
        if win[2]:
            notes.append(f'signatures: {win[2]} isolated invalid samples (runs of at most '
                         f'{MAX_BRIDGE}) hold the previous value so that the signatures see '
                         f'one stretch of {win[1] - win[0]} samples; the fits bridge nothing')
        if shift:
            report['signature_window']['pv_shift_rows'] = shift
            side = 'late' if shift > 0 else 'early'
            notes.append(f'signatures: PV read {abs(shift)} rows {side} against OP, paired '
                         'again as the detector read it (clock skew between the two tags)')
        lag = realigned_lag(detection)
        if lag:
            report['signature_window']['pv_lag_rows'] = lag
            notes.append(f'signatures: PV read back through the first-order lag of {lag:.3g} '
                         'rows the detector found on it (a filter the controller did not '
                         'see)')
    ham = None
    if (win is not None and options.hammerstein and not analysis.fits
            and detection.judge.ok and not detection.period_problem):
        # Sizing needs what judging needs, and a resolvable cycle if there is
        # one: an under-sampled limit cycle aliases into a band 10x too wide.
        stage('Hammerstein fit')
        ham = run_hammerstein(read, record.sample_time, integrating)
    report['stiction'] = combine(osc, sigs, report['fits'], ham, analysis.detection,
                                 sizing=detection)
    # A size the user gave was not fitted: nothing to caution about.
    fitted = [f for f in analysis.fits if f.source != 'given']
    if fitted:
        # A band fitted and reported (stiction, or cannot tell beside it) reads low alike.
        sticks = report['stiction']['detected'] is not False
        caution = (sampling_caution(held, osc, record.sample_time, sticks) if win is not None
                   else valve_sampling_caution(record, sticks, MIN_SIGNATURE_SAMPLES))
        still, overruled = still_reading(record.signals['op'], record.signals['mv'],
                                         record.valve_segments(min_samples=2),
                                         record.sample_time, fitted[0].extra)
        if overruled:
            notes.append('MV stayed within its noise while OP travelled, but a valve without '
                         'friction explains it down to that noise: MV follows the slow part '
                         "of OP, whose spread is mostly OP's own noise; not read as still")
        if still is not None:
            # The fit's range is as narrow as the noise, but S is bounded from below only.
            lower = (f'{still.sentence()}; the fitted S and its range are where the fit '
                     'stopped, not a measured size')
            caution = f'{lower}; {caution}' if caution else lower
            sp_test = (set_point_test(record.signals['pv'], record.signals['sp'],
                                      record.valve_segments(min_samples=2))
                       if record.has('pv') and record.has('sp') else None)
            refuse_still(report['stiction'], still, sp_test)
            if report['stiction']['cannot_tell'] == 'mv_dead':
                return without_dead_mv(analysis, options, progress, say_stage)
        if caution:
            report['stiction']['size_caution'] = caution
    report['notes'] = notes
    return analysis


def without_dead_mv(analysis: Analysis, options: Options,
                    progress: Callable[[SearchProgress], object] | None,
                    stage: Callable[[str, tuple], object]) -> Analysis:
    """
    Return the analysis of ``analysis.record`` judged from OP and PV, its MV set aside.

    PV followed the set point, so the valve moved and its position reading is
    dead: a fit to that reading measures OP's travel, not friction.  The
    record is analysed again as one without MV (the learned detector decides),
    and ``mv_dead`` keeps what the first analysis said of MV: the reason, the
    set-point test and the fits, so that nothing read is lost.  The record
    stays the one read, MV included, for the figures and ``--explain``.
    """
    record, first = analysis.record, analysis.report
    # Rows invalid for MV alone stay out: they were out of the record as read.
    blind = replace(record, signals={k: v for k, v in record.signals.items() if k != 'mv'},
                    notes=list(record.notes))
    out = analyze(blind, options, progress, stage)
    st = first['stiction']
    out.record = record
    out.report['signals'] = first['signals']
    out.report['mv_dead'] = {'reason': st['reason'], 'set_point_test': st['set_point_test'],
                             'fits': first['fits']}
    notes = out.report['notes']
    # The blind copy's own note would say MV was never recorded.
    out.report['notes'] = [n for n in notes if not n.startswith('no valve position (mv)')] + [
        'MV set aside as a dead reading (mv_dead): the verdict rests on OP and PV']
    return out
