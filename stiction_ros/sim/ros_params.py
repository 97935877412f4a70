"""
Turn a loop description (YAML, see :mod:`loop_config`) into ROS node parameters.

The loop launcher, ``launch/loop.launch.py`` and the shipped
``config/params/<loop>_<case>/<node>.params.yaml`` files all use this one
mapping, so the live loop runs exactly the configuration the offline
simulator runs.  Profiles and load steps become typed parameters
(:mod:`profile_params`): ``setpoint_profile.type``, ``setpoint_profile.steps``
as ``[t0, v0, t1, v1, ...]``, ``disturbance_steps`` as ``[t0, s0, ...]``.

Two kinds of file: :func:`params_file`, every loop node in one file keyed by
its full name (the loop launcher's ``--params-file``), and
:func:`node_params_file`, one node's file keyed ``/**/<node>``, which applies
to that node in any namespace at start-up and which ``ros2 param load`` sends
to that node alone (it sends every section of a file to the one node it is
given).  Pure Python: no rclpy needed to generate a parameter file.
"""

from pathlib import Path

from stiction_ros.errors import SourceError
from stiction_ros.models import MODELS
from stiction_ros.sim.loop_config import ConfigError, load_loop
from stiction_ros.sim.profile_params import flat_pairs, profile_parameters
import yaml

LOOP_NODES = ('plant', 'controller', 'valve')
# The loop nodes reject an input beyond +-this (their input_limit's default).
INPUT_LIMIT = 1e6
# Fraction of the sample at which each node acts (see nodes/sampled.py).
PHASES = {'plant': 0.25, 'controller': 0.5, 'valve': 0.75}
# The sim clock runs in lockstep with the topic each loop node publishes.
SYNC = (('pv', 'plant'), ('op', 'controller'), ('mv', 'valve'))


def _signal(ctl, const, spec, prefix):
    # A number or a constant source is the plain parameter; any other source its profile.
    if isinstance(spec, dict) and spec.get('type') != 'constant':
        try:
            for key, value in profile_parameters(spec, f'controller.{const}').items():
                ctl[f'{prefix}.{key}'] = value
        except SourceError as err:
            raise ConfigError(str(err)) from None
    else:
        ctl[const] = float(spec.get('value', 0.0) if isinstance(spec, dict) else spec)


def node_parameters(cfg):
    """
    Return ``{'plant': {...}, 'controller': {...}, 'valve': {...}}`` for a validated loop.

    Parameter names are flat (``setpoint_profile.steps``), as ROS names them.
    """
    ts = float(cfg['sample_time'])
    p, c, v = cfg['plant'], cfg['controller'], dict(cfg['valve'])
    noise = cfg.get('noise') or {}
    if float(noise.get('mv_std', 0.0)) > 0.0:
        raise ConfigError('noise.mv_std: the live loop has no MV measurement noise; '
                          'remove it or use stiction-sim')
    mv0 = float(p.get('mv0', 50.0))
    plant = {
        'sample_time': ts, 'phase': PHASES['plant'],
        'num': [float(x) for x in p['num']], 'den': [float(x) for x in p['den']],
        'delay': float(p.get('delay', 0.0)), 'mv0': mv0, 'pv0': float(p.get('pv0', 0.0)),
        'noise_std': float(noise.get('pv_std', 0.0)), 'seed': int(noise.get('seed', 0)),
    }
    # None is the node's default: no empty list, which rcl and launch cannot type.
    if p.get('disturbance_steps'):
        plant['disturbance_steps'] = flat_pairs(p['disturbance_steps'],
                                                'plant.disturbance_steps')
    ctl = {'sample_time': ts, 'phase': PHASES['controller'],
           'mode': c.get('mode', 'closed_loop'), 'bias': float(c.get('bias', mv0))}
    for key, default in (('Kc', 1.0), ('Ti', 0.0), ('Td', 0.0), ('N', 10.0),
                         ('op_min', 0.0), ('op_max', 100.0)):
        ctl[key] = float(c.get(key, default))
    ctl['action'] = c.get('action', 'reverse')
    _signal(ctl, 'setpoint', c.get('setpoint', p.get('pv0', 0.0)), 'setpoint_profile')
    if ctl['mode'] == 'open_loop':
        _signal(ctl, 'op', c['op'], 'op_profile')
    model = v.pop('model')
    valve = {'sample_time': ts, 'phase': PHASES['valve'], 'model': model,
             'initial_position': min(max(mv0, 0.0), 100.0)}
    for key, value in v.items():
        if key == 'sample_time':
            continue
        kind = MODELS[model].PARAMS[key][1]
        valve[key] = value if isinstance(kind, str) else float(value)
    return {'plant': plant, 'controller': ctl, 'valve': valve}


