"""
Valve models: map controller output OP (%) to valve position MV (%).

>>> from stiction_ros.models import create
>>> valve = create('kano', S=5.0, J=2.0)
>>> mv = valve.simulate([50.0, 51.0, 53.0, 56.0])

Every model has ``simulate(u)`` (whole array, from rest), ``reset(y0)``,
``step(u)`` (one sample; identical to ``simulate``), ``params`` and
``set_params(**changes)``.  Nothing here imports rclpy.
"""

from typing import Any

from stiction_ros.models.base import ModelError, ValveModel
from stiction_ros.models.choudhury import Choudhury
from stiction_ros.models.he import He
from stiction_ros.models.kano import Kano
from stiction_ros.models.kano_effects import KanoEffects
from stiction_ros.models.linear import Linear
from stiction_ros.models.physical import Physical
from stiction_ros.models.stenman import Stenman

MODELS: dict[str, type[ValveModel]] = {
    cls.name: cls for cls in (Kano, Choudhury, Stenman, He, Physical, Linear, KanoEffects)}

__all__ = ['Choudhury', 'create', 'He', 'Kano', 'KanoEffects', 'Linear', 'ModelError', 'MODELS',
           'Physical', 'Stenman', 'ValveModel']


def create(name: str, **params: Any) -> ValveModel:
    """Build a model by name: kano, choudhury, stenman, he, physical or linear."""
    try:
        cls = MODELS[str(name).lower()]
    except KeyError:
        raise ModelError(f'unknown valve model {name!r}; choose one of {sorted(MODELS)}') from None
    return cls(**params)
