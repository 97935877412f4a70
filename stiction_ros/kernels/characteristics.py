"""
Valve input/output conversions: the 4-20 mA look-up and flow characteristics.

The characteristic maps stem position (% of travel) to % of full flow.  The
equal-percentage curve uses the form that closes tight at 0 %,
``100 (R^(x/100) - 1) / (R - 1)``, rather than ISA's ``R^(x/100 - 1)``,
which leaks ``1/R`` of full flow when shut.
"""

import math

CHARACTERISTICS = ('linear', 'equal_percentage', 'square_root')
UNITS = ('percent', 'mA')


def ma_to_percent(ma: float) -> float:
    """Convert a 4-20 mA signal to % of span (4 mA = 0 %, 20 mA = 100 %)."""
    return (ma - 4.0) * 6.25


def percent_to_ma(pct: float) -> float:
    """Convert % of span to a 4-20 mA signal."""
    return 4.0 + pct * 0.16


def characteristic_code(name: str) -> int:
    """Return the integer code the kernels use for a characteristic name."""
    return CHARACTERISTICS.index(name)


def apply_characteristic(code: int, x: float, rangeability: float) -> float:
    """Map stem position ``x`` (%) to flow (%) for characteristic ``code``."""
    if code == 0:
        return x
    if code == 1:
        return 100.0 * (rangeability ** (x / 100.0) - 1.0) / (rangeability - 1.0)
    return 10.0 * math.sqrt(max(x, 0.0))


def invert_characteristic(code: int, f: float, rangeability: float) -> float:
    """Return the stem position (%) that gives flow ``f`` (%)."""
    if code == 0:
        return f
    if code == 1:
        return 100.0 * math.log1p(f / 100.0 * (rangeability - 1.0)) / math.log(rangeability)
    return (max(f, 0.0) / 10.0) ** 2
