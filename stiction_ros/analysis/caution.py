"""
Why S and J fitted to MV may not be trusted at the record's sampling.

The cautions the analyzer attaches to a size read from MV (``size_caution``):
a loop that cycles in fewer samples than a cycle's shape needs has the
valve's turning points between samples.  And the smallest slip jump the
sampling resolves (:func:`step_while_moving`).
"""

import numpy as np

from stiction_ros.analysis.detection.resolve import alternating, MIN_SAMPLES
from stiction_ros.analysis.oscillation import detect_oscillation, MIN_PERIOD_SAMPLES
from stiction_ros.analysis.record import Record


def valve_sampling_caution(record: Record, sticks: bool, min_samples: int) -> str:
    """
    Return :func:`sampling_caution` for a record without PV: OP's own cycle, MV for PV.

    OP cycles with the loop (a sticky valve's limit cycle is a sawtooth in
    OP), so its period says how many samples a cycle holds; '' when no
    stretch of OP and MV is ``min_samples`` long.
    """
    stretches = record.segments(min_samples)
    if not stretches or not record.has('mv'):
        return ''
    a, b = max(stretches, key=lambda r: r[1] - r[0])
    op, mv = record.signals['op'][a:b], record.signals['mv'][a:b]
    osc = detect_oscillation(op - np.mean(op), record.sample_time)
    return sampling_caution({'op': op, 'pv': mv, 'sp': None}, osc, record.sample_time,
                            sticks, 'MV')


def sampling_caution(held: dict, osc, sample_time: float, sticks: bool,
                     pv_name: str = 'PV') -> str:
    """
    Return why S and J fitted to MV cannot be trusted at this sampling, or ''.

    MV is measured, so the fits see no alias; but a loop cycling in fewer
    than 10 samples has its turning points, where the valve sticks and
    slips, between samples.  Table 2.1's loop with S 5 %, J 2 % (a 144 s
    cycle) fitted 4.71 % at 18 s and 2.89 % at 60 s, each 95 % range short
    of 5 %.  ``sticks``: the fits report a band (stiction, or cannot tell
    beside one), so it reads low;
    otherwise a band this sampling cannot resolve may have been missed.
    ``pv_name``: what ``held['pv']`` holds (MV where the record has no PV).
    """
    if len(held['pv']) >= MIN_SAMPLES and alternating(held['op'], held['pv']):
        seen = (f'OP and {pv_name} alternate from sample to sample (a cycle of 2-3 samples '
                f'of {sample_time:g} s)')
    elif (osc is not None and osc.oscillating and osc.period_s
          and osc.period_s / sample_time < MIN_PERIOD_SAMPLES):
        seen = (f'the loop cycles every {osc.period_s:.4g} s, only '
                f'{osc.period_s / sample_time:.1f} samples of {sample_time:g} s (at least '
                f'{MIN_PERIOD_SAMPLES:g} a cycle: record at '
                f'{osc.period_s / MIN_PERIOD_SAMPLES:.3g} s or faster, or faster still: at '
                'this sampling the true cycle may alias to a longer one)')
    else:
        return ''
    if sticks:
        return (f"{seen}; S and J fitted to MV at this sampling miss the valve's turning "
                'points between samples: they read low, and their 95 % ranges do not allow '
                'for it')
    return (f"{seen}; the valve's turning points fall between samples, so a small band may "
            'have been missed')


def step_while_moving(op: np.ndarray, position: np.ndarray, segments) -> float:
    """
    Return OP's median move in one sample while a fitted valve moves (0 where it never does).

    A valve breaks away somewhere between two samples, so play taken up
    between them shows at the next sample as a jump of up to OP's move in
    that sample: a slip jump no larger than this is not resolved.
    ``position``: the fit's MV (``pipeline.predict``); ``segments``: the
    scored ``(start, stop)`` ranges.
    """
    moves = []
    for a, b in segments:
        d_op = np.abs(np.diff(op[a:b]))
        moved = np.diff(position[a:b]) != 0.0
        moves.append(d_op[moved & np.isfinite(d_op)])
    steps = np.concatenate(moves) if moves else np.empty(0)
    return float(np.median(steps)) if steps.size else 0.0


def slips(position: np.ndarray, segments) -> int:
    """
    Return how many runs of movement a fitted valve makes in the scored segments.

    A fit whose valve never leaves its first position (or does so once or
    twice) fits MV as a constant, whatever its S and J: its band and slip
    jump are not identified, however narrow their ranges.  Each segment is
    read on its own: a move under way at its start counts, and a move that
    runs on through a gap counts in each segment.  A step to or from a
    non-finite position is no move.
    """
    count = 0
    for a, b in segments:
        step = np.diff(position[a:b])
        moving = np.isfinite(step) & (step != 0.0)
        count += int(np.sum(moving[1:] & ~moving[:-1])) + int(moving[:1].sum())
    return count
