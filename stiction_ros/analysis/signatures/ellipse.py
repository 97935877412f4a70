"""
Apparent stiction from an ellipse fitted to the filtered PV-OP map.

Choudhury, M.A.A.S., Shah, S.L., Thornhill, N.F., Shook, D.S. (2006),
Automatic detection and quantification of stiction in control valves,
Control Engineering Practice 14(12), 1395-1412; and Choudhury, Shah and
Thornhill, Diagnosis of Process Nonlinearities and Valve Stiction, Springer
(2008).  Ellipse fit: Fitzgibbon, A., Pilu, M., Fisher, R.B. (1999), Direct
least square fitting of ellipses, IEEE Trans. PAMI 21(5), 476-480, in the
numerically stable form of Halir, R., Flusser, J. (1998), Numerically stable
direct least squares fitting of ellipses, WSCG'98.

PV and OP are detrended and band-passed in the frequency domain to
[0.5, 1.5] times the oscillation frequency (components outside set to zero;
the paper uses a Wiener filter over a band around the oscillation; keeping
the fundamental only makes the map an ellipse whose width is the phase
hysteresis between OP and PV).  For an integrating process the first
difference of PV (a stand-in for the flow through the valve) is used
instead of PV, so the integrator's 90 degree lag is not read as stiction.
An ellipse ``(p - c)' Q (p - c) = 1`` is fitted by direct least squares on
standardised coordinates and mapped back.  The apparent stiction is its
width along the OP axis through the centre, i.e. its maximum width in the OP
direction, ``2 m n / sqrt(m^2 sin^2 a + n^2 cos^2 a)`` for semi-axes m, n and
angle a (the paper's formula), in % of OP.

Significance (our choice, not the paper's): the width must reach 10 % of
the ellipse's OP extent.  For sines ``OP = A cos t``, ``PV = B cos(t - phi)``
the ratio is ``|sin phi|``, so 10 % is a phase of about 6 degrees from
in-phase or anti-phase, below which sampling, noise and the fit's own
error can make a line look like a thin ellipse.  A significant width alone
is not stiction (a linear loop also has a phase lag); below it the map shows
no hysteresis, so the signature returns stiction=False, and otherwise None
(decided with a nonlinearity test, see ``bicoherence.hos_with_pv_op``).
"""

import math

import numpy as np

from stiction_ros.analysis.oscillation import bandpass, detect_oscillation
from stiction_ros.analysis.signatures.result import Signature

REFERENCE = ('Choudhury, M.A.A.S., Shah, S.L., Thornhill, N.F., Shook, D.S. (2006), Automatic '
             'detection and quantification of stiction in control valves, Control Engineering '
             'Practice 14, 1395-1412')
RELATIVE_WIDTH = 0.1
BAND = (0.5, 1.5)
MAX_RESIDUAL = 0.25
LINE_CORRELATION = 0.999


def no_ellipse(sig: Signature) -> bool:
    """Return whether the PV-OP map of an :func:`ellipse` result fitted no ellipse (no size)."""
    return sig.details.get('fit_residual', 0.0) > MAX_RESIDUAL


