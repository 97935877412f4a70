"""First-order lags used in front of the friction logic (air chamber, EWMA)."""

import math


def first_order_pole(tau: float, sample_time: float) -> float:
    """
    Return the exact zero-order-hold pole ``exp(-Ts/tau)`` of ``1/(tau s + 1)``.

    ``tau = 0`` means no lag (pole 0: the output equals the input).
    """
    if tau <= 0.0:
        return 0.0
    return math.exp(-sample_time / tau)
