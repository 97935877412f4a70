"""
``ros2 param load`` and ``ros2 param dump`` against the real loop nodes, and typed profiles.

``ros2 param load /valve FILE`` is ``AsyncParameterClient.load_parameter_file(FILE,
use_wildcard=True)``: every section of the file goes to that one node, one
parameter at a time, each value re-read from its text.  So the shipped files
hold one node each (``config/params/<loop>_<case>/<node>.params.yaml``, keyed
``/**/<node>``).  Each starts its node in a namespace of its own with
``--params-file``, and loads into it again with every entry accepted,
start-up-only values included.  A dump (every parameter, written as
``ros2 param dump`` writes it) loads back into its node and into another one.
A set-point or OP profile changes with one typed parameter, seen on the
topic, and ``use_sim_time`` cannot switch the clock of a running node.
"""

from pathlib import Path
import time

import pytest
from rcl_interfaces.msg import Parameter as ParamMsg
from rclpy.parameter import Parameter, parameter_dict_from_yaml_file
from ros_helpers import start_node, stop, wait_for
from stiction_ros.errors import SourceError
from stiction_ros.resources import config_dir, config_file
from stiction_ros.sim.loop_config import load_loop
from stiction_ros.sim.profile_params import key_defaults, KEYS, pairs, profile_parameters
from stiction_ros.sim.profile_params import profile_spec, PROFILE_TYPES
from stiction_ros.sim.ros_params import nest, node_params_file, shipped_node_params
from stiction_ros.sim.sources import make_source
import yaml

pytestmark = pytest.mark.ros
SHIPPED = sorted(shipped_node_params(config_dir()))
# rclpy's own, declared read-only by rclpy itself: refused by rclpy in any load.
ROS_READ_ONLY = {'start_type_description_service'}
TS = 0.05


def node_of(rel):
    return Path(rel).name.split('.')[0]


def plain(value):
    return value if isinstance(value, (str, bool, int, float)) else list(value)


def current(probe, client, names):
    """Return ``{name: value}`` of the node's parameters, arrays as lists."""
    return dict(zip(names, map(plain, probe.get_params(client, *names))))


def in_file(path):
    """Return ``{name: value}`` as ``ros2 param load`` reads the file."""
    return {name: plain(Parameter.from_parameter_msg(msg).value)
            for name, msg in parameter_dict_from_yaml_file(str(path), True).items()}


def load(probe, client, path):
    """Do what ``ros2 param load NODE PATH`` does; return the results."""
    return probe.call(client,
                      lambda c: c.load_parameter_file(str(path), use_wildcard=True)).results


def dump(probe, client, node, path):
    """Write every parameter of the node as ``ros2 param dump`` does; return them flat."""
    names = sorted(probe.call(client, lambda c: c.list_parameters([], 0)).result.names)
    res = probe.call(client, lambda c: c.get_parameters(names))
    flat = {n: plain(Parameter.from_parameter_msg(ParamMsg(name=n, value=v)).value)
            for n, v in zip(names, res.values) if n not in ROS_READ_ONLY}
    path.write_text(yaml.dump({node: {'ros__parameters': nest(flat)}},
                              default_flow_style=False))
    return flat


def test_the_shipped_node_files_are_what_the_loop_files_give():
    expected = shipped_node_params(config_dir())
    on_disk = {str(p.relative_to(config_dir())): p.read_text(encoding='utf-8')
               for p in (config_dir() / 'params').glob('*/*')}
    assert sorted(on_disk) == sorted(expected), 'run make params'
    for rel, text in expected.items():
        assert on_disk[rel] == text, f'config/{rel} is stale: run make params'
        # One node per file, for a node of that name in any namespace.
        assert list(yaml.safe_load(text)) == [f'/**/{node_of(rel)}'], rel
    assert len(expected) >= 15 and 'params/hidden_effect/plant.params.yaml' in expected


def test_every_source_maps_to_typed_parameters_and_back(tmp_path):
    # Every key of every profile source has a declared range or rule (KEYS) and a default.
    assert set(key_defaults()) == set(KEYS)
    csv = tmp_path / 'op.csv'
    csv.write_text('t,op\n0,40\n5,45\n')
    specs = [{'type': 'steps', 'steps': [[0, 1], [10, 2]]},
             {'type': 'sine', 'period': 20.0, 'amplitude': 3.0},
             {'type': 'triangle', 'offset': 10.0}, {'type': 'random_walk', 'seed': 4},
             {'type': 'replay', 'file': str(csv)}]
    assert {s['type'] for s in specs} == set(PROFILE_TYPES[1:])
    times = [0.0, 2.5, 5.0, 7.5, 10.0, 12.5]
    for spec in specs:
        flat = profile_parameters(spec, 'sp')
        assert list(flat)[-1] == 'type'
        assert all(isinstance(v, (str, int, float)) or all(isinstance(x, float) for x in v)
                   for v in flat.values()), flat
        back = make_source(profile_spec(flat, 'sp'), 'sp')
        assert list(back.sample(times)) == list(make_source(spec).sample(times)), spec
    assert profile_spec({'type': ''}, 'sp') is None
    with pytest.raises(SourceError, match='odd count'):
        pairs([0.0, 1.0, 2.0], 'disturbance_steps')


