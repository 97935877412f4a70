"""
The interface every valve model shares: one sample at a time or a whole array.

Signals are in % of span: ``u`` is the valve input (controller output OP after
any mA-to-% conversion), ``y`` the valve position (MV).

Each model keeps *all* of its memory in one float array (``self.state``) and
advances it with one kernel function ``_run(u, y, state)``.  ``simulate()``
runs the kernel over a whole array, ``step()`` runs it over one sample; since
the kernel carries everything in ``state``, both give identical results, and a
fast compiled kernel can replace the Python one without changing behaviour.
"""

import math
from typing import Any, Callable, ClassVar

import numpy as np
from numpy.typing import ArrayLike

from stiction_ros.errors import ModelError
from stiction_ros.kernels.arrays import Floats
from stiction_ros.kernels.loop_kinds import LoopArgs

# Parameter name -> (default, low, high, description); ``low`` 'choice' makes ``high`` the
# tuple of allowed values.
ParamTable = dict[str, tuple[Any, Any, Any, str]]
# A kernel: advance over input ``u``, writing ``y`` and updating ``state`` in place.
Kernel = Callable[[Floats, Floats, Floats], None]


def check_finite(name: str, value: Any, low: float = -math.inf, high: float = math.inf) -> float:
    """Return ``value`` as float if it is finite and within [low, high], else raise."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ModelError(f'{name} must be a number, got {value!r}') from None
    if not math.isfinite(v):
        raise ModelError(f'{name} must be finite, got {v}')
    if v < low or v > high:
        raise ModelError(f'{name} = {v} is outside [{low}, {high}]')
    return v


def clip(x: float, low: float = 0.0, high: float = 100.0) -> float:
    """Clamp a scalar to [low, high] (faster than numpy for one value)."""
    return low if x < low else high if x > high else x


def as_signal(u: ArrayLike, name: str = 'input') -> Floats:
    """Return ``u`` as a 1-D float64 array, rejecting NaN and infinities."""
    a = np.asarray(u, dtype=np.float64)
    if a.ndim != 1:
        a = a.reshape(-1)
    # Not np.dot(a, a) (finite only if every sample is): OpenBLAS splits a dot of over
    # 10 000 samples across its threads, whose spinning after each call then held a
    # second core busy for as long as simulate() was called (measured: CPU/wall 1.98).
    finite = np.isfinite(a)
    if not finite.all():
        bad = int(np.flatnonzero(~finite)[0])
        raise ModelError(f'{name} has a non-finite value at index {bad}: {a[bad]}')
    return a


class ValveModel:
    """
    Base class: subclasses define ``PARAMS``, ``_initial_state`` and ``_run``.

    ``PARAMS`` maps each parameter name to ``(default, low, high, description)``.
    """

    name: ClassVar[str] = 'base'
    PARAMS: ClassVar[ParamTable] = {}

    def __init__(self, **params: Any) -> None:
        self._params = self.checked(**params)
        self._y0: float | None = None
        self._u_rest: float | None = None
        self.state: Floats | None = None
        self._on_params_changed()

    # -- parameters --------------------------------------------------------
    @classmethod
    def checked(cls, **params: Any) -> dict[str, Any]:
        """
        Return every parameter, defaults filled in, checked as building the model checks them.

        Raises ModelError as the build would; builds nothing (a valve node checks
        every model a change touches, and the physical one's build takes 0.3 s).
        """
        unknown = set(params) - set(cls.PARAMS)
        if unknown:
            raise ModelError(
                f'{cls.name}: unknown parameter(s) {sorted(unknown)}; '
                f'valid: {sorted(cls.PARAMS)}')
        values = {k: spec[0] for k, spec in cls.PARAMS.items()}
        values.update(params)
        return cls._validate(values)

    @classmethod
    def _validate(cls, values: dict[str, Any]) -> dict[str, Any]:
        """Check every value against its range; subclasses add cross-checks."""
        out = {}
        for k, (_, low, high, _) in cls.PARAMS.items():
            if isinstance(low, str):
                if values[k] not in high:
                    raise ModelError(
                        f'{cls.name}: {k} = {values[k]!r} is not one of {list(high)}')
                out[k] = values[k]
            else:
                out[k] = check_finite(f'{cls.name}: {k}', values[k], low, high)
        return out

    @property
    def params(self) -> dict[str, Any]:
        """Return a copy of the current parameter values."""
        return dict(self._params)

    def set_params(self, **changes: Any) -> None:
        """Change parameters, all or none; they apply from the next sample on."""
        unknown = set(changes) - set(self.PARAMS)
        if unknown:
            raise ModelError(f'{self.name}: unknown parameter(s) {sorted(unknown)}')
        merged = dict(self._params)
        merged.update(changes)
        self._params = self._validate(merged)
        self._on_params_changed()

    def _on_params_changed(self) -> None:
        """Recompute derived constants; the dynamic state is kept."""

    def __getattr__(self, key: str) -> Any:
        params = self.__dict__.get('_params')
        if params is not None and key in params:
            return params[key]
        raise AttributeError(f'{type(self).__name__!s} has no attribute {key!r}')

    def __repr__(self) -> str:
        args = ', '.join(f'{k}={v!r}' for k, v in self._params.items())
        return f'{type(self).__name__}({args})'

    # -- simulation --------------------------------------------------------
    def reset(self, y0: float | None = None, u_rest: float | None = None) -> None:
        """
        Forget the history; the next sample starts the valve at rest.

        The start-up convention of :meth:`step`: the valve has rested at ``y0``
        (output units) under the input ``u_rest``, with no friction force
        stored, so its first input is a change from ``u_rest`` and moves it as
        soon as that change exceeds the band, as in the chapter's models.
        ``u_rest`` defaults to the input that holds the valve at ``y0``
        (:meth:`rest_input`; ``y0`` itself for a valve in % of travel).  With
        ``y0`` None the valve rests at its first input.
        """
        self._y0 = None if y0 is None else check_finite('y0', y0, 0.0, 100.0)
        if u_rest is not None:
            self._u_rest = check_finite('u_rest', u_rest)
        else:
            self._u_rest = None if self._y0 is None else self.rest_input(self._y0)
        self.state = None

    def rest_input(self, y0: float) -> float:
        """Return the input under which the valve rests at output ``y0``."""
        return y0

    def step(self, u: float) -> float:
        """Advance one sample with input ``u`` and return the new position."""
        x = check_finite('valve input', u)
        if self.state is None:
            self.state = self._new_state(x if self._u_rest is None else self._u_rest)
        y = np.empty(1)
        self._run(np.array([x]), y, self.state)
        return float(y[0])

    def simulate(self, u: ArrayLike, y0: float | None = None) -> Floats:
        """
        Reset, run the whole input array and return positions of the same length.

        A record starts with the valve at rest at ``y0`` (default: ``u[0]``)
        under its first input ``u[0]``: what force a recorded valve had
        stored when the record began is unknown, and none is assumed.
        """
        return self._simulate(u, y0, self._run)

    def simulate_reference(self, u: ArrayLike, y0: float | None = None) -> Floats:
        """
        Return :meth:`simulate` computed by the model's pure-Python kernel.

        Where ``simulate`` runs compiled code, this is the oracle it is tested
        against sample for sample; elsewhere the two are the same code.
        """
        return self._simulate(u, y0, self._run_reference)

    def _simulate(self, u: ArrayLike, y0: float | None, run: Kernel) -> Floats:
        a = as_signal(u, 'valve input')
        self.reset(y0)
        y = np.empty_like(a)
        if a.size:
            self.state = self._new_state(float(a[0]))
            run(a, y, self.state)
        return y

    def snapshot(self) -> dict[str, Any]:
        """Return the dynamic state as plain JSON-able data (see :meth:`restore`)."""
        return {'model': self.name, 'state': None if self.state is None else
                [float(x) for x in self.state]}

    def restore(self, snap: object) -> None:
        """
        Continue from a :meth:`snapshot`: position, stuck or moving, direction, stored force.

        A live valve that restarts must not jump; its memory is all in
        ``state``.  Raises ModelError if ``snap`` is not this model's.
        """
        if not isinstance(snap, dict) or snap.get('model') != self.name:
            raise ModelError(f'{self.name}: the saved state is of model '
                             f'{snap.get("model") if isinstance(snap, dict) else snap!r}')
        state = snap.get('state')
        if state is None:
            self.state = None
            return
        want = len(self._new_state(50.0))
        try:
            arr = np.array(state, dtype=np.float64)
        except (TypeError, ValueError):
            raise ModelError(f'{self.name}: the saved state is not a list of numbers') from None
        if arr.shape != (want,) or not np.all(np.isfinite(arr)):
            raise ModelError(f'{self.name}: the saved state has {arr.size} values, '
                             f'{want} finite ones expected')
        self.state = arr

    @property
    def position(self) -> float | None:
        """Return the current position, or None before the first sample."""
        return None if self.state is None else float(self.state[0])

    def _new_state(self, u0: float) -> Floats:
        return np.array(self._initial_state(u0, self._y0), dtype=np.float64)

    def _initial_state(self, u0: float, y0: float | None) -> list[float] | Floats:
        """Return the state (position first) of a valve at rest before input ``u0``."""
        raise NotImplementedError

    def _run(self, u: Floats, y: Floats, state: Floats) -> None:
        """Advance over the array ``u``, writing ``y`` and updating ``state`` in place."""
        raise NotImplementedError

    def loop_args(self) -> LoopArgs | None:
        """
        Return this valve's arguments for the compiled offline loop, or None.

        ``(kind, float params, array, propagators, steps, q, jmax)``, built by
        ``loop_kinds.loop_args``; None runs the loop sample by sample in Python.
        """
        return None

    def _run_reference(self, u: Floats, y: Floats, state: Floats) -> None:
        # Models with a compiled _run override this with their pure-Python kernel.
        self._run(u, y, state)
