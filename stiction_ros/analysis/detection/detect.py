"""
The detector's answer on one record: stiction, no stiction, or cannot tell.

First the record must be judgeable (:mod:`resolve`); if not, the answer is
``cannot tell`` with the reason.  Otherwise the boosted trees score the
feature vector, the stack (:mod:`stack`) weighs that score with the large
network's logit, the calibration map turns the result into a probability,
and the answer is ``stiction`` at ``BAND[1]`` or above, ``no stiction``
under ``BAND[0]`` and ``cannot tell`` between (the evidence is balanced).
The evidence says which test saw what and where in time, so the engineer
can check the claim on the trend.
"""

from dataclasses import dataclass, field, replace
from functools import lru_cache

import numpy as np

from stiction_ros.analysis.detection import cnn, model_file, stack
from stiction_ros.analysis.detection import interpolated, timing
from stiction_ros.analysis.detection.feature_words import words
from stiction_ros.analysis.detection.features import extract, FEATURE_NAMES
from stiction_ros.analysis.detection.resolve import cycle_judgeable, Judgeable, judgeable
from stiction_ros.analysis.detection.stale import drop_held, holds_judgeable, NOTABLE
from stiction_ros.analysis.detection.stuck import record_row
from stiction_ros.analysis.signatures.slip_events import found_text
from stiction_ros.errors import DetectorFileError

# The forced choice between the two answers, kept for the accuracy study.
THRESHOLD = 0.5
# An answer only when it is at least three times as likely as its opposite (at
# even odds, as the map is calibrated): between these the evidence is
# balanced, and a confident "no stiction" there would close a case that a
# valve travel test should decide (docs/DETECTION.md, section 3, "The band").
BALANCED = (0.25, 0.75)
# The answers the analyzer gives: (THRESHOLD, THRESHOLD) would be the forced choice.
BAND = BALANCED
ANSWERS = ('stiction', 'no stiction', 'cannot tell')
VOTERS = ('horch', 'he_curve_fit', 'hos_pv_op', 'yamashita', 'slip_events')
# Every training record had its set point; the user should know what its absence costs.
NO_SET_POINT = ('no set point in the record: the mean PV stands in for it, which no training '
                'record needed (each had its SP), so the answer is less sure than with SP '
                '(docs/ROBUSTNESS.md, "no set point"), and whether OP acts on the error at '
                'all cannot be checked; export SP with OP and PV')
# A stuck period's OP this straight, on an error held this many standard
# errors off zero, is the pattern a steady load drift shares with a stuck valve.
RAMP_R2 = 0.9
HELD_ERRORS = 10.0
# How many figures the evidence names as the ones the trees leaned on.
LEANED_ON = 3


@dataclass
class Detection:
    """The answer, its calibrated probability and the evidence behind it."""

    answer: str
    probability: float | None
    reason: str
    judge: Judgeable
    evidence: list = field(default_factory=list)
    features: dict = field(default_factory=dict)
    period_problem: str = ''
    model: dict = field(default_factory=dict)
    details: dict = field(default_factory=dict)

    @property
    def detected(self) -> bool | None:
        """Return True/False for stiction/no stiction, None when it cannot tell."""
        return None if self.answer == 'cannot tell' else self.answer == 'stiction'

    def to_json(self) -> dict:
        """Return the JSON-able answer (features rounded, no arrays)."""
        return {'answer': self.answer, 'probability': self.probability, 'reason': self.reason,
                'judgeable': self.judge.to_json(), 'evidence': self.evidence,
                'period_problem': self.period_problem or None,
                'features': {k: (None if not np.isfinite(v) else round(float(v), 5))
                             for k, v in self.features.items()},
                'model': self.model, **self.details}


@lru_cache(maxsize=4)
def _model(path: str | None) -> model_file.TreeModel:
    model = model_file.load(path, FEATURE_NAMES)
    # Loaded here, not first after the slow fits, so a bad network file is
    # refused before any record is read.  The trees learned what this
    # network's logit means; one retrained since (make cnn without make
    # detector) would feed them another.
    net = cnn.load()
    trained_with = model.meta.get('cnn_sha256')
    if trained_with is not None and trained_with != net.sha256:
        raise DetectorFileError(
            f'{path or model_file.DEFAULT_PATH}: trained with another CNN ({trained_with[:12]}) '
            f'than the one shipped ({net.sha256[:12]}); rebuild with `make detector`')
    stack.check_network(model.meta, str(path or model_file.DEFAULT_PATH))
    return model


