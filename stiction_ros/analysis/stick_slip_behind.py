"""
Stick-slip read through the timing and calibration of the position reading.

The plain valve fits compare MV with OP sample for sample.  A reading that
follows the valve late (a transmitter or historian dead time) or off in
offset and gain hides a sticking valve from them: the fit then needs a band
without a slip jump (a dead time looks like play) or removes under half of
an ideal valve's MSE (an offset is in both), and the verdict could not tell.
The best valve without friction (:mod:`.without_friction`) has already
measured that dead time and a first calibration.  Here stick-slip is fitted
again behind them::

    OP -> dead time d -> stick-slip (S, J) -> offset + gain * position -> MV

with ``d`` the frictionless valve's, MV read back through its calibration
before the fit (a friction the frictionless valve has to imitate leaves its
gain low and offset large, but near enough to start from), and the
calibration solved again in closed form on the fitted position.  That
second calibration is the one judged against what a working reading can
have (:func:`.verdict.plausible`).  The lag is left out: a lag smooths the
slips this fit looks for, and a sticking valve behind one is ``--explain``'s
question.  The verdict weighs the result against the frictionless valve
itself (:func:`.verdict.from_fits`).
"""

import numpy as np

from stiction_ros.analysis.caution import slips
from stiction_ros.analysis.frictionless_valve import plausible
from stiction_ros.analysis.identify import confidence_box, identify, ValveProblem
from stiction_ros.analysis.without_friction import calibrated, indices, shift
from stiction_ros.errors import IdentifyError


def fit_behind(op: np.ndarray, mv: np.ndarray, segments, sample_time: float,
               chain: dict, model: str, beat: float = np.inf) -> dict | None:
    """
    Return the fit of ``model`` behind the dead time and calibration of ``chain``.

    Parameters
    ----------
    op, mv : numpy.ndarray
        The record's controller output and measured valve position (%).
    segments : list of (int, int)
        The runs the valve fits read.
    sample_time : float
        Seconds per sample.
    chain : dict
        The best valve without friction
        (:func:`.without_friction.fit_without_friction`).
    model : str
        ``'kano'`` or ``'choudhury'``.
    beat : float
        The MSE (MV's units) the refit must come under for its 95 % ranges
        to be worth their cost; above it they are not computed.

    Returns
    -------
    dict or None
        ``model``, ``S``, ``J``, their 95 % ranges ``S_interval`` and
        ``J_interval`` (% of the valve's own travel, holding the dead time
        and calibration fixed; None where the refit does not beat ``beat``),
        ``mse`` (MV's units, after the calibration), ``offset`` and ``gain``
        (MV = offset + gain x position), ``dead_time_s``, ``slips``
        (:func:`.caution.slips` of the refit's valve) and ``plausible``
        (whether that calibration is one a working reading has); None where
        the chain's gain leaves no position to read back (zero or not
        finite), or no valve can be identified behind the dead time (OP flat
        there).

    """
    gain = chain['gain']
    if not np.isfinite(gain) or abs(gain) < 1e-6:
        return None
    op = shift(np.clip(np.asarray(op, dtype=np.float64), 0.0, 100.0),
               chain['dead_time_s'] / sample_time, segments)
    mv = np.asarray(mv, dtype=np.float64)
    position = (mv - chain['offset']) / gain
    try:
        fit = identify(op, position, model, segments, sample_time, interval=False)
    except IdentifyError:
        # The plain fits stand; nothing behind the dead time can be read.
        return None
    problem = ValveProblem(model, op, position, segments, None, sample_time)
    out = problem.output(fit.S, fit.J)
    idx = indices(segments)
    if not np.all(np.isfinite(out[idx])):
        return None
    offset, g, sse = calibrated(out, mv, idx)
    s_range = j_range = None
    if sse / len(idx) <= beat:
        s_range, j_range = (list(r) for r in confidence_box(problem, fit.S, fit.J, fit.mse))
    return {'model': model, 'S': fit.S, 'J': fit.J, 'S_interval': s_range,
            'J_interval': j_range, 'mse': sse / len(idx), 'offset': offset, 'gain': g,
            'dead_time_s': chain['dead_time_s'], 'slips': slips(out, segments),
            'plausible': plausible({'offset': offset, 'gain': g})}
