"""
Base of the loop nodes: one action per sample, at a fixed phase of the sample.

A sampled control system runs its blocks in a fixed order within each scan,
and the offline simulator does the same: read PV, compute OP, move the valve,
hold MV while the plant advances.  Separate processes woken by the same
clock tick would run in a random order, adding 0-2 samples of delay that
change the limit cycle (2 samples lengthen the overshoot case's period by
6 %).  So each node acts at its ``phase`` of the sample: after the sample
instant ``k Ts`` the plant publishes PV at 1/4, the controller OP at 1/2 and
the valve MV at 3/4 of the sample, and every message has a quarter sample
to arrive.  All values of sample ``k`` are published within
``[k Ts, (k+1) Ts)``, so ``floor(t / Ts)`` of any recorded time stamp is
its sample number.

With ``use_sim_time`` a timer runs at a quarter of ``sample_time`` and the
node acts in the first quarter-tick of each sample that is at or past its
phase, so a node started late, or a clock that skips ticks, still acts once
per sample; the clock source must step in quarter samples (the loop launcher
sets this).  At its action instant the node waits, up to ``input_wait`` wall
seconds, for each input's first message since it last acted: a message that
reached the lockstep clock may not have reached this node yet, and a busy
machine must slow the run down, not change it.

On wall time the timer ticks once per sample, just after the node's phase
instant on the system clock, so that all processes share the same grid with
a quarter of the wake-ups (82.6 % -> 97-98 % of cycles within 1 ms at 100 Hz,
measured); a tick that comes so late that its sample is over
acts for the next one, and that sample has no message.  ``realtime_priority``
runs the process under SCHED_FIFO.

Degraded inputs: a sample at which the node acts without a value of an
input sent in that sample (the message was lost, late, or its producer is
down) acts on the held value; the node says so on ``/diagnostics`` and
publishes ``held_inputs`` (``diagnostic_msgs/KeyValue``: the input topic,
then the sample number and the value acted on, ``nan`` if none had come
yet), which the recorder records and the analyzer uses to put the valve's
real input in place, or leave the sample out.  With ``state_file`` the node
saves its state after every sample and resumes from it when restarted.
"""

from collections import deque
import math
import os
from pathlib import Path
import sys
import time

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
import numpy as np
from rcl_interfaces.msg import SetParametersResult
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from std_msgs.msg import Float64
from stiction_ros.errors import StartupError
from stiction_ros.nodes import state_file
from stiction_ros.nodes.input_guard import InputGuard
from stiction_ros.nodes.params import check_choices, check_fixed, coerce, declare
from stiction_ros.nodes.params import fixed_reason, plain
from stiction_ros.nodes.realtime import align_timer, CpuWatch, set_fifo
from stiction_ros.nodes.sampled_params import common_params

SLOTS = 4
# Reliable with room for a few seconds of backlog: a slow subscriber (the
# recorder) must not lose samples, yet the newest value is what a loop uses.
DATA_QOS = QoSProfile(depth=100, history=HistoryPolicy.KEEP_LAST,
                      reliability=ReliabilityPolicy.RELIABLE)