def fit_ellipse(x, y):
    """
    Return the conic ``[a, b, c, d, e, f]`` of the direct least-squares ellipse through (x, y).

    ``a x^2 + b x y + c y^2 + d x + e y + f = 0`` with ``4 a c - b^2 > 0``
    (Halir and Flusser's partition of Fitzgibbon's eigenproblem).
    Raises ValueError when no ellipse fits (e.g. collinear points).
    """
    x = np.asarray(x, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    quad = np.column_stack([x * x, x * y, y * y])
    lin = np.column_stack([x, y, np.ones_like(x)])
    s1, s2, s3 = quad.T @ quad, quad.T @ lin, lin.T @ lin
    try:
        t = -np.linalg.solve(s3, s2.T)
    except np.linalg.LinAlgError:
        raise ValueError('points are degenerate (collinear or too few)') from None
    m = s1 + s2 @ t
    # Premultiply by the inverse of the constraint matrix [[0, 0, 2], [0, -1, 0], [2, 0, 0]].
    m = np.vstack([m[2] / 2.0, -m[1], m[0] / 2.0])
    vals, vecs = np.linalg.eig(m)
    vecs = np.real(vecs)
    cond = 4.0 * vecs[0] * vecs[2] - vecs[1] ** 2
    ok = np.flatnonzero(cond > 0)
    if len(ok) == 0:
        raise ValueError('no ellipse fits these points')
    a1 = vecs[:, ok[0]]
    return np.concatenate([a1, t @ a1])


def conic_to_matrix(conic):
    """Return (centre, Q) with the ellipse ``(p - centre)' Q (p - centre) = 1``."""
    a, b, c, d, e, f = conic
    quad = np.array([[a, b / 2.0], [b / 2.0, c]])
    centre = np.linalg.solve(quad, -0.5 * np.array([d, e]))
    k = centre @ quad @ centre - f
    return centre, quad / k


def fit_ellipse_scaled(x, y):
    """Return (centre, Q) of the ellipse fitted to (x, y) after standardising each axis."""
    mx, my, sx, sy = x.mean(), y.mean(), x.std(), y.std()
    if sx == 0 or sy == 0:
        raise ValueError('one of the signals is constant')
    centre_n, q_n = conic_to_matrix(fit_ellipse((x - mx) / sx, (y - my) / sy))
    scale = np.diag([1.0 / sx, 1.0 / sy])
    return np.array([mx, my]) + np.array([sx, sy]) * centre_n, scale @ q_n @ scale


def geometry(q):
    """Return (semi_major, semi_minor, angle_rad of the major axis from the OP axis)."""
    vals, vecs = np.linalg.eigh(q)
    semi = 1.0 / np.sqrt(vals)
    angle = math.atan2(vecs[1, 0], vecs[0, 0])
    return float(semi[0]), float(semi[1]), float(angle)


def ellipse(op, pv, sample_time, period_s=None, integrating=False):
    """Return the apparent-stiction signature: the PV-OP ellipse's width along OP (%)."""
    op = np.asarray(op, dtype=np.float64)
    pv = np.asarray(pv, dtype=np.float64)
    if integrating:
        pv = np.gradient(pv, sample_time)
    if period_s is None:
        osc = detect_oscillation(op, sample_time)
        if not osc.oscillating:
            return Signature('ellipse', None, None, None, f'no regular oscillation in OP: '
                             f'{osc.reason}', REFERENCE)
        period_s = osc.period_s
    f0 = 1.0 / period_s
    # The means go back on so the figure overlays the raw map's operating point.
    u = bandpass(op, sample_time, BAND[0] * f0, BAND[1] * f0) + op.mean()
    y = bandpass(pv, sample_time, BAND[0] * f0, BAND[1] * f0) + pv.mean()
    details = {'band_hz_low': BAND[0] * f0, 'band_hz_high': BAND[1] * f0,
               'pv_signal': 'dPV/dt' if integrating else 'PV'}
    curves = {'op_filtered': u, 'pv_filtered': y}
    if u.std() > 0 and y.std() > 0 and abs(np.corrcoef(u, y)[0, 1]) > LINE_CORRELATION:
        # An ellipse fit to a line is degenerate; its width is zero.
        threshold = RELATIVE_WIDTH * 2.0 * math.sqrt(2.0) * float(u.std())
        return Signature('ellipse', 0.0, threshold, False, 'PV-OP map is a straight line: '
                         'no hysteresis', REFERENCE, details, curves)
    try:
        centre, q = fit_ellipse_scaled(u, y)
        major, minor, angle = geometry(q)
    except (ValueError, np.linalg.LinAlgError) as err:
        return Signature('ellipse', None, None, None, f'no ellipse fits the PV-OP map: {err}',
                         REFERENCE, details, curves)
    width = 2.0 / math.sqrt(q[0, 0])
    extent = 2.0 * math.sqrt(np.linalg.inv(q)[0, 0])
    p = np.column_stack([u, y]) - centre
    radius = np.sqrt(np.einsum('ni,ij,nj->n', p, q, p))
    residual = float(np.sqrt(np.mean((radius - 1.0) ** 2)))
    threshold = RELATIVE_WIDTH * extent
    details.update(semi_major=major, semi_minor=minor, angle_deg=math.degrees(angle),
                   centre_op=float(centre[0]), centre_pv=float(centre[1]),
                   op_extent=extent, relative_width=width / extent, fit_residual=residual)
    t = np.linspace(0, 2 * np.pi, 200)
    vals, vecs = np.linalg.eigh(q)
    ring = centre[:, None] + vecs @ (np.vstack([np.cos(t), np.sin(t)]) / np.sqrt(vals)[:, None])
    curves.update(ellipse_op=ring[0], ellipse_pv=ring[1], centre=centre, width=width)
    if residual > MAX_RESIDUAL:
        verdict, reason = None, (f'PV-OP map is not an ellipse (radial residual '
                                 f'{residual:.2f} > {MAX_RESIDUAL})')
    elif width < threshold:
        verdict, reason = False, (f'thin PV-OP map: width {width:.3g} % < {threshold:.3g} % '
                                  f'({RELATIVE_WIDTH:.0%} of the OP extent)')
    else:
        verdict, reason = None, (f'apparent stiction {width:.3g} % of OP (>= {threshold:.3g} %); '
                                 'stiction only if the loop is nonlinear')
    return Signature('ellipse', width, threshold, verdict, reason, REFERENCE, details, curves)