@pytest.fixture(scope='module')
def shipped(probe, tmp_path_factory):
    """Start the node of every shipped file with it, one namespace per case; yield clients."""
    logs = tmp_path_factory.mktemp('param_load')
    base = f'/pl{time.monotonic_ns() % 10**6}'
    procs = {}
    for rel in SHIPPED:
        ns = f'{base}/{Path(rel).parent.name}'
        procs[rel] = (start_node(node_of(rel), namespace=ns, log_dir=str(logs),
                                 extra=['--params-file', str(config_dir() / rel)]),
                      f'{ns}/{node_of(rel)}')
    # 15 processes start at once on a small machine: allow them time.
    clients = {rel: (probe.params(name, timeout=120.0), name) for rel, (_, name) in procs.items()}
    # Services are discovered before a node's executor is free to answer them
    # (its first samples may still be compiling kernels on a loaded machine):
    # one answered request from each before any test reads them.
    for client, _ in clients.values():
        probe.call(client, lambda c: c.list_parameters([], 0), timeout=60.0)
    yield clients
    for rel, (proc, name) in procs.items():
        assert stop(proc) == 0, name


@pytest.mark.parametrize('rel', SHIPPED)
@pytest.mark.slow
def test_a_shipped_file_starts_its_node_and_ros2_param_load_takes_every_entry(
        probe, shipped, rel):
    client, _ = shipped[rel]
    path = config_dir() / rel
    want = in_file(path)
    assert len(want) >= 6
    # --params-file applied the /**/<node> section in this namespace.
    assert current(probe, client, list(want)) == want
    results = load(probe, client, path)
    assert len(results) == len(want)
    refused = {n: r.reason for n, r in zip(want, results) if not r.successful}
    assert not refused, refused
    assert current(probe, client, list(want)) == want


@pytest.mark.parametrize('node', ['valve', 'controller', 'plant'])
def test_a_dump_loads_back_into_its_node_and_into_another(probe, shipped, node, tmp_path):
    client, name = shipped[f'params/concentration_undershoot/{node}.params.yaml']
    other, _ = shipped[f'params/concentration_overshoot/{node}.params.yaml']
    live = {'valve': {'S': 6.5}, 'controller': {'Kc': 0.3}, 'plant': {'load': 0.25}}[node]
    assert probe.set_params(client, **live)[0].successful
    path = tmp_path / f'{node}.yaml'
    before = dump(probe, client, name, path)
    assert before['use_sim_time'] is False and len(before) >= 10
    if node == 'valve':
        # rclpy reads 1e-07 back from a file as a string; the node takes it as the double.
        assert 0.0 < before['v_stick'] < 1e-4 and str(before['v_stick']).count('e-')
    for target in (client, other):
        results = load(probe, target, path)
        assert len(results) == len(before)
        refused = {n: r.reason for n, r in zip(in_file(path), results) if not r.successful}
        assert not refused, refused
        assert current(probe, target, list(before)) == before


@pytest.fixture(scope='module')
def controller(probe, tmp_path_factory):
    """Start a controller in open loop on wall time, its set point and OP from steps profiles."""
    logs = tmp_path_factory.mktemp('profiles')
    ns = f'/prof{time.monotonic_ns() % 10**6}'
    proc = start_node('controller', {
        'sample_time': TS, 'mode': 'open_loop',
        'setpoint_profile.steps': [0.0, 1.0], 'setpoint_profile.type': 'steps',
        'op_profile.steps': [0.0, 30.0], 'op_profile.type': 'steps'},
        namespace=ns, log_dir=str(logs))
    probe.listen(f'{ns}/sp')
    probe.listen(f'{ns}/op')
    yield ns, probe.params(f'{ns}/controller')
    assert stop(proc) == 0, (logs / 'controller.log').read_text()


