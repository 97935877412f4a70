"""
The breakaway rule the two-parameter models share.

A stuck valve last moved in direction ``d`` (+1 opening, -1 closing, 0 = at
rest with no friction force stored) and stuck when its input was ``u_s``.
With ``rel = u - u_s`` it moves again the other way once ``-d rel > S``
(static friction plus the deadband of the reversal), on in the same direction
once ``d rel > J``, and from the neutral state once ``|rel| > (S + J)/2``.
"""

import math


def breakaway(d: float, rel: float, S: float, J: float) -> float:
    """Return the new direction of motion, or 0.0 if the valve stays stuck."""
    if d == 0.0:
        return math.copysign(1.0, rel) if abs(rel) > 0.5 * (S + J) else 0.0
    if -d * rel > S:
        return -d
    if d * rel > J:
        return d
    return 0.0
