"""
Parameter declaration the ROS way: every parameter with a full ``ParameterDescriptor``.

A :class:`Param` lists what ``ros2 param describe`` shows (description, range,
allowed values, read-only); :func:`declare` turns a list of them into
declared parameters.  Ranges are enforced by rclpy itself before the node's
on-set callback runs; allowed values and cross-checks are enforced there.

A parameter ``fixed`` for the run is not rclpy ``read_only``: rclpy refuses
every set of a read-only parameter, even to the value it has, so loading the
file a node was started from, or a ``ros2 param dump`` of it, would fail on
those entries.  The node's on-set callback refuses a change instead
(:func:`check_fixed`) and accepts the value it has.  :func:`coerce` (a
pre-set callback) turns what ``ros2 param set`` and ``ros2 param load`` make
of a number back into the declared type: ``7`` for a double, ``1e-05`` (which
rclpy's file loader re-reads as a string) and ``[]`` (a bool array to it).
"""

from dataclasses import dataclass
import math
import sys
import textwrap

from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor
from rcl_interfaces.msg import ParameterType
from rclpy.exceptions import ParameterUninitializedException
from rclpy.parameter import Parameter
from stiction_ros.errors import StartupError


@dataclass
class Param:
    """One node parameter: default value and what may be set."""

    name: str
    default: object
    description: str
    low: float = None
    high: float = None
    choices: tuple = None
    # rclpy read-only: refused even at the value it has (use ``fixed`` for start-up values).
    read_only: bool = False
    step: float = 0.0
    # What a free-form value must be (a string the node parses): shown by ``ros2 param
    # describe`` as the descriptor's additional_constraints.
    constraint: str = ''
    # Set at start-up only: the on-set callback refuses a change, accepts the same value.
    fixed: bool = False


FIXED_RULE = ('fixed for the run: set at start-up; later only the value it has is accepted '
              '(so a saved parameter file loads back)')
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
    rules = []
    if p.choices:
        rules.append('one of: ' + ', '.join(repr(c) if c == '' else str(c) for c in p.choices))
    elif p.constraint:
        rules.append(p.constraint)
    if p.fixed:
        rules.append(FIXED_RULE)
    d.additional_constraints = '; '.join(rules)
    return d


_TYPE_WORDS = {bool: 'bool', int: 'integer', float: 'double', str: 'string'}


def _num(x) -> str:
    return f'{x:g}' if isinstance(x, float) else str(x)


def help_entry(p: Param, width: int = 79) -> str:
    """
    Return a :class:`Param` as ``--help`` lists it: the name, type, default and rule.

    What ``ros2 param describe`` shows on a running node, for a newcomer whose
    Python environment has rclpy but not the ``ros2`` command.
    """
    if isinstance(p.default, (list, tuple)):
        kind = 'string array' if p.default and isinstance(p.default[0], str) else 'double array'
        default = '[' + ', '.join(_num(v) for v in p.default) + ']'
    else:
        kind = _TYPE_WORDS[type(p.default)]
        default = repr(p.default) if isinstance(p.default, str) else _num(p.default)
    head = [kind, f'default {default}']
    if p.low is not None:
        head.append(f'{_num(p.low)} to {_num(p.high)}')
    if p.choices:
        head.append('one of ' + ', '.join(repr(c) if c == '' else str(c) for c in p.choices))
    if p.read_only:
        head.append('read-only')
    elif p.fixed and 'fixed for the run' not in p.description.lower():
        head.append('fixed for the run')
    text = p.description
    if p.constraint and not p.choices:
        text += f' ({p.constraint})'
    body = textwrap.fill(text, width, initial_indent=' ' * 6, subsequent_indent=' ' * 6,
                         break_long_words=False, break_on_hyphens=False)
    return f'  {p.name} ({"; ".join(head)})\n{body}'


def plain(value):
    """Return a parameter value with arrays as lists (rclpy hands over ``array.array``)."""
    return list(value) if isinstance(value, (list, tuple)) or hasattr(value, 'tolist') else value


def declare(node, params):
    """
    Declare every :class:`Param` on ``node``; return ``{name: value}`` as set at start.

    An empty list default is declared by its type: rclpy would type ``[]`` as a
    bool array.  A parameter file that gives an array as ``[]`` leaves it
    unset (rcl cannot type it either): it is set to the empty array.
    """
    empty = {p.name for p in params if isinstance(p.default, (list, tuple)) and not p.default}
    node.declare_parameters('', [(p.name, Parameter.Type.DOUBLE_ARRAY if p.name in empty
                                  else p.default, descriptor(p)) for p in params])
    out = {}
    for p in params:
        try:
            out[p.name] = plain(node.get_parameter(p.name).value)
        except ParameterUninitializedException:
            if not isinstance(p.default, (list, tuple)):
                raise StartupError(f'{p.name}: no value given; give one or leave it out '
                                   f'(default {p.default!r})') from None
            node.set_parameters([Parameter(p.name, Parameter.Type.DOUBLE_ARRAY, [])])
            out[p.name] = []
    return out


def check_fixed(params, values, changes):
    """Return the reason a change of a parameter fixed for the run is refused, or None."""
    by_name = {p.name: p for p in params}
    for name, value in changes.items():
        p = by_name.get(name)
        if p is not None and p.fixed and plain(value) != values[name]:
            return fixed_reason(name, plain(value))
    return None


def fixed_reason(name, value):
    """Return why ``name`` cannot change now, and how to give it ``value``."""
    shown = (str(value).lower() if isinstance(value, bool) else
             '[' + ', '.join(map(str, value)) + ']' if isinstance(value, list) else value)
    return (f'{name} can only be set at start-up (restart the node with -p {name}:={shown}); '
            'setting the value it has is accepted')


def coerce(params, parameters):
    """
    Return ``parameters`` with numbers put into the declared type of their :class:`Param`.

    An integer becomes a double, an integer array a double array, a string that
    reads as a number (or a bracketed list of numbers) the double (array) it
    says, and an empty array of any type the empty double array.  Anything else
    is passed on for rclpy to accept or refuse as it is.
    """
    by_name = {p.name: p for p in params}
    return [_coerce(by_name.get(q.name), q) for q in parameters]


def _coerce(p, q):
    t = Parameter.Type
    if p is None:
        return q
    double_array = isinstance(p.default, list) and all(isinstance(x, float) for x in p.default)
    try:
        if isinstance(p.default, float) and q.type_ in (t.INTEGER, t.STRING):
            value = float(q.value)
            return Parameter(q.name, t.DOUBLE, value) if math.isfinite(value) else q
        if double_array and q.type_ != t.DOUBLE_ARRAY:
            empty = q.type_.name.endswith('_ARRAY') and not len(q.value)
            if q.type_ == t.INTEGER_ARRAY or empty:
                return Parameter(q.name, t.DOUBLE_ARRAY, [float(x) for x in q.value])
            text = q.value.strip() if q.type_ == t.STRING else ''
            if text.startswith('[') and text.endswith(']'):
                items = [x for x in text[1:-1].split(',') if x.strip()]
                return Parameter(q.name, t.DOUBLE_ARRAY, [float(x) for x in items])
    except (TypeError, ValueError):
        pass
    return q


def check_choices(params, changes):
    """Return the reason a change breaks an allowed-values list, or None."""
    by_name = {p.name: p for p in params}
    for name, value in changes.items():
        p = by_name.get(name)
        if p is not None and p.choices and value not in p.choices:
            return f'{name} = {value!r} is not one of {list(p.choices)}'
    return None
