"""
``recorder`` node: records topics to a rosbag2 bag directory (MCAP + metadata.yaml).

Like ``ros2 bag record -s mcap``: each topic is subscribed as soon as a
publisher of it appears, with the publisher's type, and the CDR bytes are
stored exactly as received (``raw=True``), with the offered QoS and type
hash in the channel metadata.  The log time is the time of reception and the
publish time the sender's source timestamp, as rosbag2 does.

Under ``use_sim_time`` both stamps are the sim time in force when the
message was *sent*: its DDS source stamp mapped through the source stamps of
the ``/clock`` messages.  Stamping with the recorder's clock when it gets
round to a message puts messages of an accelerated run up to a sample late;
arrival stamps still jitter by a quarter sample.  Send stamps are exact when
the clock runs in lockstep (it publishes the next tick only after it has
received the message), and need sender and recorder on one machine clock.
A message sent after the newest ``/clock`` the recorder has seen waits in a
small queue until the next ``/clock`` arrives, since that one may have been
sent before it.

The open chunk goes to disk every ``flush_period`` wall seconds, so a
SIGKILL loses at most that much.  SIGINT/SIGTERM finish the file, with every
message that had reached the recorder's queues, and further signals cannot
interrupt that (``run.py``).

Disk space: the recorder refuses to start with less than ``min_free_mb``
free where the bag goes, and finishes the bag cleanly (summary, index,
metadata.yaml) when free space falls below it during the run, then counts
what it could not record.  A write that fails anyway (the disk filled
faster, a quota, a file-size limit) stops the recording with one error
naming the cause; the process keeps running and what was flushed before is
recovered by ``stiction-bag repair``.

Example::

    ros2 run stiction_ros recorder --ros-args -p output:=run1 -p topics:="['op', 'mv']"
"""

from pathlib import Path
import re
import shutil
import sys

from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rosgraph_msgs.msg import Clock as RosClock
from stiction_ros.bag.metadata import INFINITE
from stiction_ros.bag.writer import BagError, BagWriter, COMPRESSION
from stiction_ros.nodes.params import check_choices, declare, Param
from stiction_ros.nodes.run import run
from stiction_ros.nodes.sampled import StartupError

# Most messages one callback takes from its topic's queue before yielding to the executor.
DRAIN_LIMIT = 1000
CLOCK_DEPTH = 1000
_TYPE_NAME = re.compile(r'^[A-Za-z_][A-Za-z0-9_]*/msg/[A-Za-z][A-Za-z0-9_]*$')


def _duration(d):
    ns = d.nanoseconds
    if ns <= 0 or ns >= 9223372036854775807:
        return dict(INFINITE)
    sec, nsec = divmod(ns, 10**9)
    return {'sec': int(sec), 'nsec': int(nsec)}


def qos_dict(qos):
    """Return a publisher's QoS as rosbag2 version 9 writes it."""
    def name(policy):
        return policy.name.lower() if policy is not None else 'unknown'
    return {
        'history': name(qos.history), 'depth': int(qos.depth),
        'reliability': name(qos.reliability), 'durability': name(qos.durability),
        'deadline': _duration(qos.deadline), 'lifespan': _duration(qos.lifespan),
        'liveliness': name(qos.liveliness),
        'liveliness_lease_duration': _duration(qos.liveliness_lease_duration),
        'avoid_ros_namespace_conventions': bool(qos.avoid_ros_namespace_conventions),
    }


