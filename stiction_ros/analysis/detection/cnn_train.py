"""
Train the detector's 1-D CNN (:mod:`cnn`) on simulated loops and export it as arrays.

Only ``make cnn`` imports this module: it needs PyTorch, which neither the
analyzer nor the tests do.  It trains on a CUDA GPU when PyTorch sees one
and on the CPU otherwise; the NumPy export reads the same either way.  The
corpus is drawn like the detector's training set (``stiction_ros.sim.corpus``)
from its own seed range, which the boosted trees' training, calibration and
scoring sets never touch, so the network's logit on those sets is an honest
out-of-sample figure.
Records left out of the detector's sets (hidden stiction, not judgeable)
are left out here too.
"""

from dataclasses import asdict, dataclass
from functools import partial
from pathlib import Path
import time

import numpy as np

from stiction_ros._threads import worker_pool
from stiction_ros.analysis.detection.cnn import channels, CnnModel, N_CHANNELS

CORPUS = range(2_000_000, 2_040_000)
WIDTH = 32
DILATIONS = (1, 2, 4, 8, 16, 32, 64)
HIDDEN = 32
EPOCHS = 10
CROP = 500
BATCH = 64
PEAK_LR = 2e-3
SEED = 0
# Training records read whole after each epoch, beside the check set.
SEEN_RECORDS = 2000


@dataclass(frozen=True)
class Arch:
    """The network's shape: channels, hidden units and the dilation of each residual layer."""

    width: int = WIDTH
    hidden: int = HIDDEN
    dilations: tuple = DILATIONS

    def __post_init__(self):
        if self.width < 1 or self.hidden < 1 or not self.dilations:
            raise ValueError(f'a network needs channels, hidden units and layers: {self}')
        if any(int(d) < 1 for d in self.dilations):
            raise ValueError(f'dilations must be 1 or more: {self.dilations}')

    def to_json(self) -> dict:
        """Return the shape as plain JSON types (the weights file's header keeps it)."""
        return {**asdict(self), 'dilations': [int(d) for d in self.dilations]}


ARCH = Arch()


def _record(seed: int, without_deadband_like: bool = False, healthy_only: bool = False):
    from stiction_ros.analysis.detection.dataset import MIN_FOOTPRINT, stiction_footprint
    from stiction_ros.analysis.detection.resolve import judgeable
    from stiction_ros.sim.corpus import draw_scenario, simulate
    sc = draw_scenario(seed)
    if healthy_only and sc.label:
        return None
    rec = simulate(sc)
    if sc.label and stiction_footprint(sc, rec) < MIN_FOOTPRINT:
        return None
    if not judgeable(rec['op'], rec['pv'], sc.sample_time, rec['sp']).ok:
        return None
    if sc.label and without_deadband_like:
        # Checked last: 27 deadband runs, the dearest test, on judged records only.
        from stiction_ros.analysis.detection.deadband_like import slip_footprint
        if slip_footprint(sc, rec) < MIN_FOOTPRINT:
            return None
    return seed, channels(rec['op'], rec['pv'], rec['sp']), bool(sc.label), bool(sc.integrating)


def corpus(seeds, jobs: int = 2, say=print, without_deadband_like: bool = False,
           healthy_only: bool = False) -> dict:
    """
    Return the network inputs of ``seeds``: ``x`` (5, total) with record offsets ``off``.

    ``without_deadband_like``: leave out the sticky records whose slip moves
    PV by less than its noise against the nearest deadband, as the detector's
    scoring and calibration do (:mod:`deadband_like`).  ``healthy_only``:
    leave out every sticky record (before it is simulated), for
    :func:`hard_negatives`.
    """
    t0, recs = time.perf_counter(), []
    draw = partial(_record, without_deadband_like=without_deadband_like,
                   healthy_only=healthy_only)
    with worker_pool(jobs) as pool:
        for i, r in enumerate(pool.map(draw, seeds, chunksize=64), 1):
            if r is not None:
                recs.append(r)
            if i % 5000 == 0 or i == len(seeds):
                say(f'  corpus: {i}/{len(seeds)} seeds, {len(recs)} records '
                    f'({time.perf_counter() - t0:.0f} s)')
    # Training cuts windows of CROP samples; the corpus never draws fewer
    # than 500, but a shorter record would have no window to cut.
    short = sum(r[1].shape[1] < CROP for r in recs)
    recs = [r for r in recs if r[1].shape[1] >= CROP]
    if short:
        say(f'  corpus: {short} records shorter than {CROP} samples left out')
    if not recs:
        raise ValueError(f'no record of seeds {seeds[0]}-{seeds[-1]} can be learned from')
    lengths = np.array([r[1].shape[1] for r in recs])
    return {'seed': np.array([r[0] for r in recs]),
            'x': np.concatenate([r[1] for r in recs], axis=1),
            'off': np.concatenate([[0], np.cumsum(lengths)]),
            'y': np.array([r[2] for r in recs]), 'integ': np.array([r[3] for r in recs])}


