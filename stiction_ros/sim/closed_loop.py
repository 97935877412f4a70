"""
Offline loop simulator: controller, valve and plant stepped at one sample time.

Each sample, in the order a sampled loop runs: read PV, compute OP, move the
valve, then hold MV over the sample while the plant advances.  The live ROS
loop runs the same objects in three nodes.
"""

import errno
import os
from os import PathLike
import secrets
from typing import Any, Callable, Mapping, Sequence, TextIO

import numpy as np

from stiction_ros.kernels.arrays import Floats
from stiction_ros.kernels.loop import run_loop
from stiction_ros.models import create, MODELS, ValveModel
from stiction_ros.sim.controller import PID
from stiction_ros.sim.plant import TransferFunctionPlant
from stiction_ros.sim.sources import make_source, Source

COLUMNS = ('t', 'sp', 'op', 'mv', 'pv')
# Called as progress(samples done, samples in all).
Progress = Callable[[int, int], object]


def build_valve(cfg: Mapping[str, Any]) -> ValveModel:
    """Return the valve model of a validated loop description, at rest at ``plant.mv0``."""
    spec = dict(cfg['valve'])
    cls_name = spec.pop('model')
    if 'sample_time' in MODELS[cls_name].PARAMS and 'sample_time' not in spec:
        spec['sample_time'] = cfg['sample_time']
    return create(cls_name, **spec)


def build_plant(cfg: Mapping[str, Any]) -> TransferFunctionPlant:
    """Return the plant of a validated loop description."""
    p = cfg['plant']
    noise = cfg.get('noise') or {}
    return TransferFunctionPlant(
        p['num'], p['den'], delay=p.get('delay', 0.0), sample_time=cfg['sample_time'],
        mv0=p.get('mv0', 50.0), pv0=p.get('pv0', 0.0), noise_std=noise.get('pv_std', 0.0),
        disturbance_steps=p.get('disturbance_steps', ()), seed=noise.get('seed', 0))


def build_controller(cfg: Mapping[str, Any]) -> tuple[PID, Source, Source | None]:
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


