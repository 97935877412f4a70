"""
Where the plain model's residual sits: in time, and by regime.

Each sample gets regime labels from the plain model's own state (stuck or
moving) and from OP (opening or closing), plus its valve-position third and
its time third.  A regime's ``residual_share`` is its part of the total
squared residual; ``lift`` divides that by its part of the samples, so a
lift well above 1 says the model is wrong *there*.  Regions are stretches of
time whose smoothed squared residual stands well above the record's median,
each named by the regime that carries most of its residual.
"""

import numpy as np

from stiction_ros.analysis.record import runs

REGION_FACTOR = 4.0


def regime_labels(op, mv_model, resting):
    """Return {name: boolean mask} of the regimes every sample belongs to."""
    dop = np.diff(op, prepend=op[0])
    opening = dop > 0
    thirds = np.nanpercentile(mv_model, [33.3, 66.7])
    return {
        'stuck': resting > 0.5, 'moving': resting <= 0.5,
        'opening': opening, 'closing': dop < 0,
        'stuck, opening': (resting > 0.5) & opening,
        'stuck, closing': (resting > 0.5) & (dop < 0),
        'moving, opening': (resting <= 0.5) & opening,
        'moving, closing': (resting <= 0.5) & (dop < 0),
        'low position': mv_model <= thirds[0],
        'mid position': (mv_model > thirds[0]) & (mv_model <= thirds[1]),
        'high position': mv_model > thirds[1],
    }


def regime_shares(residual, labels, mask):
    """Return [{regime, residual_share, sample_share, lift}] sorted by lift, on ``mask``."""
    r2 = np.where(mask, residual, 0.0) ** 2
    total = float(np.sum(r2))
    n = int(np.sum(mask))
    out = []
    for name, m in labels.items():
        m = m & mask
        share = float(np.sum(r2[m]) / total) if total > 0 else 0.0
        frac = float(np.sum(m) / n) if n else 0.0
        out.append({'regime': name, 'residual_share': round(share, 4),
                    'sample_share': round(frac, 4),
                    'lift': round(share / frac, 3) if frac > 0 else 0.0})
    return sorted(out, key=lambda x: -x['lift'])


def time_thirds(n, mask):
    """Return {name: mask} of the first, middle and last third of the samples in ``mask``."""
    idx = np.flatnonzero(mask)
    cuts = np.array_split(idx, 3) if len(idx) >= 3 else [idx]
    out = {}
    for name, part in zip(('early', 'middle', 'late'), cuts):
        m = np.zeros(n, dtype=bool)
        m[part] = True
        out[name] = m
    return out


def regions(t, residual, labels, mask, window=None, factor=REGION_FACTOR, most=8):
    """Return the time stretches where the residual concentrates, strongest first."""
    n = len(residual)
    r2 = np.where(mask & np.isfinite(residual), residual, 0.0) ** 2
    total = float(np.sum(r2))
    if total <= 0.0:
        return []
    w = window or max(5, n // 100)
    smooth = np.convolve(r2, np.ones(w) / w, mode='same')
    level = float(np.median(smooth[mask])) if np.any(mask) else 0.0
    hot = mask & (smooth > factor * max(level, 1e-300))
    out = []
    for a, b in runs(hot):
        share = float(np.sum(r2[a:b]) / total)
        local = {name: float(np.sum(r2[a:b][m[a:b]])) for name, m in labels.items()
                 if ',' in name}
        regime = max(local, key=local.get) if local else 'unknown'
        out.append({'t_start': float(t[a]), 't_end': float(t[b - 1]), 'regime': regime,
                    'residual_share': round(share, 4)})
    return sorted(out, key=lambda x: -x['residual_share'])[:most]


def breakaways(t, op, mv, mv_model, resting, sample_time, after=5):
    """
    Return one row per breakaway of the plain model.

    Each row: time, direction, rest time before it, position, and the mean
    residual (measured - model) over the ``after`` samples that follow: how
    far the real valve was from the model's breakaway.
    """
    rows = []
    rest_since = 0
    for k in range(1, len(resting)):
        if resting[k] > 0.5 and resting[k - 1] <= 0.5:
            rest_since = k
        # Outside the valid segments the model is NaN and its resting flag 0: the end of
        # a segment that stopped at rest is no breakaway.
        if resting[k - 1] > 0.5 and resting[k] <= 0.5 and np.isfinite(mv_model[k]):
            seg = slice(k, min(len(mv), k + after))
            diff = mv[seg] - mv_model[seg]
            diff = diff[np.isfinite(diff)]
            err = float(np.mean(diff)) if len(diff) else float('nan')
            rows.append({'t': float(t[k]), 'direction': 'opening' if op[k] > op[k - 1]
                         else 'closing', 'rest_s': float((k - rest_since) * sample_time),
                         'position': float(mv_model[k - 1]), 'residual': err})
    return rows
