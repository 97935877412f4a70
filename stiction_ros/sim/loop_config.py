"""
Loop descriptions in YAML: load, merge a case, validate every key.

A loop file (see ``config/concentration_loop.yaml``) has the sections
``plant``, ``controller``, ``valve`` and optionally ``noise`` and ``cases``.
A case is a partial loop description merged over the base, so the four
Table 2.1 cases differ only in ``valve: {S, J}``.  Errors name the offending
key (``controller.Ti``) and suggest the nearest valid key on a typo.
"""

import copy
import difflib
import math

from stiction_ros.errors import ConfigError
from stiction_ros.models import MODELS
import yaml

TOP = {'name', 'description', 'sample_time', 'duration', 'plant', 'controller', 'valve',
       'noise', 'cases'}
PLANT = {'num', 'den', 'delay', 'mv0', 'pv0', 'disturbance_steps'}
CONTROLLER = {'mode', 'Kc', 'Ti', 'Td', 'N', 'op_min', 'op_max', 'bias', 'action', 'setpoint',
              'op'}
NOISE = {'pv_std', 'mv_std', 'seed'}


def _path(where, key):
    return f'{where}.{key}' if where else str(key)


def _check_keys(section, allowed, where):
    if not isinstance(section, dict):
        raise ConfigError(f'{where or "loop"}: expected a mapping, got {type(section).__name__}')
    for key in section:
        if key not in allowed:
            hint = difflib.get_close_matches(str(key), sorted(allowed), n=1)
            raise ConfigError(
                f'{_path(where, key)}: unknown key'
                + (f"; did you mean '{hint[0]}'?" if hint else f'; valid keys: {sorted(allowed)}'))


def _require(section, key, where):
    if key not in section:
        raise ConfigError(
            f'{_path(where, key)}: missing; add it (see config/concentration_loop.yaml)')
    return section[key]


def deep_merge(base, over):
    """Return ``base`` with mapping ``over`` merged in recursively."""
    out = copy.deepcopy(base)
    for k, v in over.items():
        if isinstance(v, dict) and isinstance(out.get(k), dict):
            out[k] = deep_merge(out[k], v)
        else:
            out[k] = copy.deepcopy(v)
    return out


def parse_overrides(items):
    """Turn ``['valve.S=7', 'valve.model=kano']`` into ``{'valve.S': 7, ...}`` (YAML values)."""
    out = {}
    for item in items or ():
        key, sep, value = item.partition('=')
        if not sep or not key:
            raise ConfigError(f'--set {item!r}: expected KEY=VALUE, e.g. valve.S=7')
        try:
            out[key] = yaml.safe_load(value)
        except yaml.YAMLError:
            raise ConfigError(f'--set {item!r}: the value is not valid YAML') from None
    return out


def load_loop(path, case=None, overrides=None):
    """Read a loop file, merge ``case`` and dotted ``overrides``, validate, return a dict."""
    try:
        with open(path, encoding='utf-8') as f:
            doc = yaml.safe_load(f)
    except OSError as err:
        raise ConfigError(f'{path}: {err.strerror}') from None
    except UnicodeDecodeError:
        raise ConfigError(f'{path}: not a loop file (not UTF-8 text); the shipped ones are in '
                          'config/, e.g. concentration_loop.yaml') from None
    except yaml.YAMLError as err:
        raise ConfigError(f'{path}: not valid YAML: {err}') from None
    return resolve_loop(doc, case, overrides, source=str(path))


def resolve_loop(doc, case=None, overrides=None, source='loop'):
    """Merge ``case`` and ``overrides`` (``{'valve.S': 7}``) into ``doc`` and validate."""
    if not isinstance(doc, dict):
        raise ConfigError(f'{source}: expected a mapping at the top level')
    cases = doc.get('cases') or {}
    cfg = {k: v for k, v in doc.items() if k != 'cases'}
    if case is not None:
        if case not in cases:
            raise ConfigError(f'{source}: no case {case!r}; cases: {sorted(cases)}')
        cfg = deep_merge(cfg, cases[case])
        cfg['case'] = case
    overrides = overrides or {}
    if 'case' in overrides:
        # A case merges a whole section of the file; set as a key it would change nothing.
        raise ConfigError(f'{source}: --set case=...: choose a case with --case NAME; cases: '
                          f'{sorted(cases)}')
    for dotted, value in overrides.items():
        node = cfg
        *parents, leaf = dotted.split('.')
        for p in parents:
            node = node.setdefault(p, {})
        node[leaf] = value
    _drop_other_models_keys(cfg, overrides)
    try:
        validate(cfg)
    except ConfigError as err:
        raise ConfigError(f'{source}: {err}') from None
    return cfg


