"""
Turn a loop description (YAML, see :mod:`loop_config`) into ROS node parameters.

The loop launcher, ``launch/loop.launch.py`` and the shipped
``config/*.params.yaml`` files all use this one mapping, so the live loop
runs exactly the configuration the offline simulator runs.  Pure Python: no
rclpy needed to generate a parameter file.
"""

from stiction_ros.models import MODELS
from stiction_ros.sim.loop_config import ConfigError
import yaml

LOOP_NODES = ('plant', 'controller', 'valve')
# Fraction of the sample at which each node acts (see nodes/sampled.py).
PHASES = {'plant': 0.25, 'controller': 0.5, 'valve': 0.75}
# The sim clock runs in lockstep with the topic each loop node publishes.
SYNC = (('pv', 'plant'), ('op', 'controller'), ('mv', 'valve'))


def _flow(value):
    return yaml.safe_dump(value, default_flow_style=True, width=1 << 20).strip()


def node_parameters(cfg):
    """Return ``{'plant': {...}, 'controller': {...}, 'valve': {...}}`` for a validated loop."""
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
        'disturbance_steps': _flow([[float(t), float(s)] for t, s in
                                    p.get('disturbance_steps', ())]),
        'noise_std': float(noise.get('pv_std', 0.0)), 'seed': int(noise.get('seed', 0)),
    }
    ctl = {'sample_time': ts, 'phase': PHASES['controller'],
           'mode': c.get('mode', 'closed_loop'), 'bias': float(c.get('bias', mv0))}
    for key, default in (('Kc', 1.0), ('Ti', 0.0), ('Td', 0.0), ('N', 10.0),
                         ('op_min', 0.0), ('op_max', 100.0)):
        ctl[key] = float(c.get(key, default))
    ctl['action'] = c.get('action', 'reverse')
    sp = c.get('setpoint', p.get('pv0', 0.0))
    if isinstance(sp, dict):
        ctl['setpoint_profile'] = _flow(sp)
    else:
        ctl['setpoint'] = float(sp)
    if ctl['mode'] == 'open_loop':
        if isinstance(c['op'], dict):
            ctl['op_profile'] = _flow(c['op'])
        else:
            ctl['op'] = float(c['op'])
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


def params_file(cfg, namespace='', extra=None):
    """
    Return the text of a ROS 2 parameter file for the loop's nodes.

    Node names are fully qualified (``/ns/valve``) so the file loads with
    ``--params-file`` for that namespace only.  ``extra`` adds sections for
    other nodes (``{'recorder': {...}}``).
    """
    ns = '/' + namespace.strip('/') if namespace.strip('/') else ''
    sections = dict(node_parameters(cfg))
    sections.update(extra or {})
    doc = {f'{ns}/{name}': {'ros__parameters': params} for name, params in sections.items()}
    head = f'# Generated from the loop "{cfg.get("name", "loop")}"'
    if cfg.get('case'):
        head += f', case {cfg["case"]}'
    return head + ' by stiction_ros.sim.ros_params.\n' + yaml.safe_dump(doc, sort_keys=False)
