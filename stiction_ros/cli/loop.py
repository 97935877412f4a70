"""
``loop``: bring up a whole loop from one YAML file as separate node processes.

For machines without ``ros2 launch`` (``launch/loop.launch.py`` does the same
on a ROS install).  Starts ``plant``, ``controller`` and ``valve`` (and the
``recorder`` with ``--record``, and a ``sim_clock`` with ``--rtf``), waits
for the run to end, stops every node with SIGINT so the bag is finalised,
and prints a summary: messages recorded, limit cycle live vs offline.

Examples::

    loop config/concentration_loop.yaml --case undershoot --rtf 100 --record out/bag
    loop config/concentration_loop.yaml --namespace /loop2 --duration 600   # real time
    loop config/concentration_loop.yaml --case overshoot --write-params overshoot.params.yaml
    loop config/concentration_loop.yaml --inject op:drop=0.1,jitter=0.3 --respawn --record b

Node logs go to ``--logs`` (default: next to the bag, or a temporary directory).
Exit status: 0 the loop ran; 1 it could not run (a node failed, a bag in the
way); 2 bad input or option, before anything started; 128 + the signal when
interrupted.
"""

import argparse
import json
import math
import os
from pathlib import Path
import signal
import subprocess
import sys
import tempfile
import time

from stiction_ros.app.live_summary import format_summary, summarise
from stiction_ros.bag.reader import read_bag
from stiction_ros.cli.text import description, pipe_safe
from stiction_ros.errors import LoopError, StictionError
from stiction_ros.nodes.realtime import set_fifo
from stiction_ros.sim.launch_plan import resolve_config
from stiction_ros.sim.loop_config import ConfigError, load_loop, parse_overrides
from stiction_ros.sim.ros_params import loop_extras, LOOP_NODES, params_file, write_node_params

MODULES = {'plant': 'plant_node', 'controller': 'controller_node', 'valve': 'valve_node',
           'recorder': 'recorder_node', 'sim_clock': 'sim_clock_node',
           'loop_nodes': 'composed'}
# The node that consumes each loop topic: where its injected faults happen.
CONSUMER = {'op': 'valve', 'mv': 'plant', 'pv': 'controller'}
INJECT_KEYS = ('drop', 'delay', 'jitter', 'seed')
# Seconds a node that will not stop gets to print its stacks (SIGUSR1) before SIGKILL.
STACKS_S = 1.0
# Fast DDS's shared-memory transport hung loop nodes now and then (about one run in
# 25 of three loops at rtf 50 beside a busy process: a node stopped hearing its clock
# and inputs, and its publisher's teardown then blocked); over UDP on the loopback
# no hang was seen in 20 runs.  A user's own choice of transports is kept.
TRANSPORT_VAR = 'FASTDDS_BUILTIN_TRANSPORTS'
TRANSPORT = 'UDPv4'


# A loop node is restarted only after it ran this long (s).
RESPAWN_AFTER = 3.0


def parse_inject(items):
    """Return ``{topic: {key: value}}`` from ``TOPIC:key=value,...`` strings."""
    out = {}
    for item in items or ():
        topic, _, spec = item.partition(':')
        if topic not in CONSUMER:
            raise ConfigError(f'--inject {item!r}: the topic must be one of {sorted(CONSUMER)}')
        faults = {}
        for part in filter(None, spec.split(',')):
            key, sep, value = part.partition('=')
            try:
                if not sep or key not in INJECT_KEYS:
                    raise ValueError
                faults[key] = int(value) if key == 'seed' else float(value)
            except ValueError:
                raise ConfigError(f'--inject {item!r}: {part!r} is not one of '
                                  + ', '.join(f'{k}=NUMBER' for k in INJECT_KEYS)) from None
        out[topic] = faults
    return out


def node_command(name, namespace, params_path, extra=()):
    """
    Return the argv that starts node ``name`` with the given parameter file.

    In a namespace every node (its time source, and the sim clock's publisher)
    uses the loop's own clock topic ``<namespace>/clock``: two sped-up loops on
    one ``/clock`` would each drive the other's nodes back and forth in time.
    """
    cmd = [sys.executable, '-m', f'stiction_ros.nodes.{MODULES[name]}', '--ros-args',
           '--params-file', str(params_path)]
    if namespace:
        cmd += ['-r', f'__ns:={namespace}']
    ns = namespace.strip('/')
    if ns:
        cmd += ['-r', f'/clock:=/{ns}/clock']
    return cmd + list(extra)