def load_model(path: str | None = None) -> model_file.TreeModel:
    """Return the detector model at ``path`` (default: the shipped one), loaded once."""
    return _model(None if path is None else str(path))


def evidence_lines(ev: dict, ts: float, rows: np.ndarray | None = None,
                   fresh_only: bool = False) -> list:
    """
    Return the evidence as sentences: which test saw what, where in time.

    ``rows`` maps a sample the features read to its row in the record (held
    rows dropped); None when they are the same.  ``fresh_only``: held rows
    were dropped, so a signature's own counts are of the fresh rows.
    """
    def _t(k: int, ts: float) -> str:
        return f'{record_row(k, rows) * ts:.0f} s'
    out = []
    st = ev['stuck']
    if st.stuck and not st.slips:
        # Said before the periods: a batch row shows two lines, and stuck periods
        # alone beside "no stiction" read as a contradiction; they are not one
        # (docs/DETECTION_LOG.md, "Sticky records that look like a deadband").
        out.append('no slip after any stuck period: a valve that stands still while OP '
                   'travels and then moves on without a jump is what a deadband (play in '
                   'the actuator or linkage) leaves as well as stiction, and OP and PV '
                   'alone cannot tell the two apart; stuck periods alone do not make the '
                   'answer, and a valve travel test tells')
    # The three with the most OP travel, in the order they happened.
    for a, b, travel in sorted(sorted(st.stuck, key=lambda s: -s[2])[:3]):
        out.append(f'stuck period {_t(a, ts)}-{_t(b, ts)}: OP moved through a range of '
                   f"{travel:.3g} (in OP's own units, % of its span on most plants) while the "
                   'valve proxy stayed within its noise')
    if st.stuck:
        # Integral action on a constant error ramps OP in a straight line; a
        # loop holding PV against a load that wanders has neither.
        held = 10.0 ** st.log_offset - 1.0
        shape = ('in a straight ramp' if st.ramp_r2 >= RAMP_R2 else 'but not in a straight ramp')
        line = (f'in its stuck periods OP moved {shape} (R^2 {st.ramp_r2:.2f} of a line) on '
                f'an error held {held:.3g} standard errors off zero')
        if st.ramp_r2 >= RAMP_R2 and held >= HELD_ERRORS:
            # A load drifting at a steady rate leaves the same trace under PI
            # control (the ramp cancels it): said, so that neither answer reads
            # as a contradiction of this line.
            line += (': what a stuck valve leaves, and also a load drifting at a steady rate '
                     'that the ramp cancels; a slip, or PV answering when OP turns, tells them '
                     'apart')
        out.append(line)
    for k, z in sorted(st.slips, key=lambda s: -s[1])[:3]:
        out.append(f'slip at {_t(k, ts)}: the valve proxy jumped {z:.1f} noise widths '
                   f'(no set-point step before it)')
    osc = ev['oscillation']
    if osc.oscillating and ev['period_problem']:
        out.append(f'oscillation not voted on: {ev["period_problem"]}')
    elif osc.oscillating:
        out.append(f'regular oscillation of the error: period {osc.period_s:.4g} s '
                   f'({osc.period_s / ts:.1f} samples), regularity {osc.regularity:.2f}')
    for name in VOTERS:
        s = ev['signatures'].get(name)
        if s is not None and s.stiction is not None:
            if ev['period_problem'] and name in ('horch', 'he_curve_fit', 'hos_pv_op'):
                continue
            # One signature's own vote, which the detector weighs with the rest:
            # said as such, so that it does not read as the verdict.
            # With held rows dropped its counts differ from the report's signature table,
            # which reads every row: say which rows these are.
            rows_read = ', on the fresh rows the detector read' if fresh_only else ''
            why = s.reason
            if name == 'slip_events' and s.stiction and rows is not None:
                # Its time counts the samples read; said on the record's clock.
                first = s.details['events'][0]
                why = found_text(int(s.value), first,
                                 record_row(round(first['t'] / ts), rows) * ts)
            out.append(f'{name} on its own: {"stiction" if s.stiction else "no stiction"} '
                       f'({why}{rows_read})')
    return out


