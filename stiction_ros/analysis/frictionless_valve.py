"""
What the best valve without friction (``fits[].frictionless``) can stand for.

Its calibration must be one a working position reading can have
(:func:`plausible`), and the report names its stages (:func:`chain_words`).
"""

# The calibration a position reading can have (gain; error at mid-span, % of span) and
# still be read as working: a frictionless valve that needs more explains nothing.
CALIBRATION_GAIN = (0.8, 1.25)
CALIBRATION_OFFSET = 10.0


def chain_words(chain: dict) -> str:
    """Return the stages of a frictionless valve (``fits[].frictionless``) in words."""
    words = []
    if chain['dead_time_s'] > 0.0:
        words.append(f'dead time {chain["dead_time_s"]:.3g} s')
    if chain['lag_s'] > 0.0:
        words.append(f'lag {chain["lag_s"]:.3g} s')
    if abs(chain['offset']) >= 0.1 or abs(chain['gain'] - 1.0) >= 0.005:
        words.append(f'MV = {chain["offset"]:.2f} + {chain["gain"]:.3f} x OP')
    if chain.get('rate_pct_s') is not None:
        words.append(f'rate limit {chain["rate_pct_s"]:.3g} %/s')
    for name, key in (('low', 'stop_low'), ('high', 'stop_high')):
        if chain.get(key) is not None:
            words.append(f'{name} travel stop at {chain[key]:.3g} %')
    return ', '.join(words) or 'MV = OP'


def plausible(chain: dict) -> bool:
    """
    Return whether a frictionless valve's calibration is one a reading can have.

    A gain outside ``CALIBRATION_GAIN``, or a reading off by more than
    ``CALIBRATION_OFFSET`` at mid-span, is a positioner fault, and a chain
    that needs one to fit is imitating something else (a limit cycle sampled
    too coarsely, friction): no explanation without friction.
    """
    lo, hi = CALIBRATION_GAIN
    mid = chain['offset'] + (chain['gain'] - 1.0) * 50.0
    return lo <= chain['gain'] <= hi and abs(mid) <= CALIBRATION_OFFSET