class Processes:
    """The node processes of one loop, with their logs."""

    def __init__(self, log_dir):
        self.log_dir = Path(log_dir)
        self.log_dir.mkdir(parents=True, exist_ok=True)
        self.procs = {}
        self.started, self.commands = {}, {}
        # Held by run_loop from the first node started, and by stop() from the first
        # stop to the last: between two calls (loop nodes, then the recorder) a
        # KeyboardInterrupt would skip the recorder's stop.
        self.held = HeldSignals()

    def start(self, name, cmd, env):
        log = open(self.log_dir / f'{name}.log', 'ab')
        self.procs[name] = (subprocess.Popen(cmd, stdout=log, stderr=subprocess.STDOUT, env=env,
                                             start_new_session=True), log)
        self.started[name] = time.monotonic()
        self.commands[name] = (cmd, env)

    def restart(self, name):
        """Start a node that stopped again, with the same command (its log goes on)."""
        self.procs[name][1].close()
        self.start(name, *self.commands[name])

    def uptime(self, name):
        """Return how long ago the node was (last) started, s."""
        return time.monotonic() - self.started[name]

    def failed(self):
        """
        Return the name of a node that has stopped, or None.

        Only the sim clock ends by itself (at the run's last sample); any other
        node that exits before the run ends has stopped, whatever its code: a
        node asked to stop by SIGTERM exits 0, and a recorder gone quiet so
        would leave the run going on with nothing recorded.
        """
        for name, (p, _) in self.procs.items():
            if p.poll() is not None and (p.returncode != 0 or name != 'sim_clock'):
                return name
        return None

    def tail(self, name, lines=8):
        """Return the last lines of a node's log."""
        text = (self.log_dir / f'{name}.log').read_text(errors='replace').splitlines()
        return '\n'.join('    ' + x for x in text[-lines:])

    def stop(self, names, timeout=10.0):
        """
        SIGINT the named nodes and wait; SIGKILL what does not exit in time.

        A node that does not exit is first asked for its stacks (SIGUSR1: every
        thread's, into its log) and given a second to write them: where it hung
        is the one clue a SIGKILL alone would lose.  One line on stderr says so.

        A SIGINT or SIGTERM that comes meanwhile (Ctrl-C pressed again) is held
        back until every node of the loop has exited, then delivered: it cannot
        leave a node running or a bag unfinished.
        """
        held = self.held
        held.hold()
        try:
            for name in names:
                if name in self.procs and self.procs[name][0].poll() is None:
                    self.procs[name][0].send_signal(signal.SIGINT)
            deadline = time.monotonic() + timeout
            for name in names:
                if name not in self.procs:
                    continue
                p, log = self.procs[name]
                try:
                    p.wait(max(deadline - time.monotonic(), 0.1))
                except subprocess.TimeoutExpired:
                    self._kill_with_stacks(name, p, timeout)
                log.close()
        finally:
            if all(p.poll() is not None for p, _ in self.procs.values()):
                # An exception on its way (the first Ctrl-C, a node that failed) ends the
                # run already: what was held during its stop is not delivered on top.
                held.release(deliver=sys.exc_info()[1] is None)

    def _kill_with_stacks(self, name, p, timeout):
        p.send_signal(signal.SIGUSR1)
        try:
            p.wait(STACKS_S)
        except subprocess.TimeoutExpired:
            pass
        if p.poll() is None:
            p.kill()
            p.wait()
        print(f'loop: node {name} did not stop within {timeout:g} s of SIGINT and was killed; '
              f'its stacks are at the end of {self.log_dir / f"{name}.log"}', file=sys.stderr)