def simulate_loop(cfg: Mapping[str, Any], duration: float | None = None,
                  progress: Progress | None = None, compiled: bool = True) -> dict[str, Floats]:
    """
    Run a validated loop description; return a dict of arrays named by COLUMNS.

    ``mv`` and ``pv`` are the measured values (with the configured noise);
    ``mv_true`` is the valve position the plant received.  ``compiled``: run
    all samples after the first in ``loop_kernel`` (a valve without
    ``loop_args`` runs in Python anyway); False steps the objects one sample
    at a time in Python, the reference the compiled loop is tested against.
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
    out['t'] = np.arange(n) * ts
    out['sp'] = sp_src.sample(out['t'])
    op_open = op_src.sample(out['t']) if op_src is not None else None
    every = max(n // 20, 1)
    fast = compiled and valve.loop_args() is not None
    for k in range(1 if fast else n):
        pv = plant.output()
        op = op_open[k] if op_open is not None else pid.update(out['sp'][k], pv)
        mv = valve.step(op)
        plant.update(mv)
        out['op'][k], out['pv'][k], out['mv_true'][k] = op, pv, mv
        if progress is not None and (k % every == 0 or k == n - 1):
            progress(k + 1, n)
    if fast:
        run_compiled(out, valve, plant, pid, op_open, 1, n, progress, every)
    out['mv'] = out['mv_true'] + (mv_std * rng.standard_normal(n) if mv_std > 0 else 0.0)
    return out


def run_compiled(out: dict[str, Floats], valve: ValveModel, plant: TransferFunctionPlant, pid: PID,
                 op_open: Floats | None, k0: int, n: int, progress: Progress | None = None,
                 every: int | None = None) -> None:
    """
    Run samples ``k0`` to ``n - 1`` in ``loop_kernel``, in chunks between progress calls.

    The objects' states go in and come back out, so they end as the Python
    loop would leave them.
    """
    sign = 1.0 if pid.action == 'reverse' else -1.0
    pp = np.array([pid.Kc, pid.Ti, pid.Td, pid.N, pid.sample_time, pid.op_min, pid.op_max,
                   pid.bias, sign])
    pc = np.array([pid._i, pid._d, pid._pv_prev or 0.0,
                   0.0 if pid._pv_prev is None else 1.0, pid.op])
    m = plant._m
    hist = np.array(plant._hist, dtype=np.float64)
    ps = np.array([plant.time, plant._last])
    x = plant._x.copy()
    # The PV noise the plant would draw sample by sample, drawn at once (same stream).
    noise = np.zeros(n)
    if plant.noise_std > 0.0:
        noise[k0:] = plant.noise_std * plant._rng.standard_normal(n - k0)
    dist_t = np.array([t for t, _ in plant.disturbance_steps], dtype=np.float64)
    dist_v = np.array([v for _, v in plant.disturbance_steps], dtype=np.float64)
    kind, fp, arr, phis, hs, q, jmax = valve.loop_args()
    opo = np.empty(0) if op_open is None else op_open
    hpos = 0
    step = n if progress is None else max(every, 1)
    k = k0
    while k < n:
        k1 = min(n, k + step)
        hpos = run_loop(k, k1, out['sp'], opo, pp, pc, kind, fp, valve.state, arr, phis, hs,
                        q, jmax, plant._phi, plant._g0, plant._g1, plant._c, plant._d, m,
                        plant._fractional, x, hist, hpos, ps, plant.pv0, plant.mv0, dist_t,
                        dist_v, noise, out['op'], out['mv_true'], out['pv'])
        k = k1
        if progress is not None:
            progress(k, n)
    plant._x = x
    plant._hist = [float(hist[(hpos + i) % (m + 1)]) for i in range(m + 1)]
    plant.time, plant._last = float(ps[0]), float(ps[1])
    pid._i, pid._d, pid.op = float(pc[0]), float(pc[1]), float(pc[4])
    pid._pv_prev = float(pc[2]) if pc[3] > 0.5 else None


def write_csv(path: str | PathLike[str] | TextIO, data: Mapping[str, Floats],
              columns: Sequence[str] = COLUMNS, progress: Progress | None = None) -> None:
    """
    Write the named columns of a simulation result to CSV with a header row.

    Each value is written in the fewest digits that read back as the same
    float: an exact model must still fit with MSE 0, and a slip that falls
    on a stick band's edge must not move a sample when the file is read.
    The text is made a block of rows at a time, so that a long run needs no
    more memory for it than its arrays; a file is written beside its name and
    renamed at the end, so that a failed or interrupted write leaves no half
    file (and an earlier one whole).  ``progress(rows written, rows)``.
    """
    cols = [np.asarray(data[c], dtype=np.float64) for c in columns]
    n = len(cols[0]) if cols else 0
    if hasattr(path, 'write'):
        _write_rows(path, columns, cols, n, progress)
        return
    # Through a link to the file it names; never over a file the user may not write.
    target = os.path.realpath(os.fspath(path))
    if os.path.exists(target) and not os.access(target, os.W_OK):
        raise PermissionError(errno.EACCES, os.strerror(errno.EACCES), target)
    tmp = os.path.join(os.path.dirname(target),
                       f'.{os.path.basename(target)}.{secrets.token_hex(4)}.tmp')
    # Made as open() makes a file (0o666 less the umask), but only if new.
    fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666)
    try:
        with os.fdopen(fd, 'w', encoding='utf-8') as f:
            _write_rows(f, columns, cols, n, progress)
        if os.path.exists(target):
            # A file written over keeps its permissions, as open(..., 'w') would.
            os.chmod(tmp, os.stat(target).st_mode & 0o7777)
        os.replace(tmp, target)
    except BaseException:
        os.unlink(tmp)
        raise


def _write_rows(f: TextIO, columns: Sequence[str], cols: list[np.ndarray], n: int,
                progress: Progress | None, block: int = 65536) -> None:
    f.write(','.join(columns) + '\n')
    for start in range(0, n, block):
        rows = np.column_stack([c[start:start + block] for c in cols]).tolist()
        f.write(''.join(','.join(map(repr, row)) + '\n' for row in rows))
        if progress is not None:
            progress(min(start + block, n), n)