def take(data: dict, keep: np.ndarray) -> dict:
    """Return the records of corpus ``data`` where the boolean ``keep`` is true."""
    idx = np.flatnonzero(keep)
    off = data['off']
    parts = [data['x'][:, off[i]:off[i + 1]] for i in idx]
    lengths = np.array([p.shape[1] for p in parts], dtype=np.int64)
    return {'seed': data['seed'][idx],
            'x': (np.concatenate(parts, axis=1) if parts
                  else np.empty((data['x'].shape[0], 0), dtype=data['x'].dtype)),
            'off': np.concatenate([[0], np.cumsum(lengths)]).astype(off.dtype),
            'y': data['y'][idx], 'integ': data['integ'][idx]}


def join(a: dict, b: dict) -> dict:
    """Return corpus ``a`` followed by corpus ``b``."""
    return {'seed': np.concatenate([a['seed'], b['seed']]),
            'x': np.concatenate([a['x'], b['x']], axis=1),
            'off': np.concatenate([a['off'], a['off'][-1] + b['off'][1:]]),
            'y': np.concatenate([a['y'], b['y']]),
            'integ': np.concatenate([a['integ'], b['integ']])}


def hard_negatives(data: dict, net: CnnModel, threshold: float = 0.0, say=print) -> dict:
    """
    Return the healthy records of ``data`` that ``net`` calls sticky (logit above ``threshold``).

    The whole record is read once, its signs as recorded (NumPy, no
    PyTorch).  Added to a corpus, they are the look-alikes (backlash,
    sluggish loops under load steps, quantised valves) the starting network
    gets wrong, which a corpus drawn as every other one holds few of.
    """
    t0, off = time.perf_counter(), data['off']
    z = np.full(len(data['y']), -np.inf)
    for i in np.flatnonzero(~data['y']):
        z[i] = net.logit(data['x'][:, off[i]:off[i + 1]], bool(data['integ'][i]))
        if (i + 1) % 5000 == 0:
            say(f'  hard negatives: {i + 1}/{len(z)} records read '
                f'({time.perf_counter() - t0:.0f} s)')
    out = take(data, z > threshold)
    say(f'  hard negatives: {len(out["y"])} of {int((~data["y"]).sum())} healthy records '
        f'read as sticky ({time.perf_counter() - t0:.0f} s)')
    return out


def corpus_file(seeds, path: str | Path, jobs: int = 2, say=print,
                without_deadband_like: bool = False) -> dict:
    """
    Return :func:`corpus` of ``seeds``: read from ``path`` if it holds them, else kept there.

    One simulated corpus then serves several trainings (network shapes
    compared on the same records, one GPU lease).  A file of other seeds
    is an error, not silently replaced.
    """
    path = Path(path)
    want = np.array([seeds[0], seeds[-1] + 1, len(seeds)] + [1] * without_deadband_like,
                    dtype=np.int64)
    if path.exists():
        with np.load(path) as f:
            got = f['seeds'] if 'seeds' in f.files else None
            if got is None or not np.array_equal(got, want):
                raise ValueError(f'{path} holds another corpus than seeds {seeds[0]}-{seeds[-1]}'
                                 f'{" without deadband-like records" * without_deadband_like}; '
                                 'remove it or name another file')
            data = {k: f[k] for k in ('seed', 'x', 'off', 'y', 'integ')}
        say(f'  corpus: {len(data["y"])} records read from {path}')
        return data
    data = corpus(seeds, jobs, say, without_deadband_like)
    path.parent.mkdir(parents=True, exist_ok=True)
    part = path.with_name(path.name + '.part')
    with open(part, 'wb') as f:
        np.savez(f, seeds=want, **data)
    part.replace(path)
    return data