class HeldSignals:
    """SIGINT and SIGTERM noted instead of acted on, until :meth:`release` delivers them."""

    SIGNALS = (signal.SIGINT, signal.SIGTERM)

    def __init__(self):
        self.previous = {}
        self.got = []

    def hold(self):
        """Note SIGINT and SIGTERM from now on (in the main thread; elsewhere they cannot be)."""
        if self.previous:
            return
        try:
            for signum in self.SIGNALS:
                if signal.getsignal(signum) is not None:    # None: set outside Python, kept
                    self.previous[signum] = signal.signal(signum, self._note)
        except ValueError:                                  # not the main thread
            pass

    def _note(self, signum, frame):
        self.got.append(signum)

    def release(self, deliver=True):
        """Put the previous handlers back, then deliver each held signal once, in order."""
        previous, self.previous = self.previous, {}
        for signum, handler in previous.items():
            signal.signal(signum, handler)
        got, self.got = self.got, []
        for signum in dict.fromkeys(got) if deliver else ():
            signal.raise_signal(signum)


def run_loop(cfg, namespace='', rtf=None, duration=None, record=None, log_dir=None,
             progress=None, realtime_priority=0, respawn=False, respawned=None, inject=None,
             composed=False):
    """
    Run the loop; return the bag path (or None) after every node has stopped.

    ``rtf`` > 0 runs on a sim clock at that real-time factor, on ``/clock``
    or, in a namespace, on the loop's own ``<namespace>/clock`` (else wall
    time, where ``realtime_priority`` > 0 runs the loop nodes under
    SCHED_FIFO).  With ``respawn`` each loop node keeps its state in the log
    directory (a file written after every sample, which costs time at high
    rates, so only then), and one that dies after its first seconds is
    started again and resumes where it was (counted in the ``respawned``
    dict).  ``inject`` (from :func:`parse_inject`) makes the node that uses a
    topic lose and delay its messages (``inject_*`` parameters); the recorder
    still records the topic as sent.  ``composed`` runs plant, controller and
    valve in one process on one executor (``loop_nodes``); it takes neither
    ``respawn`` nor ``inject``, which are set per node process.  Raises
    :class:`LoopError` when a node fails otherwise.
    """
    if composed and (respawn or inject):
        raise ConfigError('--composed runs the loop nodes in one process: it cannot respawn '
                          'one of them or inject faults into one; drop --respawn/--inject')
    ts = float(cfg['sample_time'])
    duration = float(duration if duration is not None else cfg['duration'])
    work = Path(log_dir or tempfile.mkdtemp(prefix='stiction_loop_'))
    work.mkdir(parents=True, exist_ok=True)
    sim = bool(rtf)
    if record:
        record = Path(record).resolve()
        if record.exists() and any(record.iterdir()):
            raise LoopError(f'{record}: already exists and is not empty; choose a new bag '
                            'directory (nothing is overwritten)')
    extra = loop_extras(cfg, rtf=rtf, record=record, duration=duration)
    params = work / 'loop.params.yaml'
    params.write_text(params_file(cfg, namespace, extra), encoding='utf-8')
    env = dict(os.environ)
    env.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    env.setdefault(TRANSPORT_VAR, TRANSPORT)
    procs = Processes(work)
    sim_arg = ['-p', f'use_sim_time:={"true" if sim else "false"}']
    supervising = not sim and realtime_priority > 0 and _supervise(realtime_priority + 1)
    # Ctrl-C and SIGTERM are noted and acted on between two polls, never inside
    # one: a KeyboardInterrupt raised in Popen.poll between taking its waitpid
    # lock and the try that frees it leaves the lock taken, and the stop's
    # wait() then blocks on it for good (a CI run hung that way, no node stopped).
    held = procs.held
    held.hold()
    try:
        if record:
            procs.start('recorder', node_command('recorder', namespace, params, sim_arg), env)
        # On wall time the profiles count from the launch, alike in every node (a
        # respawned one too).
        rt_arg = ['-p', f'realtime_priority:={int(realtime_priority)}',
                  '-p', f'start_time:={time.time():.3f}'] if not sim else []
        faults = {}
        for topic, spec in (inject or {}).items():
            faults.setdefault(CONSUMER[topic], []).extend(
                a for k, v in spec.items() for a in ('-p', f'inject_{k}:={v}'))
        loop_nodes = ('loop_nodes',) if composed else LOOP_NODES
        for name in loop_nodes:
            keep = []
            if respawn:
                state = work / f'{name}.state'
                state.unlink(missing_ok=True)   # a state of an earlier run is not this run's
                keep = ['-p', f'state_file:={state}']
            procs.start(name, node_command(name, namespace, params, sim_arg + rt_arg + keep
                                           + faults.get(name, [])), env)
        end = None if sim else time.monotonic() + duration + 0.75 * ts
        if sim:
            procs.start('sim_clock', node_command('sim_clock', namespace, params), env)
        while True:
            time.sleep(0.1)
            if held.got:
                raise Terminated if held.got.pop(0) == signal.SIGTERM else KeyboardInterrupt
            bad = procs.failed()
            # A node that started, ran and died (killed, crashed) is restarted; one that
            # fails at once (bad parameters) would only fail again.
            if bad in LOOP_NODES and respawn and procs.uptime(bad) > RESPAWN_AFTER:
                code = procs.procs[bad][0].returncode
                print(f'loop: node {bad} stopped (exit {code}); restarting it from its state',
                      file=sys.stderr)
                procs.restart(bad)
                if respawned is not None:
                    respawned[bad] = respawned.get(bad, 0) + 1
                continue
            if bad is not None:
                raise LoopError(f'node {bad} stopped (exit {procs.procs[bad][0].returncode}); '
                                f'its log {work / (bad + ".log")} ends:\n{procs.tail(bad)}')
            if sim and procs.procs['sim_clock'][0].poll() == 0:
                break
            if end is not None and time.monotonic() >= end:
                break
            if progress is not None:
                progress()
        time.sleep(0.5)
    finally:
        procs.stop(['sim_clock', 'controller', 'valve', 'plant', 'loop_nodes'])
        if supervising:
            set_fifo(0)
        procs.stop(['recorder'], timeout=30.0)
    return record


