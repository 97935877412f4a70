"""
One answer from a record that gaps cut into stretches.

A gap (a manual period, a lost connection, flagged samples) cuts a record
into stretches, and the detector reads each as a record of its own.  Their
readings are pooled as the length-weighted mean of their log-odds: each
stretch counts by the samples it holds, and the pooled odds are never
stronger than the strongest stretch's, since the stretches of one valve share
its tuning and its disturbances and are no independent evidence.  Summing
the log-odds, as for independent evidence, stated answers with more
confidence than they earned (docs/DETECTION_LOG.md, "A record cut by a
gap").
"""

from collections.abc import Sequence
import math

# Log-odds of a probability of exactly 0 or 1 are held at those of 1e-4 and
# 1 - 1e-4: the calibration's steps state nothing nearer certainty.
EDGE = 1e-4


def logit(p: float) -> float:
    """Return the log-odds of ``p``, held within those of ``EDGE`` and ``1 - EDGE``."""
    p = min(max(float(p), EDGE), 1.0 - EDGE)
    return math.log(p / (1.0 - p))


def pooled_probability(probabilities: Sequence[float], samples: Sequence[int]) -> float:
    """
    Return the probability of the length-weighted mean log-odds of the stretches.

    ``probabilities`` are the stretches' calibrated probabilities and
    ``samples`` their lengths; at least one stretch is needed.
    """
    if not probabilities or len(probabilities) != len(samples) or min(samples) <= 0:
        raise ValueError('pooled_probability needs one positive length per probability')
    total = float(sum(samples))
    mean = sum(n * logit(p) for p, n in zip(probabilities, samples)) / total
    return 1.0 / (1.0 + math.exp(-mean))