def _network(arch: Arch = ARCH):
    import torch
    from torch import nn

    class Net(nn.Module):
        def __init__(self):
            super().__init__()
            w = arch.width
            self.dilations = tuple(int(d) for d in arch.dilations)
            self.inp = nn.Conv1d(N_CHANNELS, w, 7, padding=3)
            self.convs = nn.ModuleList([nn.Conv1d(w, w, 5, dilation=d, padding=2 * d)
                                        for d in self.dilations])
            self.fc1 = nn.Linear(2 * w + 1, arch.hidden)
            self.fc2 = nn.Linear(arch.hidden, 1)

        def forward(self, x, integ):
            h = torch.relu(self.inp(x))
            for conv in self.convs:
                h = h + conv(torch.relu(h))
            pooled = torch.cat([h.mean(-1), h.amax(-1), integ[:, None]], 1)
            return self.fc2(torch.relu(self.fc1(pooled)))[:, 0]
    return Net()


def load_weights(net, model: CnnModel) -> None:
    """Copy the weights of ``model`` into the torch network ``net`` (:func:`to_model` undone)."""
    import torch
    shape = (tuple(int(d) for d in model.dilations), model.inp_w.shape, model.fc1_w.shape)
    if shape != (net.dilations, tuple(net.inp.weight.shape), tuple(net.fc1.weight.shape)):
        raise ValueError(f'the starting weights are of another network shape: dilations '
                         f'{list(shape[0])}, input {shape[1]}, hidden {shape[2]}')
    sd = {'inp.weight': model.inp_w, 'inp.bias': model.inp_b,
          'fc1.weight': model.fc1_w, 'fc1.bias': model.fc1_b,
          'fc2.weight': model.fc2_w, 'fc2.bias': model.fc2_b}
    for i in range(len(net.dilations)):
        sd[f'convs.{i}.weight'], sd[f'convs.{i}.bias'] = model.conv_w[i], model.conv_b[i]
    net.load_state_dict({k: torch.from_numpy(np.asarray(v, dtype=np.float32))
                         for k, v in sd.items()})


def to_model(net, meta: dict) -> CnnModel:
    """Return the NumPy :class:`CnnModel` of a trained network."""
    sd = {k: v.detach().cpu().numpy().astype(np.float32) for k, v in net.state_dict().items()}
    n = len(net.dilations)
    return CnnModel(sd['inp.weight'], sd['inp.bias'],
                    np.stack([sd[f'convs.{i}.weight'] for i in range(n)]),
                    np.stack([sd[f'convs.{i}.bias'] for i in range(n)]),
                    np.array(net.dilations, dtype=np.int32), sd['fc1.weight'], sd['fc1.bias'],
                    sd['fc2.weight'], sd['fc2.bias'], meta)


def _device(name: str | None = None):
    import torch
    if name:
        return torch.device(name)
    return torch.device('cuda' if torch.cuda.is_available() else 'cpu')


def _logits(net, data: dict) -> np.ndarray:
    import torch
    dev = next(net.parameters()).device
    out = np.zeros(len(data['y']))
    net.eval()
    with torch.no_grad():
        for i in range(len(out)):
            x = torch.from_numpy(data['x'][:, data['off'][i]:data['off'][i + 1]])[None]
            out[i] = net(x.to(dev), torch.tensor([float(data['integ'][i])], device=dev)).item()
    net.train()
    return out


def balanced_log_loss(logits: np.ndarray, y: np.ndarray) -> float:
    """Return the cross-entropy of ``logits`` with each class weighted half."""
    y = np.asarray(y, dtype=bool)
    z = np.asarray(logits, dtype=np.float64)
    return float(0.5 * np.logaddexp(0.0, -z[y]).mean() + 0.5 * np.logaddexp(0.0, z[~y]).mean())


def subset(data: dict, count: int) -> dict:
    """Return the first ``count`` records of a corpus."""
    off = data['off'][:count + 1]
    return {'seed': data['seed'][:count], 'x': data['x'][:, :off[-1]], 'off': off,
            'y': data['y'][:count], 'integ': data['integ'][:count]}


def cut_windows(xt, starts: np.ndarray, width: int = CROP):
    """
    Return the windows ``xt[:, s:s + width]`` for each start, shape (starts, channels, width).

    One gather on ``xt``'s device: the corpus stays there and only the
    starts travel each step.
    """
    import torch
    cols = torch.from_numpy(np.asarray(starts)).to(xt.device)[:, None] + torch.arange(
        width, device=xt.device)
    return xt[:, cols].permute(1, 0, 2)


