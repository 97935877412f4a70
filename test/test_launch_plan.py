"""
What ``loop.launch.py`` starts, from its arguments (``sim.launch_plan``; no ``launch`` needed).

The launch file only maps the plan onto launch_ros actions; its own syntax
and the names it uses are checked here too.
"""

import ast
from pathlib import Path
import time

import pytest
from stiction_ros.errors import ConfigError
from stiction_ros.resources import config_dir
from stiction_ros.sim.launch_plan import launch_plan, resolve_config, split_settings

ROOT = Path(__file__).resolve().parents[1]


def test_a_shipped_config_is_found_by_its_file_name_and_a_path_is_taken_as_it_is(tmp_path):
    assert resolve_config('concentration_loop.yaml') == config_dir() / 'concentration_loop.yaml'
    own = tmp_path / 'mine.yaml'
    own.write_text((config_dir() / 'concentration_loop.yaml').read_text())
    assert resolve_config(str(own)) == own
    with pytest.raises(ConfigError, match="shipped: .*'concentration_loop.yaml'"):
        resolve_config('concentration_lop.yaml')


def test_settings_split_outside_brackets():
    assert split_settings('valve.S=7, plant.num=[3.0, 1.0]; valve.J=2') == [
        'valve.S=7', 'plant.num=[3.0, 1.0]', 'valve.J=2']
    assert split_settings('') == []


def test_duration_set_and_log_level_reach_the_nodes():
    plan = launch_plan(config='concentration_loop.yaml', case='undershoot', rtf='50',
                       duration='120', settings='valve.S=7, valve.J=2', log_level='WARN')
    nodes = {n.name: n for n in plan.nodes}
    assert set(nodes) == {'plant', 'controller', 'valve', 'sim_clock'}
    assert (nodes['valve'].parameters['S'], nodes['valve'].parameters['J']) == (7.0, 2.0)
    ts = nodes['valve'].parameters['sample_time']
    # The sim clock stops after the valve's last sample of the 120 s asked for.
    assert nodes['sim_clock'].parameters['stop_at'] == pytest.approx(120.0 + 0.75 * ts)
    assert nodes['sim_clock'].sim_time is False and nodes['valve'].sim_time is True
    assert plan.end_after is None
    assert plan.ros_arguments == ['--log-level', 'warn']


def test_a_wall_time_launch_ends_after_its_duration_and_respawns_with_a_state_dir(tmp_path):
    plan = launch_plan(duration='30', state_dir=str(tmp_path), record=str(tmp_path / 'bag'))
    nodes = {n.name: n for n in plan.nodes}
    assert 'sim_clock' not in nodes and nodes['recorder'].respawn is False
    assert all(nodes[n].respawn for n in ('plant', 'controller', 'valve'))
    assert nodes['valve'].parameters['state_file'] == str(tmp_path / 'valve.state')
    assert plan.end_after == pytest.approx(30.0 + 0.75 * nodes['valve'].parameters['sample_time'])
    # The profiles of every loop node count from one launch instant (none on sim time).
    starts = {nodes[n].parameters['start_time'] for n in ('plant', 'controller', 'valve')}
    assert len(starts) == 1 and abs(starts.pop() - time.time()) < 60.0
    assert 'start_time' not in nodes['recorder'].parameters
    assert all('start_time' not in n.parameters for n in launch_plan(rtf='10').nodes)


@pytest.mark.parametrize('kwargs, match', [
    ({'log_level': 'loud'}, 'log_level'), ({'duration': 'long'}, 'must be numbers'),
    ({'rtf': '-1'}, 'rtf must be'), ({'settings': 'valve.S'}, 'KEY=VALUE'),
    ({'settings': 'valve.Q=1'}, 'valve.Q'), ({'case': 'nope'}, 'no case')])
def test_a_bad_launch_argument_is_named(kwargs, match):
    with pytest.raises(ConfigError, match=match):
        launch_plan(**kwargs)


def test_the_launch_file_declares_every_argument_the_plan_takes():
    tree = ast.parse((ROOT / 'launch' / 'loop.launch.py').read_text())
    args = next(n for n in ast.walk(tree) if isinstance(n, ast.Assign)
                and getattr(n.targets[0], 'id', '') == 'ARGUMENTS')
    names = {t.elts[0].value for t in args.value.elts}
    assert names == {'config', 'case', 'namespace', 'rtf', 'duration', 'set', 'log_level',
                     'record', 'state_dir'}