def settles(probe, topic, value, what):
    """Wait until the last 3 values on ``topic`` are ``value``."""
    wait_for(lambda: probe.values(topic)[-3:] == [value] * 3, 20.0, what)


def test_one_typed_parameter_changes_the_profile_on_the_topic(probe, controller):
    ns, client = controller
    settles(probe, f'{ns}/sp', 1.0, 'the start-up set-point profile')
    settles(probe, f'{ns}/op', 30.0, 'the start-up OP profile')
    # One set_parameters call of one parameter: the new steps are in force at once.
    assert probe.set_params(client, **{'setpoint_profile.steps': [0.0, 4.0]})[0].successful
    settles(probe, f'{ns}/sp', 4.0, 'the new set-point steps')
    assert probe.set_params(client, **{'op_profile.steps': [0.0, 70.0]})[0].successful
    settles(probe, f'{ns}/op', 70.0, 'the new OP steps')
    # The constant, set last, is in force, and the profile's type says so.
    assert probe.set_params(client, setpoint=2.0)[0].successful
    settles(probe, f'{ns}/sp', 2.0, 'the constant set point')
    assert probe.get_params(client, 'setpoint_profile.type') == ['']
    # Setting the profile's type puts it back in force.
    assert probe.set_params(client, **{'setpoint_profile.type': 'steps'})[0].successful
    settles(probe, f'{ns}/sp', 4.0, 'the profile again')
    # As ros2 param set sends "[0, 5, 100, 6]": integers, taken as the doubles they say.
    assert probe.set_params(client, **{'setpoint_profile.steps': [0, 5]})[0].successful
    settles(probe, f'{ns}/sp', 5.0, 'integer steps')


def test_an_invalid_profile_is_refused_with_the_fix_and_changes_nothing(probe, controller):
    ns, client = controller
    keep = probe.get_params(client, 'setpoint_profile.steps', 'setpoint_profile.type')
    res = probe.set_params(client, **{'setpoint_profile.steps': [0.0, 1.0, 2.0]})[0]
    assert not res.successful and '[t0, v0, t1, v1, ...]' in res.reason, res.reason
    # A random walk whose bounds cross is refused when its type is set.
    assert probe.set_params(client, **{'setpoint_profile.low': 200.0})[0].successful
    res = probe.set_params(client, **{'setpoint_profile.type': 'random_walk'})[0]
    assert not res.successful and 'below high' in res.reason, res.reason
    res = probe.set_params(client, **{'setpoint_profile.type': 'sinus'})[0]
    assert not res.successful and 'one of' in res.reason, res.reason
    assert list(map(plain, probe.get_params(
        client, 'setpoint_profile.steps', 'setpoint_profile.type'))) == list(map(plain, keep))


def test_a_loop_file_profile_loads_into_a_running_controller(probe, controller, tmp_path):
    ns, client = controller
    cfg = load_loop(config_file('concentration_loop.yaml'), 'undershoot', {
        'sample_time': TS, 'controller.mode': 'open_loop',
        'controller.op': {'type': 'sine', 'offset': 40.0, 'amplitude': 5.0, 'period': 1.0}})
    path = tmp_path / 'controller.params.yaml'
    path.write_text(node_params_file(cfg, 'controller'))
    results = load(probe, client, path)
    assert results and all(r.successful for r in results), [r.reason for r in results]
    assert probe.get_params(client, 'op_profile.type', 'op_profile.period') == ['sine', 1.0]
    n = len(probe.values(f'{ns}/op'))
    wait_for(lambda: len(probe.values(f'{ns}/op')) >= n + 30, 20.0, 'a period of the sine')
    wave = probe.values(f'{ns}/op')[n + 5:]
    assert min(wave) < 37.0 and max(wave) > 43.0
    assert all(35.0 - 1e-9 <= v <= 45.0 + 1e-9 for v in wave)
    settles(probe, f'{ns}/sp', 1.0, "the file's set-point steps")


def test_use_sim_time_is_refused_on_a_running_node_which_keeps_publishing(probe, controller):
    ns, client = controller
    res = probe.set_params(client, use_sim_time=True)[0]
    assert not res.successful
    assert 'use_sim_time can only be set at start-up' in res.reason, res.reason
    assert '-p use_sim_time:=true' in res.reason
    assert probe.get_params(client, 'use_sim_time') == [False]
    # Had the time source switched to a /clock nobody publishes, time would stand at 0.
    n = len(probe.values(f'{ns}/sp'))
    wait_for(lambda: len(probe.values(f'{ns}/sp')) >= n + 10, 10.0, 'samples after the refusal')
    assert probe.set_params(client, use_sim_time=False)[0].successful