def detect(op: np.ndarray, pv: np.ndarray, sp: np.ndarray | None, sample_time: float,
           integrating: bool = False, model_path: str | None = None,
           realign: bool = True, first_row: int = 0) -> Detection:
    """
    Return the :class:`Detection` of one contiguous stretch of OP, PV (and SP).

    ``realign=False`` reads a skewed or lagged record as given (``make robustness``
    compares the two; the analyzer always realigns).  ``first_row`` is the
    record's row the stretch starts on: the evidence's times count from the
    record's start.
    Raises :class:`model_file.DetectorFileError` when the model file is
    missing or damaged (never a silent fallback).
    """
    model = load_model(model_path)
    info = {'file': model.meta.get('file', ''), 'version': model.meta.get('version'),
            'trained_on': model.meta.get('trained_on', '')}
    # A historian's held rows are not measurements (stale.py); the evidence
    # below names rows of the record as given, not of the fresh rows read.
    op, pv, sp, held = drop_held(op, pv, sp)
    holds = {'held_rows': held.count} if held.count else {}
    if sp is None:
        holds['set_point_given'] = False
    judge = holds_judgeable(held, sample_time)
    if judge.ok:
        judge = interpolated.lines_judgeable(pv)
    skew = None
    if judge.ok:
        # Tags stamped on different clocks are realigned by the controller's own law.
        if realign:
            skew, op, pv, sp, kept = timing.realign(op, pv, sp, held.count)
        else:
            skew = replace(timing.alignment(op, pv, sp), shift=0, lag=0.0)
        holds['timing'] = skew.to_json()
        judge = judgeable(op, pv, sample_time, sp)
        if judge.code == 'too_short' and held.count:
            # The count is of fresh rows; the stretch the engineer sees holds more.
            judge = replace(judge, reason=f"{judge.reason} ({held.count} of the stretch's "
                            f'{len(held.held)} rows repeat the previous row '
                            'exactly in OP and PV: historian holds, not read)')
    if not judge.ok:
        return Detection('cannot tell', None, judge.reason, judge, model=info, details=holds)
    vec, ev = extract(op, pv, sp, sample_time, integrating)
    rows = held.kept if held.count else None
    if skew.shift:
        rows = kept if rows is None else rows[kept]
    if first_row:
        rows = (np.arange(len(op)) if rows is None else np.asarray(rows)) + int(first_row)
    lines = evidence_lines(ev, sample_time, rows, fresh_only=bool(held.count))
    if held.count:
        # A row or two held in 751 is routine; a third of the record is not.
        lines.insert(0 if held.share >= NOTABLE else len(lines), held.describe(sample_time))
    if skew.describe(sample_time):
        # A lag named but not undone changed nothing read: a caveat, after the findings.
        if skew.declined == timing.LEAD:
            lines.append(skew.describe(sample_time))
        else:
            lines.insert(0, skew.describe(sample_time))
    lerped = interpolated.interpolated_rows(op, pv)
    if lerped.any():
        # Read as they are (a fair guess of the trend), but named: the noise reads low.
        holds['interpolated_rows'] = int(lerped.sum())
        top = 1 if held.count and held.share >= NOTABLE else 0
        lines.insert(top if lerped.mean() >= NOTABLE else len(lines),
                     interpolated.describe(lerped, sample_time))
    if sp is None:
        # A caveat on everything read: the last finding.
        lines.append(NO_SET_POINT)
    osc = ev['oscillation']
    judge = cycle_judgeable(osc.oscillating, osc.period_s, sample_time)
    if not judge.ok:
        return Detection('cannot tell', None, judge.reason, judge, lines, ev['features'],
                         ev['period_problem'], info, holds)
    # The large network reads the same fresh rows as the figures.
    logit = None if model.stack is None else stack.large_logit(op, pv, sp, integrating)
    p = float(model.probability(vec, logit)[0])
    answer = answer_of(p)
    reason = reason_of(p)
    leaned = leaned_on(model, vec, logit)
    # After a notable share of held rows, which says how much of the trend was read.
    lines.insert(1 if held.count and held.share >= NOTABLE else 0, leaned_line(leaned, p))
    # Judged but declined: a script tells this from a record that cannot be judged.
    return Detection(answer, round(p, 4), reason, judge, lines, ev['features'],
                     ev['period_problem'], info,
                     {'stuck': ev['stuck'].to_json(sample_time, rows), **holds,
                      'leaned_on': leaned, 'balanced': answer == 'cannot tell'})