class RecorderNode(Node):
    """Writes every message of the chosen topics to one bag."""

    @staticmethod
    def declared_params() -> list:
        """Return every parameter the recorder declares (``--help`` lists them)."""
        return [
            Param('output', '', 'Bag directory to create (must not exist or be empty).',
                  read_only=True),
            Param('topics', ['sp', 'op', 'mv', 'pv', 'held_inputs'],
                  'Topics to record; relative names '
                  "resolve in the recorder's namespace.", read_only=True),
            Param('compression', 'zstd', 'Chunk compression.', choices=tuple(COMPRESSION),
                  read_only=True),
            Param('chunk_size', 262144, 'Chunk size before compression, bytes.', 1024,
                  2**31 - 1, read_only=True),
            Param('flush_period', 1.0, 'Wall seconds between writes of the open chunk: the '
                  'most a SIGKILL can lose.', 0.01, 3600.0, read_only=True),
            Param('depth', 1000, 'Subscription queue depth (reliable): how far the recorder '
                  'may fall behind without losing messages.', 1, 1000000, read_only=True),
            Param('min_free_mb', 64.0, 'Free disk space, MB, below which the recorder does not '
                  'start, or finishes the bag cleanly during the run.', 0.0, 1e9,
                  read_only=True),
        ]

    def __init__(self):
        super().__init__('recorder')
        self.specs = self.declared_params()
        v = self.values = declare(self, self.specs)
        reason = check_choices(self.specs, v)
        if reason:
            raise StartupError(reason)
        if not v['output']:
            raise StartupError('recorder: set the bag directory with -p output:=DIR')
        free = _free_mb(v['output'])
        if free < v['min_free_mb']:
            raise StartupError(f'recorder: only {free:.0f} MB free for {v["output"]} (min_free_mb '
                               f'is {v["min_free_mb"]:g}); free some space or record elsewhere')
        try:
            self.writer = BagWriter(v['output'], compression=v['compression'],
                                    chunk_size=v['chunk_size'])
        except BagError as err:
            raise StartupError(str(err)) from None
        self.wanted = [self.resolve_topic_name(t) for t in v['topics'] if t]
        self._clock_wall, self._clock_sim, self._pending = [], [], []
        self._sim = self.get_parameter('use_sim_time').value
        self._clock_sub = None
        if self._sim:
            self._clock_sub = self.create_subscription(
                RosClock, '/clock', self._on_clock,
                QoSProfile(depth=CLOCK_DEPTH, reliability=ReliabilityPolicy.RELIABLE))
        self.subs = {}
        self._unflushed = 0
        self._closed = False
        self.stopped = None     # why recording stopped early, if it did
        self.not_recorded = 0
        self.publishers_of, self.last_seq, self.gaps = {}, {}, {}
        self.unchecked = set()
        self.before_match = 0
        wall = Clock(clock_type=ClockType.STEADY_TIME)
        self.create_timer(0.05, self._discover, clock=wall)
        self.create_timer(v['flush_period'], self._flush, clock=wall)
        self._discover()
        self.get_logger().info(f'recording {self.wanted} to {v["output"]}')

    def _discover(self):
        for name in self.wanted:
            if name in self.subs:
                continue
            pubs = self.get_publishers_info_by_topic(name)
            if not pubs:
                continue
            types = sorted({p.topic_type for p in pubs})
            if len(types) > 1:
                self.get_logger().error(f'{name}: publishers disagree on the type {types}; '
                                        'not recorded', throttle_duration_sec=10.0)
                continue
            try:
                self.writer.add_topic(name, types[0], [qos_dict(p.qos_profile) for p in pubs],
                                      str(pubs[0].topic_type_hash))
                msg_type = _import_type(types[0])
            except (LookupError, ImportError, AttributeError) as err:
                self.get_logger().error(f'{name}: cannot record type {types[0]}: {err}',
                                        throttle_duration_sec=10.0)
                continue
            qos = QoSProfile(depth=self.values['depth'], history=HistoryPolicy.KEEP_LAST,
                             reliability=ReliabilityPolicy.RELIABLE,
                             durability=DurabilityPolicy.VOLATILE)
            if all(p.qos_profile.reliability == ReliabilityPolicy.BEST_EFFORT for p in pubs):
                qos.reliability = ReliabilityPolicy.BEST_EFFORT
            self.publishers_of[name] = len(pubs)
            self.subs[name] = self.create_subscription(
                msg_type, name, self._callback(name), qos, raw=True)
            self.get_logger().info(f'subscribed to {name} [{types[0]}]')

    def _on_clock(self, msg, info):
        self._clock_wall.append(info['source_timestamp'])
        self._clock_sim.append(msg.clock.sec * 10**9 + msg.clock.nanosec)
        if len(self._clock_wall) > 20000:
            del self._clock_wall[:10000], self._clock_sim[:10000]
        while self._pending and self._pending[0][2] < self._clock_wall[-1]:
            self._write(*self._pending.pop(0))

    def _sim_time_at(self, sent):
        walls = self._clock_wall
        i = len(walls) - 1
        while i >= 0 and walls[i] > sent:
            i -= 1
        return self._clock_sim[i] if i >= 0 else self.get_clock().now().nanoseconds

    def _write(self, name, data, sent, received=None):
        if self.stopped:
            self.not_recorded += 1
            return
        if self._sim:
            # Both stamps in sim time: the wall send stamp would be decades
            # after the log time, which validators flag and no reader can relate.
            received = sent = self._sim_time_at(sent)
        try:
            self.writer.write(name, data, received, sent)
        except OSError as err:
            self._fail(err)
            self.not_recorded += 1
            return
        self._unflushed += 1

    def _fail(self, err):
        self.stopped = f'cannot write {self.writer.directory}: {err.strerror or err}'
        self.get_logger().error(
            f'{self.stopped}; recording stopped after {self.writer.message_count} messages. '
            f'What reached the disk is recovered by: stiction-bag repair {self.writer.directory}')

    def _store(self, name, data, info):
        self._count_sequence(name, info.get('publication_sequence_number'))
        sent = info['source_timestamp']
        if not self._sim:
            self._write(name, data, sent, info['received_timestamp'])
        elif self._pending or not self._clock_wall or sent >= self._clock_wall[-1]:
            self._pending.append((name, data, sent))
        else:
            self._write(name, data, sent)

    def _callback(self, name):
        def on_message(data, info):
            self._store(name, data, info)
            # Drain what else has arrived on this topic now: the executor spends tens
            # of microseconds per wake-up, taking a message costs a few.  Bounded, so
            # the flush and /clock callbacks still run under a flood.
            self._take(name, DRAIN_LIMIT)
        return on_message

    def _take(self, name, limit):
        """Store up to ``limit`` messages waiting in topic ``name``'s queue."""
        sub = self.subs.get(name)
        for _ in range(limit if sub is not None else 0):
            with sub.handle:
                got = sub.handle.take_message(sub.msg_type, True)
            if got is None:
                break
            self._store(name, *got)

    def _drain(self):
        """Store every message that reached a queue before the stop and was not taken yet."""
        # At a stop the spin ends with the last messages of the loop still in the DDS
        # queues (all nodes of a launch get the signal at once).  Taking works after the
        # context is shut down, as long as the subscription exists.  /clock first: the
        # send stamps of the messages map through it.  Bounded by the queue depths, so
        # that a publisher that goes on sending cannot keep the stop waiting.
        clock = self._clock_sub
        for _ in range(CLOCK_DEPTH if clock is not None else 0):
            with clock.handle:
                got = clock.handle.take_message(clock.msg_type, False)
            if got is None:
                break
            self._on_clock(*got)
        for name in list(self.subs):
            self._take(name, self.values['depth'])

    def _count_sequence(self, name, seq):
        # A publisher numbers its messages: a jump is a message lost on the way, and a
        # first number above 1 counts those sent before this subscription matched.  The
        # numbers are per publisher and the message info does not say which one sent it,
        # so a topic that ever has several publishers (or a restarted one) is not checked.
        if not seq or name in self.unchecked:
            return
        last = self.last_seq.get(name)
        if self.publishers_of.get(name, 0) != 1 or (last is not None and seq <= last):
            self.unchecked.add(name)
            return
        if last is None:
            self.before_match += seq - 1
        elif seq > last + 1:
            self.gaps[name] = self.gaps.get(name, 0) + seq - last - 1
        self.last_seq[name] = seq

    @property
    def transport_lost(self):
        """Return the messages lost on the way, over the topics that could be checked."""
        return sum(n for name, n in self.gaps.items() if name not in self.unchecked)

    def _flush(self):
        for name in self.subs:
            self.publishers_of[name] = len(self.get_publishers_info_by_topic(name))
        if self.stopped:
            return
        free = _free_mb(self.writer.directory)
        try:
            if free < self.values['min_free_mb']:
                self.writer.close()
                self.stopped = f'only {free:.0f} MB left on disk'
                self.get_logger().error(
                    f'{self.stopped} (min_free_mb {self.values["min_free_mb"]:g}): the bag is '
                    f'finished and complete with {self.writer.message_count} messages; '
                    'nothing more is recorded')
            elif self._unflushed:
                self.writer.flush_chunk()
                self._unflushed = 0
        except OSError as err:
            self._fail(err)

    def close(self):
        """Store what was received, finish the bag and report; only the first call acts."""
        if self._closed:
            return
        self._closed = True
        self._drain()
        for item in self._pending:
            self._write(*item)
        self._pending = []
        if not self.stopped:    # after a failed write the file is left for repair as it is
            try:
                self.writer.close()
            except OSError as err:
                self._fail(err)
        counts = ', '.join(f'{n}: {t["count"]}' for n, t in self.writer.topics.items())
        print(f'recorder: wrote {self.writer.message_count} messages to '
              f'{self.writer.directory} ({counts}); {self.transport_lost} lost on the way '
              f"(gaps in the publishers' sequence numbers; {len(self.unchecked)} topics with "
              f'several publishers not checked), {self.before_match} sent before the recorder '
              'subscribed', file=sys.stderr)
        if self.stopped:
            print(f'recorder: stopped early ({self.stopped}); {self.not_recorded} messages '
                  'received after that were not recorded', file=sys.stderr)


def _free_mb(path):
    # The nearest existing directory: the bag directory may not exist yet.
    p = Path(path).absolute()
    while not p.exists() and p != p.parent:
        p = p.parent
    return shutil.disk_usage(p).free / 2**20


def _import_type(type_name):
    # The type name comes from the graph: import only what looks like pkg/msg/Type.
    if not _TYPE_NAME.match(type_name):
        raise ImportError(f'{type_name!r} is not a message type name')
    pkg, kind, name = type_name.split('/')
    module = __import__(f'{pkg}.{kind}', fromlist=[name])
    return getattr(module, name)


def main(args=None):
    """Run the recorder until SIGINT/SIGTERM."""
    return run(RecorderNode, args, 'recorder')


if __name__ == '__main__':
    sys.exit(main())
