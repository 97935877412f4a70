"""
Helpers for tests with real nodes: node processes, and an in-test rclpy node.

Node processes inherit the environment set in conftest.py (localhost
discovery, this run's ROS_DOMAIN_ID).  The in-test node spins in a thread,
so the test body can wait on conditions with plain polling.
"""

import os
import signal
import subprocess
import sys
import threading
import time

from diagnostic_msgs.msg import KeyValue
from rcl_interfaces.msg import Parameter as ParamMsg
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.parameter_client import AsyncParameterClient
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rclpy.time import Time
from rosgraph_msgs.msg import Clock
from std_msgs.msg import Float64
from stiction_ros.nodes.sampled import DATA_QOS

MODULES = {'controller': 'controller_node', 'valve': 'valve_node', 'plant': 'plant_node',
           'recorder': 'recorder_node', 'sim_clock': 'sim_clock_node',
           'analyzer': 'analyzer_node'}
# Under pytest-xdist two test files with nodes run at once, and a node can take several
# times longer to start or answer than alone (its parameter services 13 s against 3 s):
# every wait here stretches by this factor.  A wait ends as soon as its condition holds,
# so a passing test takes no longer; only a failure is reported later.  A service call
# is not stretched: its timeout is also when a lost response is sent again.
SLACK = 3.0 if os.environ.get('PYTEST_XDIST_WORKER') else 1.0


def start_node(name, params=None, namespace='', log_dir=None, extra=(), preexec_fn=None):
    """Start a node executable as its own process; return the Popen."""
    cmd = [sys.executable, '-m', f'stiction_ros.nodes.{MODULES[name]}', '--ros-args']
    for key, value in (params or {}).items():
        cmd += ['-p', f'{key}:={_arg(value)}']
    if namespace:
        cmd += ['-r', f'__ns:={namespace}']
    cmd += list(extra)
    out = open(os.path.join(log_dir, f'{name}.log'), 'ab') if log_dir else subprocess.DEVNULL
    return subprocess.Popen(cmd, stdout=out, stderr=subprocess.STDOUT, env=dict(os.environ),
                            preexec_fn=preexec_fn)


def _arg(value):
    if isinstance(value, bool):
        return 'true' if value else 'false'
    if isinstance(value, (list, tuple)):
        return '[' + ','.join(_arg(v) for v in value) + ']'
    if isinstance(value, str):
        return value
    return repr(value)


def stop(proc, sig=signal.SIGINT, timeout=15.0):
    """Signal a node process and wait for it; return its exit code."""
    if proc.poll() is None:
        proc.send_signal(sig)
    try:
        return proc.wait(timeout * SLACK)
    except subprocess.TimeoutExpired:
        proc.kill()
        return proc.wait()


def wait_for(condition, timeout=20.0, what='condition'):
    """Poll ``condition()`` until true; fail the test with ``what`` on timeout."""
    timeout *= SLACK
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if condition():
            return
        time.sleep(0.02)
    raise AssertionError(f'timed out after {timeout} s waiting for {what}')


