"""
Every parameter of every node, through the standard services as ``ros2 param`` uses them.

One process per node kind; the test lists each node's parameters and checks
what ``ros2 param describe`` would show (a range for every number, an
allowed set or a stated rule for every settable string or array), then sets
each settable number just outside its range, each settable string or array
to something invalid and each inconsistent pair, and checks that every
rejection carries a reason and changes nothing, also inside an atomic call
with a valid value.  A loop node's parameter fixed for the run takes the
value it has and refuses any other, naming the restart that would set it.
"""

import re
import subprocess
import sys
import time

import pytest
from rcl_interfaces.msg import ParameterType as T
from ros_helpers import start_node, stop
from stiction_ros.cli.loop import MODULES

pytestmark = pytest.mark.ros
ROS_OWN = {'use_sim_time', 'start_type_description_service'}
NUMBERS = {T.PARAMETER_DOUBLE, T.PARAMETER_INTEGER}
# Settable strings with no allowed set: a value each must refuse (else 'no-such-choice').
BAD_TEXT = {f'{p}.{key}': '' for p in ('setpoint_profile', 'op_profile')
            for key in ('column', 'time_column')}
# Not [t, v] pairs (an odd count), and a change of the plant's num, den, load steps.
BAD_ARRAY = [1.0, 2.0, 3.0]
ARRAYS = {T.PARAMETER_DOUBLE_ARRAY, T.PARAMETER_STRING_ARRAY}
LOOP_NODES = ('valve', 'plant', 'controller')
# Combinations that are each in range but inconsistent together.
INCONSISTENT = {'controller': {'op_min': 80.0, 'op_max': 20.0},
                'valve': {'Fc': 900.0, 'Fs': 800.0}}


@pytest.fixture(scope='module')
def nodes(probe, tmp_path_factory):
    logs = tmp_path_factory.mktemp('audit')
    ns = f'/audit{time.monotonic_ns() % 10**6}'
    specs = {'valve': {'sample_time': 0.1}, 'plant': {'sample_time': 0.1},
             'controller': {'sample_time': 0.1},
             'recorder': {'output': str(logs / 'bag')},
             'sim_clock': {'rtf': 1.0, 'stop_at': 1e6}}
    procs = {name: start_node(name, params, namespace=ns, log_dir=str(logs))
             for name, params in specs.items()}
    clients = {name: probe.params(f'{ns}/{name}') for name in specs}
    yield clients
    for name, proc in procs.items():
        assert stop(proc) == 0, (logs / f'{name}.log').read_text()


def describe(probe, client):
    names = probe.call(client, lambda c: c.list_parameters([], 0)).result.names
    res = probe.call(client, lambda c: c.describe_parameters(list(names)))
    return {d.name: d for d in res.descriptors if d.name not in ROS_OWN}


def outside(d):
    if d.type == T.PARAMETER_DOUBLE:
        r = d.floating_point_range[0]
        return r.to_value * 2 + 1 if r.to_value < 1e300 else r.from_value - abs(r.from_value) - 1
    r = d.integer_range[0]
    return r.to_value + 1 if r.to_value < 2**62 else r.from_value - 1


@pytest.mark.parametrize('name', ['valve', 'plant', 'controller', 'recorder', 'sim_clock'])
@pytest.mark.slow
def test_help_lists_what_the_running_node_declares(probe, nodes, name):
    # A venv from PyPI has no `ros2 param`: --help is where a newcomer reads them.
    run = subprocess.run([sys.executable, '-m', f'stiction_ros.nodes.{MODULES[name]}', '--help'],
                         capture_output=True, text=True, timeout=60)
    assert run.returncode == 0, run.stderr
    listed = re.findall(r'^  (\S+) \((\w+)', run.stdout, flags=re.M)
    seen = describe(probe, nodes[name])
    assert sorted(n for n, _ in listed) == sorted(seen)
    words = {T.PARAMETER_DOUBLE: 'double', T.PARAMETER_INTEGER: 'integer',
             T.PARAMETER_STRING: 'string', T.PARAMETER_BOOL: 'bool',
             T.PARAMETER_DOUBLE_ARRAY: 'double', T.PARAMETER_STRING_ARRAY: 'string'}
    assert dict(listed) == {n: words[d.type] for n, d in seen.items()}


