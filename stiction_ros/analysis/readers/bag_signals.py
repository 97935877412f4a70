"""
Read the loop signals of a bag: Float64 topics ``op``, ``mv``, ``pv``, ``sp`` under one namespace.

The grid is that of ``op``: its median spacing is the sample time and its
stamps lie mid-bin.  Each other topic is shifted by its own mean phase
relative to ``op``, taken in [-Ts/2, Ts/2), so a value published up to half
a sample before ``op`` or less than half a sample after belongs to ``op``'s
sample.  For the project's live loop (PV at 1/4, OP at 1/2, MV at 3/4 of
the sample) that puts pv(k), op(k), mv(k) together, as ``floor(t / Ts)``
does.  Stamps: the send time (``publish_time``) where the bag has it on the
same clock as the receive time, else the receive time (``log_time``).

A ``held_inputs`` topic (the loop nodes publish one message per sample at
which they acted on an input that had not been refreshed, with the value
they acted on) corrects or excludes those samples.  Where the valve held OP,
the recorded ``op`` (what the controller sent) is not what moved the valve:
it is replaced by the value the valve used, so the valve models see their
real input and keep their state.  Where the plant held MV or the controller
PV, the sample is excluded from the loop analysis, but the valve fits keep
it: OP and MV there are the valve's true input and output, and restarting
the model after every such sample would lose its state (stuck or moving,
direction), which costs more than any sample.
"""

from datetime import datetime, timezone
import math
from pathlib import Path

import numpy as np
from stiction_ros.analysis.readers import align
from stiction_ros.analysis.record import assemble, InputError, SIGNALS
from stiction_ros.bag.reader import BagReadError, read_bag
from stiction_ros.sim.ros_params import INPUT_LIMIT

FLOAT64 = 'std_msgs/msg/Float64'
KEY_VALUE = 'diagnostic_msgs/msg/KeyValue'
HELD = ('a loop node acted on a held input (a message lost or late, or its sender down): '
        'the plant on an old MV or the controller on an old PV (the valve fits keep these '
        'samples: their OP and MV are right)')
NO_OP = ('the valve acted before any OP reached it (the first ones lost or late) and held '
         'its position: the OP recorded there is not what it used')
# Stamps after this (2001-09-09) are taken as wall-clock time; earlier is sim time.
EPOCH_LIKE = 1e9
MAX_SAMPLES = 50_000_000


def read_bag_record(path, namespace=None, held=True):
    """
    Return the :class:`Record` of the loop topics of the bag at ``path``.

    ``held=False`` ignores ``held_inputs``: the signals as recorded.
    """
    try:
        bag = read_bag(path)
    except BagReadError as err:
        raise InputError(str(err)) from None
    prefix = _prefix(path, bag, namespace)
    notes = []
    if not bag.complete:
        total = sum(t.count for t in bag.topics.values())
        notes.append(f'bag truncated: read {total} messages')
    notes += list(bag.warnings)
    topics = {}
    for name in SIGNALS:
        topic = bag.topics.get(f'{prefix}/{name}')
        if topic is None:
            continue
        if topic.type != FLOAT64 or not topic.count:
            why = f'is {topic.type or "of unknown type"}, not {FLOAT64}' if topic.count else \
                'has no messages'
            if name == 'op':
                hint = f' ({bag.warnings[0]})' if bag.warnings else ''
                raise InputError(f'{path}: topic {topic.name} {why}{hint}')
            notes.append(f'ignored {topic.name}: it {why}')
            continue
        topics[name] = topic
    stamp_kind = _stamp_kind(topics['op'])
    ref = int(np.min(getattr(topics['op'], stamp_kind)))
    series = {}
    for name, topic in topics.items():
        try:
            values = topic.values()
        except Exception as err:  # noqa: B902  (any decoding failure is bad input)
            raise InputError(f'{path}: cannot decode {topic.name}: {err}') from None
        ns = np.asarray(getattr(topic, stamp_kind), dtype=np.int64)
        order = np.argsort(ns, kind='stable')
        series[name] = ((ns[order] - ref) / 1e9, np.asarray(values, dtype=np.float64)[order])
    t_op = series['op'][0]
    try:
        ts = align.sample_period(t_op)
    except align.GridError:
        raise InputError(f'{path}: {topics["op"].name}: cannot tell the sample time: its '
                         f'{len(t_op)} message(s) share one time stamp') from None
    center = align.phase(t_op, ts) * ts
    k_op = align.bins(t_op, ts, center)
    stray = align.stray_note(topics['op'].name, t_op, ts, center)
    if stray:
        notes.append(stray)
    k0 = int(k_op[0])
    n = int(k_op[-1]) - k0 + 1
    if n > MAX_SAMPLES:
        raise InputError(f'{path}: {topics["op"].name} spans {n} samples of {ts:g} s; '
                         'its time stamps are not one recording')
    signals, phases = {}, {}
    for name, (t, v) in series.items():
        ph = 0.0 if name == 'op' else align.phase(t - center, ts)
        phases[name] = round(ph, 3)
        k = align.bins(t, ts, center + ph * ts) - k0
        signals[name], crowded, dropped, outside = align.place(k, v, n)
        note = align.crowding_note(name, crowded, dropped, ts)
        if note:
            notes.append(note)
        if outside:
            notes.append(f'{name}: ignored {outside} message' + ('s' if outside > 1 else '')
                         + " outside op's time range")
    reasons = {}
    # OP and MV are % of span: a value the loop's nodes would have rejected (a stray
    # publisher, a test message) is none of the loop's.  PV and SP are in engineering
    # units (a pressure in Pa may pass 1e6): only the any-file rule of assemble holds.
    absurd = {k: np.isfinite(v) & (np.abs(v) > INPUT_LIMIT) for k, v in signals.items()
              if k in ('op', 'mv')}
    if any(m.any() for m in absurd.values()):
        names = ', '.join(k for k, m in absurd.items() if m.any())
        reasons[f"{names} beyond +-1e6 % of span, which the loop's nodes reject (their "
                'input_limit)'] = np.any(list(absurd.values()), axis=0)
        signals.update({k: np.where(m, np.nan, signals[k]) for k, m in absurd.items()})
    held = bag.topics.get(f'{prefix}/held_inputs') if held else None
    if held is not None and held.type == KEY_VALUE and held.count:
        mask, used, note = _held_marks(held, ref, ts, center, k0, n)
        fixed = np.isfinite(used) & np.isfinite(signals['op'])
        if fixed.any():
            signals['op'] = np.where(fixed, used, signals['op'])
            notes.append(f'op: {int(fixed.sum())} samples hold the OP the valve acted on, not '
                         'the one the controller sent (lost or late on the way)')
        none = np.isinf(used)
        reasons[HELD] = mask
        if none.any():
            reasons[NO_OP] = none
        if note:
            notes.append(note)
    origin = ref / 1e9 + center + (k0 - 0.5) * ts
    start = None
    if origin > EPOCH_LIKE:
        start = datetime.fromtimestamp(origin, timezone.utc).isoformat()
    source = {'path': str(path), 'format': 'bag', 'stamps': stamp_kind,
              'topics': {name: topic.name for name, topic in topics.items()},
              'phases': phases, 'sampling': f'the spacing of the {topics["op"].name} messages'}
    if not bag.complete or bag.warnings:
        # Damage to the file itself: the terminal shows these, not only the notes.
        source['warnings'] = list(bag.warnings) or [notes[0]]
    record = assemble(signals, ts, reasons=reasons, notes=notes, source=source,
                      start_time=start, name=prefix or Path(path).name,
                      time_origin=float(origin))
    if HELD in reasons and 'mv' in signals:
        # The record's signals: assemble has read a value beyond any instrument as none.
        record.valve_ok = (reasons[HELD] & np.isfinite(record.signals['op'])
                           & np.isfinite(record.signals['mv']))
    return record