def _supervise(priority):
    """
    Run this launcher above the real-time loop nodes; return True if it could.

    It sleeps but for a poll every 0.1 s, and must always get the core to stop
    the run at its end, however busy the nodes are; its child processes start
    on the normal scheduler (SCHED_RESET_ON_FORK) and raise themselves.
    """
    try:
        set_fifo(min(priority, 99))
    except (AttributeError, OSError):
        return False                    # the nodes will say that they cannot either
    return True


class Terminated(KeyboardInterrupt):
    """SIGTERM, raised where Ctrl-C raises KeyboardInterrupt, and handled the same way."""


def _terminate(signum, frame):
    raise Terminated


@pipe_safe
def main(argv=None):
    """Run the command; return the process exit code."""
    ap = argparse.ArgumentParser(prog='loop', description=description(__doc__))
    ap.add_argument('config', help='loop description (YAML): a path, or the name of a '
                    'shipped file, e.g. concentration_loop.yaml')
    ap.add_argument('--case', help='a case from the "cases" section of the file')
    ap.add_argument('--set', action='append', metavar='KEY=VALUE',
                    help='override a setting, e.g. valve.S=7 (repeatable)')
    ap.add_argument('--namespace', default='',
                    help='namespace of the nodes and topics of the loop')
    ap.add_argument('--duration', type=float, help='seconds of loop time (default: from the file)')
    ap.add_argument('--rtf', type=float, default=0.0,
                    help='run on a /clock at this real-time factor (default: wall time)')
    ap.add_argument('--realtime-priority', type=int, default=0, metavar='P',
                    help='on wall time, run the loop nodes under SCHED_FIFO at priority P '
                    '(1-98; needs CAP_SYS_NICE)')
    ap.add_argument('--record', metavar='DIR', help='record sp, op, mv, pv to this bag directory')
    ap.add_argument('--logs', metavar='DIR', help='directory for the node logs')
    ap.add_argument('--inject', action='append', metavar='TOPIC:FAULTS',
                    help='lose and delay messages of op, mv or pv on their way to the node '
                    'that uses them, e.g. op:drop=0.1,delay=0.2,jitter=0.3 (seconds; repeatable)')
    ap.add_argument('--respawn', action='store_true',
                    help='restart a loop node that dies during the run; it resumes from the '
                    'state it saved after its last sample')
    ap.add_argument('--composed', action='store_true',
                    help='run plant, controller and valve as three nodes in one process on '
                    'one executor (ROS 2 composition) instead of three processes')
    ap.add_argument('--json', metavar='FILE', help='write the summary as JSON')
    ap.add_argument('--write-params', metavar='FILE',
                    help='only write the ROS parameter file of the loop nodes, and exit')
    ap.add_argument('--write-node-params', metavar='DIR',
                    help='only write one parameter file per loop node into DIR '
                    '(DIR/valve.params.yaml: for --params-file, or ros2 param load /valve), '
                    'and exit')
    args = ap.parse_args(argv)
    # SIGTERM (a supervisor, kill) stops the loop as Ctrl-C does.  By default it would end
    # this process at once, and the nodes, each in a session of its own, would run on.
    previous = signal.signal(signal.SIGTERM, _terminate)
    started = False
    try:
        cfg = load_loop(resolve_config(args.config), args.case, parse_overrides(args.set))
        if args.write_params:
            Path(args.write_params).write_text(params_file(cfg, args.namespace), encoding='utf-8')
            print(f'loop: wrote {args.write_params}', file=sys.stderr)
            return 0
        if args.write_node_params:
            for path in write_node_params(cfg, args.write_node_params):
                print(f'loop: wrote {path}', file=sys.stderr)
            return 0
        if not (math.isfinite(args.rtf) and args.rtf >= 0):
            raise ConfigError(f'--rtf must be 0 (wall time) or a positive factor, got '
                              f'{args.rtf:g}')
        if args.duration is not None and not (math.isfinite(args.duration)
                                              and args.duration > 0):
            raise ConfigError(f'--duration must be a positive number of seconds, got '
                              f'{args.duration:g}')
        logs = args.logs or (str(Path(args.record).resolve()) + '.logs' if args.record else None)
        t0 = time.monotonic()
        mode = f'rtf {args.rtf:g}' if args.rtf else 'wall time'
        title = ' '.join(str(x) for x in (cfg.get('name', 'loop'), cfg.get('case')) if x)
        print(f'loop: {title} on {mode}; '
              f'node logs in {logs or "a temporary directory"}', file=sys.stderr)
        if not 0 <= args.realtime_priority <= 98:
            raise ConfigError('--realtime-priority must be 0 (off) to 98')
        respawned = {}
        started = True
        bag = run_loop(cfg, args.namespace, args.rtf, args.duration, args.record, logs,
                       realtime_priority=args.realtime_priority, respawn=args.respawn,
                       respawned=respawned, inject=parse_inject(args.inject),
                       composed=args.composed)
        print(f'loop: ran in {time.monotonic() - t0:.1f} s', file=sys.stderr)
        if bag is not None:
            summary = summarise(read_bag(bag), cfg)
            summary['bag'] = str(bag)
            summary['respawned'] = respawned
            print(format_summary(summary))
            # As the user named it (the JSON summary has the absolute path).
            print(f'bag: {args.record or bag}')
            if args.json:
                Path(args.json).write_text(json.dumps(summary, indent=2), encoding='utf-8')
    except (LoopError, OSError) as err:
        # The loop was set up and could not run (a node that failed, a bag in the way).
        print(f'loop: error: {err}', file=sys.stderr)
        return 1
    except StictionError as err:
        # Bad input (the file, a case, an option) before anything started; after, the
        # run's own output (a bag that cannot be summarised) failed.
        print(f'loop: error: {err}', file=sys.stderr)
        return 1 if started else 2
    except KeyboardInterrupt as err:
        # Processes.stop has stopped every node (a Ctrl-C during the stop waits for it).
        print('loop: interrupted; nodes stopped, bag finalised', file=sys.stderr)
        return 128 + (signal.SIGTERM if isinstance(err, Terminated) else signal.SIGINT)
    finally:
        signal.signal(signal.SIGTERM, previous)
    return 0


if __name__ == '__main__':
    sys.exit(main())