@pytest.mark.parametrize('name', ['valve', 'plant', 'controller', 'recorder', 'sim_clock'])
def test_every_parameter_says_what_it_accepts(probe, nodes, name):
    seen = describe(probe, nodes[name])
    assert seen
    for pname, d in seen.items():
        assert d.description, (name, pname)
        if d.type in NUMBERS:
            assert d.floating_point_range or d.integer_range, (name, pname, 'no range')
        elif (d.type == T.PARAMETER_STRING or d.type in ARRAYS) and not d.read_only:
            assert d.additional_constraints, (name, pname, 'no allowed set or rule')
        else:
            assert d.read_only or d.type == T.PARAMETER_BOOL, (name, pname)
        fixed = 'fixed for the run' in d.additional_constraints
        assert fixed == ('Fixed for the run' in d.description and not d.read_only), (name, pname)


@pytest.mark.parametrize('name', ['valve', 'plant', 'controller', 'recorder', 'sim_clock'])
def test_invalid_values_are_rejected_with_a_reason_and_change_nothing(probe, nodes, name):
    client = nodes[name]
    seen = describe(probe, client)
    tried = 0
    for pname, d in seen.items():
        before = probe.get_params(client, pname)
        if d.read_only:
            bad = before[0]
        elif d.type in NUMBERS:
            bad = outside(d)
            bad = int(bad) if d.type == T.PARAMETER_INTEGER else float(bad)
        elif d.type == T.PARAMETER_STRING:
            bad = BAD_TEXT.get(pname, 'no-such-choice')
        elif d.type == T.PARAMETER_DOUBLE_ARRAY:
            bad = BAD_ARRAY
        else:
            continue
        res = probe.set_params(client, **{pname: bad})[0]
        assert not res.successful and res.reason, (name, pname, bad)
        assert probe.get_params(client, pname) == before, (name, pname)
        tried += 1
    assert tried >= len(seen) - 2


@pytest.mark.parametrize('name', ['valve', 'controller'])
def test_inconsistent_combinations_are_refused_atomically(probe, nodes, name):
    client = nodes[name]
    pair = INCONSISTENT[name]
    before = probe.get_params(client, *pair)
    res = probe.set_params(client, atomically=True, **pair)[0]
    assert not res.successful and res.reason
    assert probe.get_params(client, *pair) == before
    # A valid value in the same atomic call is not applied either.
    settable = 'J' if name == 'valve' else 'Kc'
    keep = probe.get_params(client, settable)
    res = probe.set_params(client, atomically=True, **{settable: 1.5}, **pair)[0]
    assert not res.successful
    assert probe.get_params(client, settable, *pair) == keep + before


def other_value(d, value):
    """Return a valid value of ``d``'s type and range that is not ``value``."""
    if d.type in NUMBERS:
        r = (d.floating_point_range or d.integer_range)[0]
        return r.from_value if value != r.from_value else r.to_value
    if d.type == T.PARAMETER_DOUBLE_ARRAY:
        return list(value) + [1.0, 2.0]
    return value + '.other'


@pytest.mark.parametrize('name', LOOP_NODES)
def test_a_parameter_fixed_for_the_run_takes_its_value_and_refuses_a_change(probe, nodes, name):
    client = nodes[name]
    fixed = {p: d for p, d in describe(probe, client).items()
             if 'fixed for the run' in d.additional_constraints}
    assert {'sample_time', 'phase', 'state_file'} <= set(fixed)
    for pname, d in fixed.items():
        before = probe.get_params(client, pname)
        # An array comes back as array.array, which rclpy's Parameter does not take.
        value = list(before[0]) if d.type in ARRAYS else before[0]
        assert probe.set_params(client, **{pname: value})[0].successful, pname
        res = probe.set_params(client, **{pname: other_value(d, value)})[0]
        assert not res.successful, pname
        assert f'{pname} can only be set at start-up' in res.reason, res.reason
        assert f'-p {pname}:=' in res.reason, res.reason
        assert probe.get_params(client, pname) == before, pname
