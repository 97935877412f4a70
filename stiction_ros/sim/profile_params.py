"""
Signal profiles and load steps as typed ROS parameters, and back.

ROS parameters hold numbers, strings and flat arrays, and ``ros2 param set``
re-reads a string as YAML, so a profile is not one YAML string but one typed
parameter per key of its source (:mod:`sources`) under a prefix::

    setpoint_profile.type    steps     ('' : no profile, the constant is in force)
    setpoint_profile.steps   [0.0, 0.0, 10.0, 1.0]      [t0, v0, t1, v1, ...]
    setpoint_profile.period  200.0     (one typed number per other source key)

The steps are one flat double array, so a new set of steps is one parameter
change, whatever order ``ros2 param load`` sets the others in; the plant's
load steps (``disturbance_steps``) are flat ``[time, size]`` pairs the same
way.  Pure Python: the loop parameter files (:mod:`ros_params`) and the
nodes share it.
"""

import inspect
import math
from pathlib import Path

from stiction_ros.errors import SourceError
from stiction_ros.sim.sources import make_source, SOURCES

# 'constant' is the node's constant parameter itself (setpoint, op), not a profile.
PROFILE_TYPES = ('',) + tuple(k for k in SOURCES if k != 'constant')
# key: (low, high, what) of every key of the profile sources; numbers get a range.
KEYS = {
    'steps': (None, None, 'steps as one flat list [t0, v0, t1, v1, ...] (s, value), v0 also '
              'before t0 (steps)'),
    'offset': (-1e12, 1e12, 'mean of the wave (sine, triangle); start of the walk (random_walk)'),
    'amplitude': (-1e12, 1e12, 'amplitude of the wave (sine, triangle)'),
    'period': (1e-12, 1e12, 'period of the wave, s (sine, triangle)'),
    'phase': (-1e6, 1e6, 'phase of the wave at t = 0, rad (sine, triangle)'),
    'std': (0.0, 1e12, 'standard deviation of one step of the walk (random_walk)'),
    'low': (-1e12, 1e12, 'lower bound of the walk (random_walk)'),
    'high': (-1e12, 1e12, 'upper bound of the walk (random_walk)'),
    'seed': (0, 2**31 - 1, 'seed of the walk (random_walk)'),
    'file': (None, None, 'CSV file to replay, read when the profile is set (replay)'),
    'column': (None, None, 'column of file to replay (replay)'),
    'time_column': (None, None, 'column of file that holds the time, s (replay)'),
}
# The parameter value of a key its source requires (no default): unset.
UNSET = {'steps': [], 'file': ''}
PAIRS_RULE = ('one flat list of [time, value] pairs: [t0, v0, t1, v1, ...], '
              'e.g. [0.0, 0.0, 10.0, 1.0]')


def source_keys(kind):
    """Return ``{key: default}`` of the keys of source type ``kind`` (unset: UNSET's value)."""
    sig = inspect.signature(SOURCES[kind].__init__)
    return {name: UNSET[name] if p.default is inspect.Parameter.empty else p.default
            for name, p in sig.parameters.items() if name != 'self'}


def key_defaults():
    """Return ``{key: default}`` over every profile type (the sources' own defaults)."""
    out = {}
    for kind in PROFILE_TYPES[1:]:
        for key, default in source_keys(kind).items():
            out.setdefault(key, default)
    return out


def flat_pairs(steps, where):
    """Return ``[[t0, v0], [t1, v1], ...]`` as the flat list ``[t0, v0, t1, v1, ...]``."""
    out = []
    try:
        for t, v in steps:
            out += [float(t), float(v)]
    except (TypeError, ValueError):
        raise SourceError(f'{where}: expected a list of [time, value] pairs, got {steps!r}') \
            from None
    return out


def pairs(flat, where):
    """Return the flat ``[t0, v0, t1, v1, ...]`` as ``[(t0, v0), ...]``; errors say the fix."""
    values = list(flat)
    if len(values) % 2:
        raise SourceError(f'{where}: {len(values)} numbers, an odd count; give {PAIRS_RULE}')
    if not all(isinstance(x, (int, float)) and math.isfinite(x) for x in values):
        raise SourceError(f'{where}: every number must be finite; give {PAIRS_RULE}')
    return [(float(values[i]), float(values[i + 1])) for i in range(0, len(values), 2)]


def profile_parameters(spec, where):
    """
    Return the profile parameters (``{key: value, ..., 'type': kind}``) of a source mapping.

    Every key of the source's type is given (its default where ``spec`` has
    none), so that loading them replaces a profile whole; ``type`` comes last,
    so that a ``ros2 param load`` in file order sets it once its keys are in.
    """
    make_source(spec, where)            # the source's own checks and messages
    kind = spec['type']
    if kind == 'constant':
        raise SourceError(f'{where}: a constant is the plain parameter, not a profile')
    out = {}
    for key, default in source_keys(kind).items():
        value = spec.get(key, default)
        if key == 'steps':
            out[key] = flat_pairs(value, f'{where}.steps')
        elif isinstance(default, str):
            out[key] = str(value)
        elif key == 'seed':
            out[key] = int(value)
        else:
            out[key] = float(value)
    out['type'] = kind
    return out


def profile_spec(values, where):
    """Return the source mapping of profile parameter values (keys without prefix), or None."""
    kind = values.get('type', '')
    if not kind:
        return None
    if kind not in SOURCES or kind == 'constant':
        raise SourceError(f'{where}.type: unknown {kind!r}; one of {list(PROFILE_TYPES)}')
    spec = {'type': kind}
    for key in source_keys(kind):
        if key == 'steps':
            steps = pairs(values.get('steps', []), f'{where}.steps')
            if not steps:
                raise SourceError(f'{where}.steps is empty: set it to {PAIRS_RULE}, before '
                                  f'{where}.type or in the same call')
            spec[key] = steps
        elif key in values:
            spec[key] = values[key]
    return spec


def check_keys(values, changed, where):
    """Return why the changed profile keys are invalid on their own, or None."""
    try:
        if 'steps' in changed:
            pairs(values['steps'], f'{where}.steps')
        if changed.get('file') and not Path(changed['file']).is_file():
            return f'{where}.file: no file {changed["file"]!r}; give a CSV file, or empty'
        for key in ('column', 'time_column'):
            if key in changed and not str(changed[key]).strip():
                return f'{where}.{key}: empty; give a column name of {where}.file'
    except SourceError as err:
        return str(err)
    return None