def train_cnn(data: dict, check: dict | None = None, epochs: int = EPOCHS, say=print,
              batch: int = BATCH, device: str | None = None, arch: Arch = ARCH,
              init: CnnModel | None = None, peak_lr: float = PEAK_LR, on_epoch=None):
    """
    Return the trained torch network and its figures.

    Adam under a one-cycle learning rate (peak ``peak_lr``), binary
    cross-entropy with the sticky class weighted to balance, random windows
    of ``CROP`` samples, ``batch`` records a step.  The corpus is copied to
    ``device`` once (default: a CUDA GPU if there is one) and the windows
    are cut there.  ``check``: a held-out set whose balanced accuracy and
    loss are reported after each epoch (reported only; nothing is chosen on
    it).  ``arch``: the network's shape (default: the shipped networks').
    ``init``: start from these weights (a network of the same shape) rather
    than at random.  ``on_epoch(net, figures)``: called after each epoch
    with the figures so far (a checkpoint, so a run stopped by a time limit
    keeps the epochs it finished).
    """
    import torch
    from torch import nn
    torch.manual_seed(SEED)
    rng = np.random.default_rng(SEED)
    dev = _device(device)
    net = _network(arch)
    if init is not None:
        load_weights(net, init)
    net = net.to(dev)
    x, off, y, integ = data['x'], data['off'], data['y'], data['integ']
    n = len(y)
    if n < batch or y.all() or not y.any():
        raise ValueError(f'{n} records ({int(y.sum())} sticky): training needs at least '
                         f'{batch} records and both labels')
    xt = torch.from_numpy(np.ascontiguousarray(x, dtype=np.float32)).to(dev)
    yt = torch.from_numpy(y.astype(np.float32)).to(dev)
    it = torch.from_numpy(integ.astype(np.float32)).to(dev)
    opt = torch.optim.Adam(net.parameters(), 1e-3)
    steps = epochs * (n // batch)
    sched = torch.optim.lr_scheduler.OneCycleLR(opt, peak_lr, total_steps=steps)
    lossf = nn.BCEWithLogitsLoss(
        pos_weight=torch.tensor((~y).sum() / max(y.sum(), 1), device=dev))
    t0, history, losses = time.perf_counter(), [], []
    seen = subset(data, min(n, SEEN_RECORDS))

    def figures() -> dict:
        return {'epochs': epochs, 'batch': batch, 'peak_lr': peak_lr, 'arch': arch.to_json(),
                'train_s': round(time.perf_counter() - t0, 1),
                'check_balanced_accuracy': list(history), 'log_loss_seen_held_out': list(losses),
                'torch': torch.__version__,
                'device': (torch.cuda.get_device_name(dev) if dev.type == 'cuda'
                           else f'cpu, {torch.get_num_threads()} threads')}
    for epoch in range(epochs):
        perm, total = rng.permutation(n), 0.0
        for b in range(n // batch):
            idx = perm[b * batch:(b + 1) * batch]
            # One draw per record, in order, as the shipped network was trained.
            starts = np.array([off[i] + rng.integers(0, off[i + 1] - off[i] - CROP + 1)
                               for i in idx])
            xb = cut_windows(xt, starts)
            ib = torch.from_numpy(idx).to(dev)
            loss = lossf(net(xb, it[ib]), yt[ib])
            opt.zero_grad()
            loss.backward()
            nn.utils.clip_grad_norm_(net.parameters(), 1.0)
            opt.step()
            sched.step()
            total += loss.item()
        line = f'  epoch {epoch + 1}/{epochs}: loss {total / (n // batch):.4f}'
        if check is not None:
            lg = _logits(net, check)
            ba = 0.5 * ((lg[check['y']] > 0).mean() + (lg[~check['y']] <= 0).mean())
            history.append(round(float(ba), 4))
            # Whole records on both sides: a gap says the network learns its
            # corpus rather than stiction; none says more records will not help.
            losses.append([round(balanced_log_loss(_logits(net, seen), seen['y']), 4),
                           round(balanced_log_loss(lg, check['y']), 4)])
            line += (f', held-out balanced accuracy {ba:.4f}, whole-record log loss '
                     f'{losses[-1][0]:.4f} seen / {losses[-1][1]:.4f} held out')
        say(f'{line} ({time.perf_counter() - t0:.0f} s)')
        if on_epoch is not None:
            on_epoch(net, {**figures(), 'epochs_done': epoch + 1})
    return net, figures()


def export_error(net, model: CnnModel, data: dict, count: int = 50) -> float:
    """Return the largest |torch - NumPy| logit over the first ``count`` records of ``data``."""
    sub = {**data, 'y': data['y'][:count]}
    ref = _logits(net, sub)
    got = [model.logit(data['x'][:, data['off'][i]:data['off'][i + 1]], bool(data['integ'][i]))
           for i in range(len(ref))]
    return float(np.max(np.abs(ref - np.array(got))))