def _held_marks(topic, ref, ts, center, k0, n):
    """
    Read a ``held_inputs`` topic: each mark is ``sample value`` for one input.

    Returns the samples to exclude (a held MV or PV), the OP the valve acted
    on where it held OP (inf where it had none yet, NaN elsewhere), and a
    note if marks cannot be read.
    """
    mask = np.zeros(n, dtype=bool)
    used = np.full(n, np.nan)
    try:
        marks = [(str(m.key).rsplit('/', 1)[-1], *str(m.value).split()) for m in topic.decoded()]
        names = [m[0] for m in marks]
        samples = np.array([int(m[1]) for m in marks], dtype=np.float64)
        values = np.array([float(m[2]) for m in marks])
    except Exception as err:  # noqa: B902  (any decoding failure is bad input)
        return mask, used, f'ignored {topic.name}: cannot read its marks ({err})'
    # A mark carries the node's sample number; OP of that sample was sent at its half,
    # so the mark goes where op's own stamps put that sample, however late it was sent.
    k = align.bins((samples + 0.5) * ts - ref / 1e9, ts, center) - k0
    for name, i, value in zip(names, k, values):
        if not 0 <= i < n:
            continue
        if name == 'op':
            # inf: the valve acted on no OP at all (none had come yet)
            used[i] = value if math.isfinite(value) else math.inf
        else:
            mask[i] = True
    return mask, used, None


def _prefix(path, bag, namespace):
    ops = sorted(n for n in bag.topics if n.rsplit('/', 1)[-1] == 'op')
    if namespace is not None:
        prefix = '/' + str(namespace).strip('/') if str(namespace).strip('/') else ''
        if f'{prefix}/op' not in bag.topics:
            found = ops or list(bag.topics)
            raise InputError(f'{path}: no topic {prefix}/op; '
                             + ('op topics: ' if ops else 'topics: ') + _list(found))
        return prefix
    if not ops:
        raise InputError(f"{path}: no 'op' topic (controller output); topics: "
                         f'{_list(bag.topics)}')
    if len(ops) > 1:
        spaces = ', '.join(repr(n.rsplit('/', 1)[0] or '/') for n in ops)
        raise InputError(f"{path}: {len(ops)} namespaces hold an 'op' topic ({spaces}); "
                         'choose one with the namespace option')
    return ops[0].rsplit('/', 1)[0]


def _stamp_kind(topic):
    pub = np.asarray(topic.publish_time, dtype=np.int64)
    log = np.asarray(topic.log_time, dtype=np.int64)
    if len(pub) < 2 or np.any(pub <= 0) or len(np.unique(pub)) < 2:
        return 'log_time'
    lag = np.median(np.abs(log - pub)) / 1e9
    spacing = np.median(np.diff(np.sort(log))) / 1e9
    # Same clock when the send stamp is within a few samples of the receive
    # stamp; a sim-time log stamp and a wall-clock send stamp are decades apart.
    return 'publish_time' if lag <= 5 * max(spacing, 1e-3) else 'log_time'


def _list(topics):
    return ', '.join(sorted(topics)) or '(none)'
