"""
``sim_clock`` node: publishes ``/clock`` in fixed steps at a chosen real-time factor.

Nodes started with ``use_sim_time:=true`` then run on this clock, so the
2 000 s experiment of Table 2.1 takes about 20 s at ``rtf:=100``.  The clock
advances by exactly ``step`` per message (a quarter of the loop's sample
time, so every node's phase falls on a tick), never faster than ``rtf``.

Lockstep (``sync``): the clock also never runs ahead of the loop.  Given
``['pv@0.25', 'op@0.5', 'mv@0.75']`` (topic and the phase at which its node
publishes), it moves on only when every message due so far has arrived, or
after ``sync_timeout`` wall seconds (counted and logged as a stall).  Each
loop node in turn waits, at its action instant, for its inputs of that
sample (``input_wait`` in ``sampled.py``), since a message that reached the
clock may not have reached them yet.  A busy machine then slows the run down
instead of changing its result: no node misses a sample or acts on an old
input.  While it waits, the clock repeats the current time every 0.1 s: a
node's time source subscribes best-effort, and a node that lost the tick
would never act on it.  A message given up on is counted as lost, so that a
node that skipped a sample costs one stall, not one at every later tick.
Until a topic's first message has come (its node is up and hears the
clock) the clock waits up to ``wait_timeout`` for it, not ``sync_timeout``.

Before it starts, the clock can wait until given topics have enough
subscribers (``wait_for: ['op=2', 'mv=2']``), so that no node misses the start.
It exits at ``stop_at`` seconds of sim time (0: never), once the messages
due by then have come.

A namespaced loop runs on its own clock topic: ``loop`` (and the launch file)
remaps ``/clock`` to ``<namespace>/clock`` for this node and for the time source
of every node of the loop, so that loops on one graph keep their own time.  A
``wait_for`` entry resolves with that remapping (``'/clock=4'`` counts the
subscribers of ``/ns/clock``).
"""

import sys
import time

import rclpy
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rosgraph_msgs.msg import Clock
from std_msgs.msg import Float64
from stiction_ros.nodes.params import declare, Param
from stiction_ros.nodes.run import run
from stiction_ros.nodes.sampled import DATA_QOS as SYNC_QOS, StartupError


# Wall seconds between repeats of the current time while the clock waits for a node.
RESEND = 0.1