class Probe:
    """An rclpy node in the test: publish, collect and tune over real DDS."""

    def __init__(self, name='probe'):
        self.node = Node(name)
        self.executor = SingleThreadedExecutor()
        self.executor.add_node(self.node)
        self.received = {}
        self.pubs = {}
        self.renewed = {}
        self._thread = threading.Thread(target=self.executor.spin, daemon=True)
        self._thread.start()

    def listen(self, topic):
        """Collect every Float64 on ``topic`` (with its arrival time) into ``received[topic]``."""
        self.received[topic] = []

        def on_msg(msg):
            self.received[topic].append((time.monotonic(), msg.data))
        self.node.create_subscription(Float64, topic, on_msg, DATA_QOS)

    def values(self, topic):
        """Return the values received on ``topic`` so far."""
        return [v for _, v in list(self.received[topic])]

    def publisher(self, topic):
        """Return (and remember) a Float64 publisher on ``topic``."""
        if topic not in self.pubs:
            self.pubs[topic] = self.node.create_publisher(Float64, topic, DATA_QOS)
        return self.pubs[topic]

    def publish(self, topic, value):
        """Publish one Float64."""
        self.publisher(topic).publish(Float64(data=float(value)))

    def publish_clock(self, t):
        """Publish ``/clock`` at ``t`` seconds, as the sim clock does (reliable)."""
        if '/clock' not in self.pubs:
            self.pubs['/clock'] = self.node.create_publisher(
                Clock, '/clock', QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE))
        self.pubs['/clock'].publish(Clock(clock=Time(nanoseconds=round(t * 1e9)).to_msg()))

    def hear(self, topic, value, namespaces, timeout=20.0):
        """
        Send ``value`` on ``topic`` until the loop node in each of ``namespaces`` has heard it.

        Our publisher can match a new node before the node knows the publisher, and what is
        sent in between is lost to that node alone: a valve started with the test missed
        2.5 s of OP under load, and a restarted one 1 run in 18. ``value`` must be what the
        node acts on already, so that resending it changes nothing. A node has heard one
        once it marks a later sample as acted on a held input (``held_inputs``), with a value:
        before the first one it marks the samples it acted on with ``nan``.
        """
        heard = set()

        def on_mark(msg, ns):
            if msg.value.split()[-1] != 'nan':
                heard.add(ns)
        subs = [self.node.create_subscription(KeyValue, f'{ns}/held_inputs',
                                              lambda m, ns=ns: on_mark(m, ns), DATA_QOS)
                for ns in namespaces]
        try:
            wait_for(lambda: self.publish(topic, value) or time.sleep(0.3) or
                     heard == set(namespaces), timeout, what=f'{namespaces} hearing {topic}')
        finally:
            for sub in subs:
                self.node.destroy_subscription(sub)

    def params(self, node_name, timeout=20.0):
        """Return a parameter client of ``node_name`` once its services are up."""
        client = AsyncParameterClient(self.node, node_name)
        assert client.wait_for_services(timeout * SLACK), f'no parameter services on {node_name}'
        return client

    def call(self, client, request, timeout=10.0, tries=3):
        """
        Send ``request(client)`` (it returns a service future) and return its result.

        A response is lost when the server answers before it has matched this
        client's response reader (a known DDS race, ros2/rmw_fastrtps#390); the
        request is then sent again, as a user would repeat a ``ros2 param`` call,
        from a new client: once, three tries of one client in a row went
        unanswered, so the retry gets new request and response endpoints, and
        later calls to that node use them too.  Parameter requests are
        idempotent, so a repeat changes nothing.
        """
        name = client.remote_node_name
        for attempt in range(tries):
            client = self.renewed.get(name, client)
            future = request(client)
            end = time.monotonic() + timeout
            while not future.done() and time.monotonic() < end:
                time.sleep(0.01)
            if future.done():
                return future.result()
            print(f'service call to {name} unanswered after {timeout} s (try {attempt + 1}/'
                  f'{tries}); next from a new client', file=sys.stderr)
            fresh = AsyncParameterClient(self.node, name)
            if fresh.wait_for_services(timeout):
                self.renewed[name] = fresh
        raise AssertionError(f'service call to {name} timed out {tries} times')

    def set_params(self, client, atomically=False, **values):
        """Set parameters through the standard service; return the SetParametersResult list."""
        params = [Parameter(k, value=v) for k, v in values.items()]
        if atomically:
            return [self.call(client, lambda c: c.set_parameters_atomically(params)).result]
        return self.call(client, lambda c: c.set_parameters(params)).results

    def get_params(self, client, *names):
        """Return the current values of parameters through the standard service."""
        res = self.call(client, lambda c: c.get_parameters(list(names)))
        return [Parameter.from_parameter_msg(ParamMsg(name=n, value=v)).value
                for n, v in zip(names, res.values)]

    def close(self):
        """Stop spinning and destroy the node."""
        self.executor.shutdown()
        self.node.destroy_node()
