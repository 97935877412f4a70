"""
Offline loop simulator: controller, valve and plant stepped at one sample time.

Each sample, in the order a sampled loop runs: read PV, compute OP, move the
valve, then hold MV over the sample while the plant advances.  The live ROS
loop runs the same objects in three nodes.
"""

import numpy as np

from stiction_ros.controller import PID
from stiction_ros.models import create, MODELS
from stiction_ros.plant import TransferFunctionPlant
from stiction_ros.sources import make_source

COLUMNS = ('t', 'sp', 'op', 'mv', 'pv')


def build_valve(cfg):
    """Return the valve model of a validated loop description, at rest at ``plant.mv0``."""
    spec = dict(cfg['valve'])
    cls_name = spec.pop('model')
    if 'sample_time' in MODELS[cls_name].PARAMS and 'sample_time' not in spec:
        spec['sample_time'] = cfg['sample_time']
    return create(cls_name, **spec)


def build_plant(cfg):
    """Return the plant of a validated loop description."""
    p = cfg['plant']
    noise = cfg.get('noise') or {}
    return TransferFunctionPlant(
        p['num'], p['den'], delay=p.get('delay', 0.0), sample_time=cfg['sample_time'],
        mv0=p.get('mv0', 50.0), pv0=p.get('pv0', 0.0), noise_std=noise.get('pv_std', 0.0),
        disturbance_steps=p.get('disturbance_steps', ()), seed=noise.get('seed', 0))


def build_controller(cfg):
    """Return the PID and the set-point (or open-loop OP) source of a loop description."""
    c = cfg['controller']
    mv0 = cfg['plant'].get('mv0', 50.0)
    pid = PID(Kc=c.get('Kc', 1.0), Ti=c.get('Ti', 0.0), Td=c.get('Td', 0.0), N=c.get('N', 10.0),
              sample_time=cfg['sample_time'], op_min=c.get('op_min', 0.0),
              op_max=c.get('op_max', 100.0), bias=c.get('bias', mv0),
              action=c.get('action', 'reverse'))
    sp = make_source(c.get('setpoint', cfg['plant'].get('pv0', 0.0)), 'controller.setpoint')
    op = make_source(c['op'], 'controller.op') if c.get('mode') == 'open_loop' else None
    return pid, sp, op


def simulate_loop(cfg, duration=None, progress=None):
    """
    Run a validated loop description; return a dict of arrays named by COLUMNS.

    ``mv`` and ``pv`` are the measured values (with the configured noise);
    ``mv_true`` is the valve position the plant received.
    """
    ts = float(cfg['sample_time'])
    n = int(round(float(duration if duration is not None else cfg['duration']) / ts)) + 1
    valve = build_valve(cfg)
    plant = build_plant(cfg)
    pid, sp_src, op_src = build_controller(cfg)
    noise = cfg.get('noise') or {}
    mv_std = float(noise.get('mv_std', 0.0))
    rng = np.random.default_rng(int(noise.get('seed', 0)) + 1)
    valve.reset(y0=min(max(plant.mv0, 0.0), 100.0))
    out = {k: np.empty(n) for k in COLUMNS + ('mv_true',)}
    every = max(n // 20, 1)
    for k in range(n):
        t = k * ts
        pv = plant.output()
        sp = sp_src(t)
        op = op_src(t) if op_src is not None else pid.update(sp, pv)
        mv = valve.step(op)
        plant.update(mv)
        out['t'][k], out['sp'][k], out['op'][k], out['pv'][k] = t, sp, op, pv
        out['mv_true'][k] = mv
        if progress is not None and (k % every == 0 or k == n - 1):
            progress(k + 1, n)
    out['mv'] = out['mv_true'] + (mv_std * rng.standard_normal(n) if mv_std > 0 else 0.0)
    return out


def write_csv(path, data, columns=COLUMNS):
    """Write the named columns of a simulation result to CSV with a header row."""
    arr = np.column_stack([data[c] for c in columns])
    np.savetxt(path, arr, delimiter=',', header=','.join(columns), comments='', fmt='%.10g')