class SimClockNode(Node):
    """Publishes sim time; completes ``finished`` at ``stop_at``."""

    @staticmethod
    def declared_params() -> list:
        """Return every parameter the clock declares (``--help`` lists them)."""
        return [
            Param('rtf', 1.0, 'Real-time factor: sim seconds per wall second.', 1e-3, 1e5,
                  read_only=True),
            Param('step', 0.25, 'Sim seconds per /clock message (a quarter sample).', 1e-6, 1e4,
                  read_only=True),
            Param('start', 0.0, 'Sim time of the first message, s.', 0.0, 1e9, read_only=True),
            Param('stop_at', 0.0, 'Sim time at which to stop, s (0: never).', 0.0, 1e9,
                  read_only=True),
            Param('wait_for', [''], 'Start only when these topics have that many subscribers, '
                  "as 'topic=count' (relative names resolve in the namespace of this node).",
                  read_only=True),
            Param('wait_timeout', 60.0, 'Give up waiting after this many wall seconds.', 0.0,
                  1e6, read_only=True),
            Param('sample_time', 1.0, 'Sample time of the loop, s (for sync).', 1e-6, 1e4,
                  read_only=True),
            Param('sync', [''], "Lockstep: wait for these Float64 topics, as 'topic@phase' "
                  '(phase: fraction of sample_time at which the topic is published).',
                  read_only=True),
            Param('sync_timeout', 1.0, 'Wall seconds to wait for a sync topic before moving on.',
                  0.0, 60.0, read_only=True),
            # 0: a loop node waits for its own inputs (input_wait), which no margin here
            # could promise on a busy machine (3 ms still failed now and then).
            Param('sync_margin', 0.0, 'Wall seconds to wait after the last due sync message '
                  'arrived, so that it reaches its other subscribers too.', 0.0, 10.0,
                  read_only=True),
            Param('settle', 1.0, 'Wall seconds to wait after the subscribers appear, so that '
                  'every publisher matches them too.', 0.0, 60.0, read_only=True),
        ]

    def __init__(self):
        super().__init__('sim_clock')
        specs = self.declared_params()
        self.values = declare(self, specs)
        if self.get_parameter('use_sim_time').value:
            raise StartupError('sim_clock must run on wall time (use_sim_time:=false)')
        self.waits = []
        for item in self.values['wait_for']:
            if not item:
                continue
            topic, sep, count = item.partition('=')
            if not sep or not count.isdigit():
                raise StartupError(f"wait_for: {item!r} is not 'topic=count'")
            self.waits.append((self.resolve_topic_name(topic), int(count)))
        self.step_ns = int(round(self.values['step'] * 1e9))
        self.start_ns = int(round(self.values['start'] * 1e9))
        self.ts_ns = int(round(self.values['sample_time'] * 1e9))
        self.syncs = []
        for item in self.values['sync']:
            if not item:
                continue
            topic, sep, phase = item.partition('@')
            try:
                ph = float(phase)
            except ValueError:
                ph = -1.0
            if not sep or not 0.0 <= ph < 1.0:
                raise StartupError(f"sync: {item!r} is not 'topic@phase' with 0 <= phase < 1")
            # the first instant this topic is due: its phase in the first sample
            k0 = -(-self.start_ns // self.ts_ns)
            entry = {'topic': topic, 'first_ns': k0 * self.ts_ns + int(round(ph * self.ts_ns)),
                     'count': 0}
            self.syncs.append(entry)
            self.create_subscription(Float64, topic, self._counter(entry), SYNC_QOS)
        self.stalls = 0
        self._last_arrival = 0.0
        self.n = 0
        self._running = False
        self._last_tick = False
        self.finished = rclpy.task.Future()
        # The time source of every node subscribes best-effort with depth 1.
        self.pub = self.create_publisher(Clock, '/clock', QoSProfile(
            depth=10, reliability=ReliabilityPolicy.RELIABLE))
        self._t0_wall = time.monotonic()
        self._settled_at = None
        self._poll = self.create_timer(0.05, self._wait)

    def _others(self, topic):
        """Count the subscribers of ``topic`` other than this node (its sync counters)."""
        me = (self.get_name(), self.get_namespace())
        return sum((i.node_name, i.node_namespace) != me
                   for i in self.get_subscriptions_info_by_topic(topic))

    def _wait(self):
        have = {t: self._others(t) for t, _ in self.waits}
        missing = [f'{t} ({have[t]}/{n})' for t, n in self.waits if have[t] < n]
        now = time.monotonic()
        if missing:
            if now - self._t0_wall > self.values['wait_timeout']:
                self.get_logger().error('gave up waiting for subscribers: ' + ', '.join(missing))
                self.finished.set_result(2)
            return
        if self._settled_at is None:
            self._settled_at = now
            self._publish(0)
        if now - self._settled_at < self.values['settle']:
            return
        self._poll.cancel()
        self._start_wall = time.monotonic()
        self._period = self.values['step'] / self.values['rtf']
        self._next_wall = self._start_wall
        self._waiting_since = None
        self._running = True
        self.get_logger().info(f'clock running at rtf {self.values["rtf"]}'
                               + (' in lockstep' if self.syncs else ''))
        # Polled finely: the sync margin and the pace are both a few ms at rtf 100.
        self._timer = self.create_timer(min(self._period, 5e-4), self._tick)

    def _counter(self, entry):
        def on_message(msg):
            # Never more than are due: a message forgiven as lost that comes after
            # all must not stand in for the next one.
            entry['count'] = min(entry['count'] + 1, self._due_count(entry))
            self._last_arrival = time.monotonic()
            self._tick()
        return on_message

    def _due_count(self, entry):
        """Return how many messages of a sync topic are due by the current time."""
        now = self.start_ns + self.n * self.step_ns
        return 0 if now < entry['first_ns'] else (now - entry['first_ns']) // self.ts_ns + 1

    def _due(self):
        """Return the sync entries still missing a message due by the current time."""
        return [e for e in self.syncs if e['count'] < self._due_count(e)]

    def _publish(self, n):
        ns = int(round(self.values['start'] * 1e9)) + n * self.step_ns
        sec, nsec = divmod(ns, 10**9)
        msg = Clock()
        msg.clock.sec, msg.clock.nanosec = sec, nsec
        self.pub.publish(msg)
        return ns / 1e9

    def _tick(self):
        if not self._running:
            return
        now = time.monotonic()
        if now < self._next_wall:
            return
        late = self._due()
        if late:
            if self._waiting_since is None:
                self._waiting_since = self._resent_at = now
            # The first message of a topic proves that its node is up and hears the clock;
            # until then, starting up under load, it gets the start-up timeout.
            started = all(e['count'] > 0 for e in late)
            timeout = self.values['sync_timeout' if started else 'wait_timeout']
            if now - self._waiting_since < timeout:
                if now - self._resent_at >= RESEND:
                    # Time sources subscribe best-effort: a node that lost this tick
                    # would never act on it.  The same time again changes nothing else.
                    self._resent_at = now
                    self._publish(self.n)
                return
            self.stalls += 1
            self.get_logger().warning(
                f'moved on without {[e["topic"] for e in late]} after '
                f'{timeout} s ({self.stalls} stalls so far)', throttle_duration_sec=5.0)
            # Counted as lost: a node that skipped a sample never sends that message,
            # and a count kept one short would stall every later tick for sync_timeout.
            for e in late:
                e['count'] = self._due_count(e)
        self._waiting_since = None
        if self._last_tick:
            self._finish(now)
            return
        if now - self._last_arrival < self.values['sync_margin']:
            self._next_wall = self._last_arrival + self.values['sync_margin']
            return
        self._next_wall = max(self._next_wall + self._period, now)
        self.n += 1
        t = self._publish(self.n)
        stop = self.values['stop_at']
        # Finished once the messages due at this last tick have come, as at any tick:
        # stopping at once left a node that was slow to hear it one sample short.
        self._last_tick = stop > 0 and t >= stop - 1e-9

    def _finish(self, now):
        t = (self.start_ns + self.n * self.step_ns) / 1e9
        wall = now - self._start_wall
        self.get_logger().info(
            f'reached {t:g} s of sim time in {wall:.1f} s: rtf {t / max(wall, 1e-9):.1f}, '
            f'{self.stalls} stalls')
        self._running = False
        self._timer.cancel()
        self.finished.set_result(0)


def main(args=None):
    """Run the clock until ``stop_at``; return 0, or 2 if the loop never came up."""
    return run(SimClockNode, args, 'sim_clock')


if __name__ == '__main__':
    sys.exit(main())
