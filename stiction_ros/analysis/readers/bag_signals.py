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
"""

from datetime import datetime, timezone
from pathlib import Path

import numpy as np
from stiction_ros.analysis.readers import align
from stiction_ros.analysis.record import assemble, InputError, SIGNALS
from stiction_ros.bag.reader import BagReadError, read_bag

FLOAT64 = 'std_msgs/msg/Float64'
# Stamps after this (2001-09-09) are taken as wall-clock time; earlier is sim time.
EPOCH_LIKE = 1e9
MAX_SAMPLES = 50_000_000


def read_bag_record(path, namespace=None):
    """Return the :class:`Record` of the loop topics of the bag at ``path``."""
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
    origin = ref / 1e9 + center + (k0 - 0.5) * ts
    start = None
    if origin > EPOCH_LIKE:
        start = datetime.fromtimestamp(origin, timezone.utc).isoformat()
    source = {'path': str(path), 'format': 'bag', 'stamps': stamp_kind,
              'topics': {name: topic.name for name, topic in topics.items()},
              'phases': phases}
    return assemble(signals, ts, notes=notes, source=source, start_time=start,
                    name=prefix or Path(path).name, time_origin=float(origin))


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