class SampledNode(Node):
    """A node that calls :meth:`on_sample` once per sample at its phase."""

    KIND = 'node'
    PHASE = 0.5

    @staticmethod
    def own_params() -> list:
        """Return the :class:`Param` specs of this kind of node beside the common ones."""
        return []

    @classmethod
    def declared_params(cls) -> list:
        """Return every parameter the node declares, known before it starts (``--help``)."""
        return common_params(cls.PHASE) + cls.own_params()

    def __init__(self, name, phase, params):
        super().__init__(name)
        self.param_specs = common_params(phase) + list(params)
        self.values = declare(self, self.param_specs)
        self.sample_time = self.values['sample_time']
        self._sim = bool(self.get_parameter('use_sim_time').value)
        # On wall time k counts samples since 1970, and a profile's step 'at 10 s' would
        # be decades past: profiles count from start_time, or this node's first sample.
        start = self.values['start_time']
        first = math.floor(start / self.sample_time + 1e-9) if start > 0 else None
        self._k0 = 0 if self._sim else first
        self._slot = int(round(self.values['phase'] * SLOTS))
        self._ts_ns = int(round(self.sample_time * 1e9))
        self.last_k = None
        self.samples = 0
        self.skipped = 0
        self.early = 0
        # The last 100 000 samples' lateness, for the shutdown summary (bounded memory).
        self._late = deque(maxlen=100_000)
        self.rejected = 0
        self.input_guards = {}
        self._lags = {}
        self._store = None
        self._inject_rng = np.random.default_rng(self.values['inject_seed'])
        self._in_flight = deque()       # (due ns, topic, value, sample), due times in order
        self._arrived = {}              # topic: messages since the node last acted (any)
        self._owed = set()              # inputs missing or held at the last action
        self._needed = []               # the inputs a sample waits for (watched ones)
        self._pending = None            # on sim time: the sample waiting for an input
        self.waited = {'samples': 0, 'gave_up': 0}
        self.injected = {'lost': 0, 'delayed': 0}
        self.unheard = {}               # samples acted on before an input's first value
        # Relative: /diagnostics without a namespace, the loop's own in one.
        self._diag = self.create_publisher(DiagnosticArray, 'diagnostics', 10)
        self._held_pub = self.create_publisher(KeyValue, 'held_inputs', DATA_QOS)
        self.create_timer(1.0, self._publish_diagnostics,
                          clock=Clock(clock_type=ClockType.STEADY_TIME))

    def start(self):
        """Resume from the state file, register the parameter callbacks, start the timer."""
        self._resume()
        self.add_pre_set_parameters_callback(lambda ps: self.expand(coerce(self.param_specs, ps)))
        # rclpy calls on-set callbacks newest first, up to a refusal: this one refuses a
        # use_sim_time change before the time source's (from Node()) switches the clock.
        self.add_on_set_parameters_callback(self._on_set)
        self.add_post_set_parameters_callback(self._post_set)
        if self._sim:
            self._timer = self.create_timer(self.sample_time / SLOTS, self._tick)
            self._wait_timer = self.create_timer(max(self.values['input_wait'], 1e-3),
                                                 self._give_up,
                                                 clock=Clock(clock_type=ClockType.STEADY_TIME))
            self._wait_timer.cancel()
        else:
            self._realtime(self.values['realtime_priority'])
            # On wall time one tick per sample, at this node's phase: a quarter of
            # the wake-ups, so the nodes contend less for the cores.
            self._timer = self.create_timer(self.sample_time, self._tick)
            align_timer(self._timer, self._ts_ns, self._slot * (self._ts_ns // SLOTS))

    def _realtime(self, priority):
        # A busy machine delays a woken process by up to a scheduler slice (ms);
        # a real-time class runs it as soon as its timer is due.
        if priority <= 0:
            return
        try:
            set_fifo(priority)
        except (AttributeError, OSError) as err:
            self.get_logger().warning(f'cannot run under SCHED_FIFO {priority} ({err}); '
                                      'keeping the normal scheduler')
            return
        self._cpu_watch = CpuWatch()
        self._cpu_timer = self.create_timer(1.0, self._watch_cpu,
                                            clock=Clock(clock_type=ClockType.STEADY_TIME))

    def _watch_cpu(self):
        if not self._cpu_watch.update(time.monotonic(), time.process_time()):
            return
        self._cpu_timer.cancel()
        set_fifo(0)
        self.get_logger().warning(
            f'under SCHED_FIFO this process used {100 * self._cpu_watch.share:.0f} % of a core '
            f'for {self._cpu_watch.windows} s: it cannot keep {1 / self.sample_time:g} Hz on this '
            'machine and would starve every other process; back on the normal scheduler')

    def _tick(self):
        now = self.get_clock().now().nanoseconds
        n = math.floor(now * SLOTS / self._ts_ns + 1e-6)
        k, slot = divmod(n, SLOTS)
        if self.last_k is not None and k < self.last_k:
            self.get_logger().warning(
                f'clock went back from sample {self.last_k} to {k}; following it')
            self.last_k = k - 1
        if slot < self._slot and not self._sim and k != self.last_k:
            # On wall time there is one tick per sample: one that fires a little before
            # the phase instant (timer jitter) waits for it rather than lose the sample.
            early = k * self._ts_ns + self._slot * (self._ts_ns // SLOTS) - now
            if early < self._ts_ns // SLOTS:
                time.sleep(early / 1e9)
                self.early += 1
                slot = self._slot
        if self._pending is not None:
            if n <= self._pending * SLOTS + self._slot:
                return                  # the same instant again: still waiting
            self._give_up()             # the clock moved on: it does not wait for this node
        if slot < self._slot or k == self.last_k:
            return
        if self._sim and self.values['input_wait'] > 0.0 and self._missing():
            self._pending = k
            self.waited['samples'] += 1
            self._wait_timer.reset()
            return
        self._act(k)

    def _missing(self):
        """
        Return the inputs with no message since the node last acted.

        The lockstep clock moves on once a message reached it, which is no proof
        that it reached this node too; waiting for it here makes the result of a
        sim-time run independent of how busy the machine is.  Each producer
        publishes once per sample, after this node's previous action, so the
        message due is the first one since then: counted, not dated, because
        the clock this node reads when a message comes may be a tick behind or
        ahead of the producer's.  An input with ``lag`` 1 that has never sent
        anything is not waited for: at the first sample there is nothing yet.
        """
        return [topic for topic in self._needed
                if not self._arrived.get(topic) and (self._lags[topic] == 0
                                                     or topic in self._arrived)]

    def _give_up(self):
        k, self._pending = self._pending, None
        self._wait_timer.cancel()
        if k is None or k == self.last_k:
            return
        self.waited['gave_up'] += 1
        self.get_logger().warning(
            f'sample {k}: no {self._missing()} after waiting; acting on the held value',
            throttle_duration_sec=5.0)
        self._act(k)

    def _act(self, k):
        if self._sim:
            self._arrived = dict.fromkeys(self._arrived, 0)
        if self._in_flight:
            self._arrive(self.get_clock().now().nanoseconds)
        if self.last_k is not None and k > self.last_k + 1:
            self.skipped += k - self.last_k - 1
        self.last_k = k
        self.samples += 1
        if self._k0 is None:
            self._k0 = k
        self.on_sample(k, (k - self._k0) * self.sample_time)
        # How late this sample's action finished, for the summary at shutdown.
        due = k * self._ts_ns + self._slot * self._ts_ns // SLOTS
        self._late.append(self.get_clock().now().nanoseconds - due)
        self._owed = {topic for topic, guard in self.input_guards.items() if not guard.fresh}
        for topic, guard in self.input_guards.items():
            # The sample and the value acted on: an analyzer can put it in place of the
            # recorded one, at the right sample however late this message is.  'nan': no
            # value had come yet (the first ones lost), so none can be put in place.
            if guard.acted(k):
                self._owed.add(topic)
                value = repr(guard.last_good[1])
                self.get_logger().warning(
                    f'acted on a held {topic} ({guard.held} samples so far): a message was '
                    'lost or late', throttle_duration_sec=5.0)
            elif guard.last_good is None and guard.lag == 0:
                value = 'nan'
                self.unheard[topic] = self.unheard.get(topic, 0) + 1
            else:
                continue
            self._held_pub.publish(KeyValue(key=self.resolve_topic_name(topic),
                                            value=f'{k} {value}'))
        if self._store is not None:
            self._save(k)

    # -- state on disk: resume where a killed node stopped ---------------------------
    def snapshot_state(self):
        """Return what the node must remember across a restart (JSON-able), or None."""
        return None

    def restore_state(self, state):
        """Continue from ``snapshot_state()`` output; raise ValueError if it does not fit."""

    def _save(self, k):
        try:
            self._store.save({'node': self.KIND, 'sample_time': self.sample_time, 'k': k,
                              'k0': self._k0, 'state': self.snapshot_state()})
        except (OSError, ValueError) as err:
            self.get_logger().error(f'cannot save the state to {self.values["state_file"]}: '
                                    f'{err}', throttle_duration_sec=10.0)

    def _resume(self):
        path = self.values['state_file']
        if not path:
            return
        try:
            Path(path).parent.mkdir(parents=True, exist_ok=True)
        except OSError as err:
            raise StartupError(f'state_file {path}: cannot create its directory: {err}') from None
        doc = None
        try:
            doc = state_file.load(path, self.KIND, self.sample_time)
            if doc is not None:
                self.restore_state(doc['state'])
        except (ValueError, KeyError, TypeError) as err:
            # Kept for a post-mortem, and out of the way of the new state.
            os.replace(path, path + '.unusable')
            self.get_logger().warning(f'cannot resume ({err}); starting afresh, the old file '
                                      f'is {path}.unusable')
            doc = None
        try:
            self._store = state_file.StateStore(path)
        except OSError as err:
            raise StartupError(f'state_file {path}: cannot write it: {err}') from None
        if doc is None:
            return
        self.last_k = doc['k']
        if self._k0 is None and isinstance(doc.get('k0'), int):
            self._k0 = doc['k0']        # the profiles go on, not start again
        self.get_logger().info(f'resumed from {path}, saved at sample {doc["k"]}')

    def close(self):
        """Say how many samples the node acted on, and how late (run.py calls this at shutdown)."""
        if self._store is not None:
            self._store.close()         # the file stays, for a restart
            self._store = None
        late = sorted(self._late)
        stats = ''
        if late:
            pick = [late[min(len(late) - 1, int(q * len(late)))] / 1e6 for q in (0.5, 0.99)]
            stats = (f'; done {pick[0]:.2f} ms after its phase instant (p50), {pick[1]:.2f} ms'
                     f' (p99), {late[-1] / 1e6:.2f} ms (max)')
        held = ', '.join([f'{g.held} on a held {t}' for t, g in self.input_guards.items()
                          if g.held] + [f'{n} before any {t} came'
                                        for t, n in self.unheard.items()])
        held = held or 'none on a held input'
        faults = ''
        if any(self.injected.values()):
            faults = (f'; injected: {self.injected["lost"]} inputs lost, '
                      f'{self.injected["delayed"]} delayed')
        if self.waited['samples']:
            faults += (f'; waited for an input at {self.waited["samples"]} samples, gave up at '
                       f'{self.waited["gave_up"]}')
        print(f'{self.get_name()}: acted on {self.samples} samples ({held}; {self.early} ticks '
              f'early), skipped {self.skipped}{stats}; {self.rejected} inputs rejected{faults}',
              file=sys.stderr)

    def receive(self, topic, value, info):
        """
        Take an input message: lose or delay it if faults are injected, else use it.

        The sample it was sent in is noted, so that a value used a sample late is
        found: on wall time from its send stamp (``info``), on sim time from the
        clock when it came, or as the sample waited for if the node is waiting.
        """
        now = self.get_clock().now().nanoseconds
        if not self._sim:
            self._receive(topic, value, now, info['source_timestamp'] // self._ts_ns)
            return
        sample = now // self._ts_ns
        self._arrived[topic] = self._arrived.get(topic, 0) + 1
        k = self._pending
        lag = self._lags.get(topic, 0)
        if k is not None:
            # The message this node waits for, whatever its clock read when it came.
            sample = max(sample, k - lag)
        elif self.last_k is None:
            sample = None               # before the first action nothing can be late
        else:
            # Sent after this node's last action (each producer publishes once per
            # sample, after it), though this node's clock may not show that yet: the
            # newer /clock can be queued behind the message (seen as a false "held").
            # The first message of an input missing or held at that action may be
            # the one that was due then, late.
            owed = topic in self._owed
            sample = max(sample, self.last_k + (0 if owed else 1) - lag)
        self._owed.discard(topic)
        self._receive(topic, value, now, sample)
        if k is not None and not self._missing():
            self._pending = None
            self._wait_timer.cancel()
            self._act(k)

    def _receive(self, topic, value, now, sample):
        v = self.values
        if v['inject_drop'] > 0.0 and self._inject_rng.random() < v['inject_drop']:
            self.injected['lost'] += 1
            return
        wait = v['inject_delay']
        if v['inject_jitter'] > 0.0:
            wait += self._inject_rng.uniform(0.0, v['inject_jitter'])
        if wait > 0.0 or self._in_flight:
            due = now + int(wait * 1e9)
            if self._in_flight:
                due = max(due, self._in_flight[-1][0])   # a reliable link keeps the order
            self._in_flight.append((due, topic, value, sample))
            self.injected['delayed'] += wait > 0.0
            return
        if self.accept(topic, value, sample):
            self.on_input(topic, value)

    def _arrive(self, now):
        # Delayed inputs whose time has come arrive just before the node acts.
        while self._in_flight and self._in_flight[0][0] <= now:
            _, topic, value, sample = self._in_flight.popleft()
            if self.accept(topic, value, sample):
                self.on_input(topic, value)

    def on_input(self, topic, value):
        """Take a valid value of input ``topic``."""

    def accept(self, topic, value, sample=None):
        """Return True for a usable input (sent in ``sample``); count, warn and report others."""
        guard = self._guard(topic)
        if guard.check(value, time.monotonic(), sample):
            return True
        self.rejected += 1
        self.get_logger().warning(
            f'ignored {topic} = {value} (not finite or beyond +-{guard.limit:g}); holding '
            f'the last good value ({self.rejected} rejected so far)', throttle_duration_sec=5.0)
        return False

    def add_input(self, topic, lag=0, watch=True):
        """
        Subscribe to the Float64 input ``topic``; its valid values go to :meth:`on_input`.

        Every message passes :meth:`receive` (injected faults, dating) and
        :meth:`accept` (rejection).  ``lag`` is 1 for an input published later in
        the sample than this node acts (the plant's MV): its newest value is then
        the previous sample's.  ``watch`` reports it on /diagnostics from now on
        (stale until its first valid value); else from its first message.
        """
        self.create_subscription(Float64, topic,
                                 lambda msg, info: self.receive(topic, msg.data, info),
                                 DATA_QOS)
        self._lags[topic] = lag
        if watch:
            self._guard(topic)
            self._needed.append(topic)

    def _guard(self, topic):
        # Created when the input is watched or first used; from then on it is reported.
        if topic not in self.input_guards:
            self.input_guards[topic] = InputGuard(topic, self.values['input_limit'],
                                                  self.values['stale_after'],
                                                  self._lags.get(topic, 0))
        return self.input_guards[topic]

    def _publish_diagnostics(self):
        now = time.monotonic()
        statuses = []
        for topic, guard in self.input_guards.items():
            level, message, values = guard.status(now)
            statuses.append(DiagnosticStatus(
                level=bytes([level]), name=f'{self.get_fully_qualified_name()}: {topic}',
                message=message, hardware_id='stiction_ros',
                values=[KeyValue(key=k, value=v) for k, v in values.items()]))
        if statuses:
            msg = DiagnosticArray(status=statuses)
            msg.header.stamp = self.get_clock().now().to_msg()
            self._diag.publish(msg)

    def on_sample(self, k, t):
        """Act for sample ``k`` taken at time ``t`` (s)."""
        raise NotImplementedError

    # -- parameters: validate everything first, then apply ----------------------
    def _on_set(self, params):
        changes = {p.name: plain(p.value) for p in params if p.name in self.values}
        sim = [p.value for p in params if p.name == 'use_sim_time' and p.value != self._sim]
        reason = (fixed_reason('use_sim_time', sim[0]) if sim else check_fixed(
            self.param_specs, self.values, changes) or check_choices(self.param_specs, changes))
        if reason is None:
            merged = dict(self.values)
            merged.update(changes)
            reason = self.check(merged, changes)
        if reason is not None:
            names = sorted(changes) or sorted(p.name for p in params)
            self.get_logger().warning(f'rejected {names}: {reason}')
            return SetParametersResult(successful=False, reason=reason)
        return SetParametersResult(successful=True)

    def _post_set(self, params):
        changes = {p.name: plain(p.value) for p in params if p.name in self.values}
        if changes:
            self.values.update(changes)
            for guard in self.input_guards.values():
                guard.limit = self.values['input_limit']
                guard.stale_after = self.values['stale_after']
            self.apply(changes)
            self.get_logger().info(
                'set ' + ', '.join(f'{k}={v!r}' for k, v in sorted(changes.items())))

    def check_startup(self):
        """Raise StartupError if the values the node was started with are invalid."""
        reason = check_choices(self.param_specs, self.values) or self.check(self.values,
                                                                            self.values)
        if reason is not None:
            raise StartupError(reason)

    def expand(self, params):
        """Return the parameters to set when ``params`` are set (a pre-set callback)."""
        return params

    def check(self, values, changes):
        """Return why ``values`` (with ``changes`` applied) are invalid, or None."""
        return None

    def apply(self, changes):
        """Apply validated ``changes``; they take effect at the next sample."""