def answer_of(p: float, band: tuple = BAND) -> str:
    """Return the answer at the calibrated probability ``p``: ``band`` decides."""
    if p >= band[1]:
        return 'stiction'
    return 'no stiction' if p < band[0] else 'cannot tell'


def reason_of(p: float, band: tuple = BAND) -> str:
    """Return the sentence that says why ``p`` gave its answer under ``band``."""
    text = probability_text(p, band)
    if p >= band[1]:
        return f'learned detector: probability of stiction {text} (at or above {band[1]})'
    if p < band[0]:
        return f'learned detector: probability of stiction {text} (below {band[0]})'
    lean = 'stiction' if p >= THRESHOLD else 'no stiction'
    return (f'the evidence is balanced: probability of stiction {text}, between {band[0]} and '
            f'{band[1]}, leaning to {lean}; an answer needs odds of 3:1, and a valve travel '
            'test would tell: small OP steps in manual, each held until PV settles')


def probability_text(p: float, band: tuple | None = None) -> str:
    """
    Return ``p`` as the analyzer prints it: two decimals, three in the tails.

    The calibration's lowest and highest steps read about 0.001 and 0.999;
    printed to two decimals they would read 0.00 and 1.00, a certainty that a
    thousand calibration records cannot support.  With the answer's ``band``,
    a value that would round onto one of its edges gets four decimals.
    """
    text = f'{p:.3f}' if p < 0.01 or p > 0.99 else f'{p:.2f}'
    if band is not None and float(text) in band and p not in band:
        # 0.7499 would read "0.75, between 0.25 and 0.75".
        text = f'{p:.4f}'
    return text


def leaned_on(model: model_file.TreeModel, vec: np.ndarray, large_logit: float | None = None,
              top: int = LEANED_ON) -> dict:
    """
    Return which figures moved the detector's score of ``vec`` most, and by how much.

    ``contributions`` are in log-odds of the score the calibration map reads:
    positive toward stiction.  ``start`` is the score of a record the trees
    know nothing about (the training records' mean leaf); with a stack the
    trees' parts are weighed as the stack weighs them and the large network's
    logit is one more part (``cnn_large_logit``).  ``start`` plus every part
    is ``score``.
    """
    bias, per = model.contributions(vec)
    names, x = list(model.feature_names), list(np.ravel(vec))
    w = model.stack
    if w is not None:
        bias, per = w[0] + w[1] * bias, w[1] * per
        names.append('cnn_large_logit')
        x.append(float(large_logit))
        per = np.append(per, w[2] * float(large_logit))
    order = np.argsort(-np.abs(per))[:top]
    return {'start': round(float(bias), 3), 'score': round(float(bias + per.sum()), 3),
            'contributions': [{'feature': names[i],
                               'value': None if not np.isfinite(x[i]) else round(float(x[i]), 4),
                               'log_odds': round(float(per[i]), 3)} for i in order]}


def leaned_line(leaned: dict, probability: float | None = None) -> str:
    """
    Return the terminal sentence of :func:`leaned_on`.

    The score is in log-odds before calibration; ``probability``, when given,
    is what the calibration map reads it as, said so that the two numbers on
    the screen are not taken for one scale.
    """
    def one(c: dict) -> str:
        value = 'missing' if c['value'] is None else f'{c["value"]:.3g}'
        return f'{words(c["feature"])} = {value} ({c["log_odds"]:+.2f})'
    parts = [one(c) for c in leaned['contributions']]
    mapped = ('' if probability is None else
              f', which the calibration map reads as a probability of '
              f'{probability_text(probability)}')
    return (f'the learned detector leaned most on {", ".join(parts)} (log-odds toward '
            f'stiction; all the parts together move its score from {leaned["start"]:+.2f}, '
            f'before any figure is read, to {leaned["score"]:+.2f}{mapped})')
