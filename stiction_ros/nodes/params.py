"""
Parameter declaration the ROS way: every parameter with a full ``ParameterDescriptor``.

A :class:`Param` lists what ``ros2 param describe`` shows (description, range,
allowed values, read-only); :func:`declare` turns a list of them into
declared parameters.  Ranges are enforced by rclpy itself before the node's
on-set callback runs; allowed values and cross-checks are enforced there.
"""

from dataclasses import dataclass
import math
import sys

from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor
from rcl_interfaces.msg import ParameterType


@dataclass
class Param:
    """One node parameter: default value and what may be set."""

    name: str
    default: object
    description: str
    low: float = None
    high: float = None
    choices: tuple = None
    read_only: bool = False
    step: float = 0.0
    # What a free-form value must be (a string the node parses): shown by ``ros2 param
    # describe`` as the descriptor's additional_constraints.
    constraint: str = ''


_TYPES = {
    bool: ParameterType.PARAMETER_BOOL,
    int: ParameterType.PARAMETER_INTEGER,
    float: ParameterType.PARAMETER_DOUBLE,
    str: ParameterType.PARAMETER_STRING,
}


def _finite(x):
    return max(min(float(x), sys.float_info.max), -sys.float_info.max) if math.isinf(x) else x


def descriptor(p):
    """Return the ``ParameterDescriptor`` of a :class:`Param`."""
    d = ParameterDescriptor(name=p.name, description=p.description, read_only=p.read_only)
    if isinstance(p.default, (list, tuple)):
        d.type = (ParameterType.PARAMETER_STRING_ARRAY if p.default and isinstance(
            p.default[0], str) else ParameterType.PARAMETER_DOUBLE_ARRAY)
    else:
        d.type = _TYPES[type(p.default)]
    if p.low is not None and d.type == ParameterType.PARAMETER_DOUBLE:
        d.floating_point_range = [FloatingPointRange(
            from_value=_finite(p.low), to_value=_finite(p.high), step=p.step)]
    elif p.low is not None and d.type == ParameterType.PARAMETER_INTEGER:
        d.integer_range = [IntegerRange(from_value=int(p.low), to_value=int(p.high), step=1)]
    if p.choices:
        d.additional_constraints = 'one of: ' + ', '.join(str(c) for c in p.choices)
    elif p.constraint:
        d.additional_constraints = p.constraint
    return d


def declare(node, params):
    """Declare every :class:`Param` on ``node``; return ``{name: value}`` as set at start."""
    node.declare_parameters('', [(p.name, p.default, descriptor(p)) for p in params])
    return {p.name: node.get_parameter(p.name).value for p in params}


def check_choices(params, changes):
    """Return the reason a change breaks an allowed-values list, or None."""
    by_name = {p.name: p for p in params}
    for name, value in changes.items():
        p = by_name.get(name)
        if p is not None and p.choices and value not in p.choices:
            return f'{name} = {value!r} is not one of {list(p.choices)}'
    return None
