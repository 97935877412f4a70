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

from concurrent.futures import ProcessPoolExecutor
import time

import numpy as np

from stiction_ros._threads import one_blas_thread
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


def _record(seed: int):
    from stiction_ros.analysis.detection.dataset import MIN_FOOTPRINT, stiction_footprint
    from stiction_ros.analysis.detection.resolve import judgeable
    from stiction_ros.sim.corpus import draw_scenario, simulate
    sc = draw_scenario(seed)
    rec = simulate(sc)
    if sc.label and stiction_footprint(sc, rec) < MIN_FOOTPRINT:
        return None
    if not judgeable(rec['op'], rec['pv'], sc.sample_time, rec['sp']).ok:
        return None
    return seed, channels(rec['op'], rec['pv'], rec['sp']), bool(sc.label), bool(sc.integrating)


def corpus(seeds, jobs: int = 2, say=print) -> dict:
    """Return the network inputs of ``seeds``: ``x`` (5, total) with record offsets ``off``."""
    t0, recs = time.perf_counter(), []
    with ProcessPoolExecutor(jobs, initializer=one_blas_thread) as pool:
        for i, r in enumerate(pool.map(_record, seeds, chunksize=64), 1):
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


def _network():
    import torch
    from torch import nn

    class Net(nn.Module):
        def __init__(self):
            super().__init__()
            self.inp = nn.Conv1d(N_CHANNELS, WIDTH, 7, padding=3)
            self.convs = nn.ModuleList([nn.Conv1d(WIDTH, WIDTH, 5, dilation=d, padding=2 * d)
                                        for d in DILATIONS])
            self.fc1 = nn.Linear(2 * WIDTH + 1, HIDDEN)
            self.fc2 = nn.Linear(HIDDEN, 1)

        def forward(self, x, integ):
            h = torch.relu(self.inp(x))
            for conv in self.convs:
                h = h + conv(torch.relu(h))
            pooled = torch.cat([h.mean(-1), h.amax(-1), integ[:, None]], 1)
            return self.fc2(torch.relu(self.fc1(pooled)))[:, 0]
    return Net()


def to_model(net, meta: dict) -> CnnModel:
    """Return the NumPy :class:`CnnModel` of a trained network."""
    sd = {k: v.detach().cpu().numpy().astype(np.float32) for k, v in net.state_dict().items()}
    n = len(DILATIONS)
    return CnnModel(sd['inp.weight'], sd['inp.bias'],
                    np.stack([sd[f'convs.{i}.weight'] for i in range(n)]),
                    np.stack([sd[f'convs.{i}.bias'] for i in range(n)]),
                    np.array(DILATIONS, dtype=np.int32), sd['fc1.weight'], sd['fc1.bias'],
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
              batch: int = BATCH, device: str | None = None):
    """
    Return the trained torch network and its figures.

    Adam under a one-cycle learning rate (peak ``PEAK_LR``), binary
    cross-entropy with the sticky class weighted to balance, random windows
    of ``CROP`` samples, ``batch`` records a step.  The corpus is copied to
    ``device`` once (default: a CUDA GPU if there is one) and the windows
    are cut there.  ``check``: a held-out set whose balanced accuracy is
    reported after each epoch (reported only; nothing is chosen on it).
    """
    import torch
    from torch import nn
    torch.manual_seed(SEED)
    rng = np.random.default_rng(SEED)
    dev = _device(device)
    net = _network().to(dev)
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
    sched = torch.optim.lr_scheduler.OneCycleLR(opt, PEAK_LR, total_steps=steps)
    lossf = nn.BCEWithLogitsLoss(
        pos_weight=torch.tensor((~y).sum() / max(y.sum(), 1), device=dev))
    t0, history = time.perf_counter(), []
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
            line += f', held-out balanced accuracy {ba:.4f}'
        say(f'{line} ({time.perf_counter() - t0:.0f} s)')
    return net, {'epochs': epochs, 'batch': batch, 'peak_lr': PEAK_LR,
                 'train_s': round(time.perf_counter() - t0, 1),
                 'check_balanced_accuracy': history, 'torch': torch.__version__,
                 'device': (torch.cuda.get_device_name(dev) if dev.type == 'cuda'
                            else f'cpu, {torch.get_num_threads()} threads')}


def export_error(net, model: CnnModel, data: dict, count: int = 50) -> float:
    """Return the largest |torch - NumPy| logit over the first ``count`` records of ``data``."""
    sub = {**data, 'y': data['y'][:count]}
    ref = _logits(net, sub)
    got = [model.logit(data['x'][:, data['off'][i]:data['off'][i + 1]], bool(data['integ'][i]))
           for i in range(len(ref))]
    return float(np.max(np.abs(ref - np.array(got))))
