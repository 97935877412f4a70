"""
How much of a reference MSE a fit removes, counting only what lies above MV's noise.

No model removes a position reading's own noise, so the plain share of an
ideal valve's MSE that a fit removes shrinks as the reading gets noisier,
whatever the valve does: at 2 % noise a fit that explains every slip of a
sticking valve removes a fifth of that MSE.  The share of the excess above
the noise does not shrink so.  It means something only where that excess is
larger than the error of the noise estimate itself (``ROOM``), and where the
fit does not fall below the noise by more than that error: no model fits
under a reading's white noise, so an estimate above the fit's MSE is too high
(MV's own moves in its sample-to-sample changes), and the share would pass 1.
"""

import math

# The noise variance comes from n samples' changes (a MAD, :func:`pipeline.mv_noise_var`):
# its relative standard error is about sqrt(2 / n) for white noise and more for a MAD, so
# an excess under ROOM / sqrt(n) of the reference (3 standard errors at 2.33 times the
# white-noise one) cannot be told from an error in the noise.
ROOM = 3.0 * 2.33


def share_above_noise(mse: float, reference: float | None, noise: float | None,
                      samples: int | None) -> float | None:
    """
    Return the share of ``reference``'s MSE above the noise that ``mse`` removes.

    Parameters
    ----------
    mse : float
        The fit's MSE.
    reference : float or None
        The MSE of the model it is judged against (an ideal valve, a valve
        without friction).
    noise : float or None
        MV's white-noise variance.
    samples : int or None
        The samples both MSEs were scored on.

    Returns
    -------
    float or None
        ``(reference - mse) / (reference - noise)``; None where any input is
        unknown, or ``reference - noise`` or ``noise - mse`` is within (or
        past) ``ROOM / sqrt(samples)`` of ``reference``.

    """
    if not (reference and noise and samples and samples > 0):
        return None
    room, error = reference - noise, _error(reference, samples)
    if room <= error or mse < noise - error:
        return None
    return (reference - mse) / room


def below_noise(mse: float, reference: float | None, noise: float, samples: int | None) -> bool:
    """
    Return whether a fit comes under MV's noise estimate by more than that estimate's error.

    No model fits under a reading's white noise, so the estimate is then too
    high: MV's own moves between samples are in its sample-to-sample changes.
    """
    if not (reference and samples):
        return False
    return mse < noise - _error(reference, samples)


def _error(reference: float, samples: int) -> float:
    # The noise estimate's error, in the reference's units (ROOM says why).
    return ROOM / math.sqrt(samples) * reference