def loop_extras(cfg, rtf=0.0, record=None, duration=None):
    """
    Return parameters of the run's helper nodes: ``recorder`` and ``sim_clock``.

    With ``rtf`` > 0 the clock steps in quarter samples, in lockstep with the
    topic each loop node publishes, and stops after the valve's last sample
    of ``duration`` (default: the file's).
    """
    ts = float(cfg['sample_time'])
    duration = float(duration if duration is not None else cfg['duration'])
    out = {}
    if record:
        out['recorder'] = {'output': str(record),
                           'topics': ['sp', 'op', 'mv', 'pv', 'held_inputs']}
    if rtf and rtf > 0:
        rec = 1 if record else 0
        waits = [f'pv={1 + rec}', f'op={1 + rec}', f'mv={1 + rec}',
                 f'/clock={len(LOOP_NODES) + rec}'] + (['sp=1'] if rec else [])
        out['sim_clock'] = {
            'rtf': float(rtf), 'step': ts / 4, 'stop_at': duration + PHASES['valve'] * ts,
            'wait_for': waits, 'sample_time': ts,
            'sync': [f'{topic}@{PHASES[node]}' for topic, node in SYNC]}
    return out


def nest(params):
    """Return flat parameter names (``a.b``) as nested mappings, as parameter files hold them."""
    out = {}
    for name, value in params.items():
        *parents, leaf = name.split('.')
        node = out
        for part in parents:
            node = node.setdefault(part, {})
        node[leaf] = value
    return out


def _head(cfg):
    head = f'# Generated from the loop "{cfg.get("name", "loop")}"'
    if cfg.get('case'):
        head += f', case {cfg["case"]}'
    return head + ' by stiction_ros.sim.ros_params.\n'


class _Dumper(yaml.SafeDumper):
    """Write lists in flow style (``[0.0, 1.0]``, as ``ros2 param set`` takes them)."""


_Dumper.add_representer(list, lambda dumper, data: dumper.represent_sequence(
    'tag:yaml.org,2002:seq', data, flow_style=True))


def _dump(doc):
    return yaml.dump(doc, Dumper=_Dumper, sort_keys=False, default_flow_style=False,
                     width=1 << 20)


def params_file(cfg, namespace='', extra=None):
    """
    Return the text of a ROS 2 parameter file for the loop's nodes.

    Node names are fully qualified (``/ns/valve``) so the file loads with
    ``--params-file`` for that namespace only.  ``extra`` adds sections for
    other nodes (``{'recorder': {...}}``).  For ``ros2 param load``, which
    sends every section to one node, use :func:`node_params_file`.
    """
    ns = '/' + namespace.strip('/') if namespace.strip('/') else ''
    sections = dict(node_parameters(cfg))
    sections.update(extra or {})
    doc = {f'{ns}/{name}': {'ros__parameters': nest(params)}
           for name, params in sections.items()}
    return _head(cfg) + _dump(doc)


def node_params_file(cfg, name):
    """
    Return the text of the parameter file of loop node ``name`` alone.

    Keyed ``/**/<name>``: ``--params-file`` applies it to a node of that name
    in any namespace, and ``ros2 param load /ns/<name> FILE`` sends it all to
    that node.  The profile's ``type`` comes after its keys, so a load in file
    order sets it once they are in.
    """
    doc = {f'/**/{name}': {'ros__parameters': nest(node_parameters(cfg)[name])}}
    return (_head(cfg) + f'# ros2 param load /{name} {name}.params.yaml   (or --params-file)\n'
            + _dump(doc))


def write_node_params(cfg, directory):
    """Write ``<node>.params.yaml`` of every loop node into ``directory``; return the paths."""
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    paths = []
    for name in LOOP_NODES:
        path = directory / f'{name}.params.yaml'
        path.write_text(node_params_file(cfg, name), encoding='utf-8')
        paths.append(path)
    return paths


def shipped_node_params(config):
    """
    Return ``{path under config: text}`` of the node parameter files shipped in ``config``.

    For every ``*_loop.yaml`` there and each of its cases, a folder
    ``params/<loop name>_<case>/`` (``params/<loop name>/`` for a loop without
    cases) with ``<node>.params.yaml`` of each loop node.
    """
    out = {}
    for path in sorted(Path(config).glob('*_loop.yaml')):
        cases = yaml.safe_load(path.read_text(encoding='utf-8')).get('cases') or {}
        for case in sorted(cases) or [None]:
            cfg = load_loop(path, case)
            folder = cfg['name'] + (f'_{case}' if case else '')
            for name in LOOP_NODES:
                out[f'params/{folder}/{name}.params.yaml'] = node_params_file(cfg, name)
    return out


def write_shipped_node_params(config):
    """Write :func:`shipped_node_params` into ``config`` (``make params``); return the paths."""
    paths = []
    for rel, text in shipped_node_params(config).items():
        path = Path(config) / rel
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text, encoding='utf-8')
        paths.append(path)
    return paths