def _drop_other_models_keys(cfg, overrides):
    """
    With ``valve.model`` set on the command line, drop the file's keys the new model lacks.

    The file's valve section holds its own model's parameters (Kano's J); a
    model set by ``--set`` without them (Stenman's S alone) would otherwise be
    refused for a key nobody on the command line wrote.  Keys given with
    ``--set`` are kept, so a wrong one is still named.
    """
    valve = cfg.get('valve')
    model = overrides.get('valve.model')
    if not isinstance(valve, dict) or model not in MODELS:
        return
    keep = set(MODELS[model].PARAMS) | {'model'}
    given = {k.split('.', 1)[1] for k in overrides if k.startswith('valve.')}
    for key in [k for k in valve if k not in keep and k not in given]:
        del valve[key]


def validate(cfg):
    """Raise ConfigError naming the first invalid key of a merged loop description."""
    _check_keys(cfg, TOP | {'case'}, '')
    for key in ('sample_time', 'duration'):
        cfg[key] = _number(_require(cfg, key, ''), key, 'a positive number of seconds',
                           lambda v: v > 0)
    if cfg['duration'] < cfg['sample_time']:
        raise ConfigError('duration: shorter than one sample_time')
    plant = _require(cfg, 'plant', '')
    _check_keys(plant, PLANT, 'plant')
    _require(plant, 'num', 'plant')
    _require(plant, 'den', 'plant')
    if 'mv0' in plant:
        # The valve starts at rest there; outside its travel it would start clipped at a
        # stop, and the plant's equilibrium would be one the valve can never reach.
        plant['mv0'] = _number(plant['mv0'], 'plant.mv0',
                               'a valve position within its travel, 0-100 %',
                               lambda v: 0 <= v <= 100)
    ctl = _require(cfg, 'controller', '')
    _check_keys(ctl, CONTROLLER, 'controller')
    mode = ctl.get('mode', 'closed_loop')
    if mode not in ('closed_loop', 'open_loop'):
        raise ConfigError(f"controller.mode: 'closed_loop' or 'open_loop', got {mode!r}")
    if mode == 'open_loop':
        _require(ctl, 'op', 'controller')
    valve = _require(cfg, 'valve', '')
    if not isinstance(valve, dict):
        raise ConfigError('valve: expected a mapping')
    model = _require(valve, 'model', 'valve')
    if model not in MODELS:
        hint = difflib.get_close_matches(str(model), sorted(MODELS), n=1)
        raise ConfigError(f'valve.model: unknown {model!r}'
                          + (f"; did you mean '{hint[0]}'?" if hint else
                             f'; choose one of {sorted(MODELS)}'))
    _check_keys(valve, set(MODELS[model].PARAMS) | {'model'}, 'valve')
    _check_noise(cfg)
    _build_each(cfg)


def _number(v, where: str, what: str, ok) -> int | float:
    """Return ``v`` as a finite float for which ``ok`` holds, or raise naming ``where``."""
    # YAML reads 1e3 (no dot) as a string; it is a number all the same.
    if isinstance(v, str):
        try:
            v = float(v)
        except ValueError:
            pass
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) \
            or not ok(v):
        raise ConfigError(f'{where}: must be {what}, got {v!r}')
    # As written where it is a number already (a params file keeps 1, not 1.0).
    return v


def _check_noise(cfg):
    noise = cfg.get('noise')
    if noise is None:
        return
    if not isinstance(noise, dict):
        raise ConfigError(f'noise: expected a mapping of {sorted(NOISE)}, got {noise!r}')
    _check_keys(noise, NOISE, 'noise')
    for key in ('pv_std', 'mv_std'):
        if key in noise:
            noise[key] = _number(noise[key], f'noise.{key}', 'a standard deviation >= 0',
                                 lambda v: v >= 0)
    seed = noise.get('seed', 0)
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise ConfigError(f'noise.seed: must be a whole number >= 0, got {seed!r}')


def _build_each(cfg):
    # Build the plant, controller and valve the loop would run, so that an unstable or
    # improper plant, a bad tuning or impossible friction fails here, named, not mid-run.
    from stiction_ros.sim.closed_loop import build_controller, build_plant, build_valve
    for section, build in (('plant', build_plant), ('controller', build_controller),
                           ('valve', build_valve)):
        try:
            build(cfg)
        except (ValueError, TypeError) as err:
            text = str(err)
            raise ConfigError(text if text.startswith(section) else f'{section}: {text}') from None
