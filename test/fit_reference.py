"""
A naive reference for where the identification starts a valve.

The fits start the record's valve at rest at the position that fits the
samples before its first move best, their mean (``kernels.sse``).  Here that
is found without the kernels: until its first move a model's output is the
start it was given, after it the start is forgotten, so two runs from
opposite starts differ exactly on the first rest.
"""

import numpy as np

from stiction_ros.models import create


def first_rest(model: str, op: np.ndarray, S: float, J: float, **kw) -> int:
    """Return how many samples the valve rests at its start before it first moves."""
    low = create(model, S=S, J=J, **kw).simulate(op, y0=0.0)
    high = create(model, S=S, J=J, **kw).simulate(op, y0=100.0)
    same = np.nonzero(low == high)[0]
    return int(same[0]) if same.size else len(op)


def reference_output(model: str, op: np.ndarray, mv: np.ndarray, S: float, J: float,
                     **kw) -> np.ndarray:
    """Return the model's MV from the start that fits its first rest best."""
    k = first_rest(model, op, S, J, **kw)
    y0 = float(np.mean(mv[:k])) if k else 0.0
    return create(model, S=S, J=J, **kw).simulate(op, y0=y0)
