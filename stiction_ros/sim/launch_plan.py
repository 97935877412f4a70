"""
What ``ros2 launch stiction_ros loop.launch.py`` starts, worked out without ``launch``.

The launch file turns the arguments into a :class:`LaunchPlan` here and only
maps it onto ``launch_ros`` actions, so everything it decides (which file,
which parameters, when the run ends) is plain code that tests run on a
machine without ROS 2 launch.
"""

from dataclasses import dataclass, field
import os
from pathlib import Path
import time
from typing import Any

from stiction_ros.errors import ConfigError
from stiction_ros.resources import config_dir
from stiction_ros.sim.loop_config import load_loop, parse_overrides
from stiction_ros.sim.ros_params import loop_extras, LOOP_NODES, node_parameters

LOG_LEVELS = ('debug', 'info', 'warn', 'error', 'fatal')
DEFAULT_CONFIG = 'concentration_loop.yaml'


def resolve_config(name: str) -> Path:
    """
    Return the loop file ``name``: a path, or the name of a shipped file.

    ``config:=concentration_loop.yaml`` finds the file in the package's
    config directory (the share directory of an install), as a ROS user
    expects; a path that exists is taken as it is.
    """
    name = name or DEFAULT_CONFIG
    path = Path(name).expanduser()
    if path.is_file():
        return path
    shipped = config_dir() / name
    if path.parent == Path('.') and shipped.is_file():
        return shipped
    names = sorted(p.name for p in config_dir().glob('*.yaml'))
    if path.is_dir():
        raise ConfigError(f'config {name!r}: a folder, not a loop file; shipped: {names}')
    raise ConfigError(f'config {name!r}: no such file, and not a shipped loop file; '
                      f'shipped: {names}')


def split_settings(text: str) -> list[str]:
    """
    Split ``'valve.S=7, plant.num=[3.0, 1.0]'`` into ``KEY=VALUE`` items.

    Items are separated by commas or semicolons outside brackets, so a list
    value keeps its commas.
    """
    items, depth, start = [], 0, 0
    for i, ch in enumerate(text):
        if ch in '[{':
            depth += 1
        elif ch in ']}':
            depth -= 1
        elif ch in ',;' and depth == 0:
            items.append(text[start:i])
            start = i + 1
    items.append(text[start:])
    return [item.strip() for item in items if item.strip()]


@dataclass
class NodeSpec:
    """One node of the plan: its executable, parameters and whether it is respawned."""

    name: str
    parameters: dict[str, Any]
    sim_time: bool
    respawn: bool = False


@dataclass
class LaunchPlan:
    """The nodes to start, and when a wall-time run ends (None: when the sim clock exits)."""

    config: Path
    nodes: list[NodeSpec] = field(default_factory=list)
    end_after: float | None = None
    ros_arguments: list[str] = field(default_factory=list)


def launch_plan(config: str = '', case: str = '', rtf: str = '0.0', record: str = '',
                state_dir: str = '', duration: str = '', settings: str = '',
                log_level: str = '') -> LaunchPlan:
    """
    Return the plan for the launch arguments (all strings, as launch gives them).

    ``duration`` (s of loop time; default the file's) ends a sim-time run at
    the sim clock and a wall-time run after that many seconds; ``settings``
    overrides the file as ``loop --set`` does (``'valve.S=7, valve.J=2'``);
    ``log_level`` is every node's ``--log-level``.  Raises ConfigError naming
    the argument at fault.
    """
    path = resolve_config(config)
    cfg = load_loop(path, case or None, parse_overrides(split_settings(settings)))
    try:
        rtf_value = float(rtf or 0.0)
        length = float(duration) if duration else float(cfg['duration'])
    except ValueError:
        raise ConfigError(f'rtf {rtf!r} and duration {duration!r} must be numbers') from None
    if rtf_value < 0.0 or length <= 0.0:
        raise ConfigError(f'rtf must be >= 0 and duration > 0 (got rtf {rtf}, duration '
                          f'{duration})')
    level = (log_level or 'info').lower()
    if level not in LOG_LEVELS:
        raise ConfigError(f'log_level {log_level!r}: one of {LOG_LEVELS}')
    params = node_parameters(cfg)
    params.update(loop_extras(cfg, rtf=rtf_value, record=record or None, duration=length))
    sim = rtf_value > 0.0
    plan = LaunchPlan(config=path, ros_arguments=['--log-level', level])
    # On wall time the profiles count from the launch, alike in every loop node.
    start = round(time.time(), 3)
    for name, p in params.items():
        if not sim and name in LOOP_NODES:
            p['start_time'] = start
        if state_dir and name in LOOP_NODES:
            p['state_file'] = os.path.join(state_dir, f'{name}.state')
        plan.nodes.append(NodeSpec(name, p, sim_time=sim and name != 'sim_clock',
                                   respawn=bool(state_dir) and name in LOOP_NODES))
    if not sim:
        # A wall-time loop runs until its last sample has been taken (as `loop` does).
        plan.end_after = length + 0.75 * float(cfg['sample_time'])
    return plan
