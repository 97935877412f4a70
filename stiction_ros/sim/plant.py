"""
Process models: a transfer function with dead time, discretised exactly.

``PV = pv0 + G(s) e^{-delay s} (MV - mv0)`` around an operating point, so a
self-regulating plant starts in equilibrium at ``MV = mv0``, ``PV = pv0`` and
an integrating one (a pole at s = 0) starts at rest there.

The input is held constant over each sample (zero-order hold, as the valve
node holds its last position), which makes the discretisation exact: the
delay-free part, in the controllable canonical form ``scipy.signal.tf2ss``
gives, is discretised as ``scipy.signal.cont2discrete(..., method='zoh')``
does it, by one matrix exponential (``scipy.linalg.expm``), and a fractional
dead time ``theta`` splits each sample into two held segments.  Written out
here, not called: importing ``scipy.signal`` took 1.4 s of the plant node's
3.6 s start (test_plant checks both against scipy.signal).
"""

import math

import numpy as np
from scipy.linalg import expm

from stiction_ros.errors import PlantError
from stiction_ros.kernels.plant import plant_advance, plant_output
from stiction_ros.models.base import check_finite


def _poly(name, coeffs):
    try:
        a = np.atleast_1d(np.asarray(coeffs, dtype=np.float64))
    except (TypeError, ValueError):
        raise PlantError(f'plant.{name} must be a list of numbers, got {coeffs!r}') from None
    if a.ndim != 1 or a.size == 0 or not np.all(np.isfinite(a)):
        raise PlantError(
            f'plant.{name} must be a non-empty list of finite numbers, got {coeffs!r}')
    nz = np.flatnonzero(a)
    if nz.size == 0:
        raise PlantError(f'plant.{name} is all zeros')
    return a[nz[0]:]


class TransferFunctionPlant:
    """
    A SISO plant ``num(s)/den(s) * exp(-delay s)`` sampled at ``sample_time``.

    Use ``output()`` to read PV at the current instant and ``update(mv)`` to
    apply MV over the next sample; or ``simulate(mv)`` for a whole array.
    """

    def __init__(self, num, den, delay=0.0, sample_time=1.0, mv0=0.0, pv0=0.0,
                 noise_std=0.0, disturbance_steps=(), seed=None):
        self.num = _poly('num', num)
        self.den = _poly('den', den)
        if self.num.size > self.den.size:
            raise PlantError(
                f'plant is not proper: numerator degree {self.num.size - 1} exceeds '
                f'denominator degree {self.den.size - 1}; a physical process cannot '
                'respond before it is excited; add poles or remove zeros')
        self.delay = check_finite('plant.delay', delay, 0.0, 1e7)
        self.sample_time = check_finite('plant.sample_time', sample_time, 1e-9, 1e7)
        self.mv0 = check_finite('plant.mv0', mv0)
        self.pv0 = check_finite('plant.pv0', pv0)
        self.noise_std = check_finite('plant.noise_std', noise_std, 0.0)
        self.disturbance_steps = sorted(
            (check_finite('disturbance time', t), check_finite('disturbance size', m))
            for t, m in disturbance_steps)
        poles = np.roots(self.den)
        if np.any(poles.real > 1e-9) or np.sum(np.abs(poles) < 1e-9) > 1:
            raise PlantError(
                f'plant.den has poles {np.round(poles, 6).tolist()}: the open-loop process '
                'is unstable (a right-half-plane pole or a double integrator); '
                'the simulator only takes stable or single-integrating processes')
        self.integrating = bool(np.any(np.abs(poles) < 1e-9))
        self._discretise()
        self._rng = np.random.default_rng(seed)
        self.reset()

    def _discretise(self):
        a, b, c, d = state_space(self.num, self.den)
        ts = self.sample_time
        steps = self.delay / ts
        m = int(math.floor(steps + 1e-9))
        theta = self.delay - m * ts
        if theta < 1e-9 * ts:
            theta = 0.0
        phi, gam = zoh(a, b, ts)
        if theta == 0.0:
            g0, g1 = gam, np.zeros_like(gam)
        else:
            # Within one sample the delayed input is u[k-m-1] for theta
            # seconds, then u[k-m] for the rest.
            phi_rest, g_rest = zoh(a, b, ts - theta)
            _, g_theta = zoh(a, b, theta)
            g0, g1 = g_rest, phi_rest @ g_theta
        self._phi = np.ascontiguousarray(phi, dtype=np.float64)
        self._g0 = np.ascontiguousarray(g0[:, 0], dtype=np.float64)
        self._g1 = np.ascontiguousarray(g1[:, 0], dtype=np.float64)
        self._c = np.ascontiguousarray(c[0], dtype=np.float64)
        self._d = float(d[0, 0])
        self._m = m
        self._fractional = theta > 0.0
        self.dc_gain = (math.inf if self.integrating
                        else float(self.num[-1] / self.den[-1]))

    def reset(self):
        """Return to the operating point: PV = pv0, MV = mv0 held for all past time."""
        self._x = np.zeros(self._phi.shape[0])
        # past deviations of MV: u[k-1], ..., u[k-m-1] (newest first)
        self._hist = [0.0] * (self._m + 1)
        self.time = 0.0
        self._last = 0.0

    def snapshot(self):
        """Return the plant's memory: state, MV history, time, noise generator."""
        return {'x': [float(v) for v in self._x], 'hist': [float(v) for v in self._hist],
                'time': self.time, 'last': self._last, 'rng': self._rng.bit_generator.state}

    def restore(self, snap):
        """Continue from a :meth:`snapshot`, so that a restarted plant does not jump to pv0."""
        try:
            x = np.array(snap['x'], dtype=np.float64)
            hist = [float(v) for v in snap['hist']]
            time, last = float(snap['time']), float(snap['last'])
        except (KeyError, TypeError, ValueError) as err:
            raise PlantError(f'the saved plant state lacks or mangles {err}') from None
        if x.shape != self._x.shape or len(hist) != len(self._hist):
            raise PlantError(f'the saved plant state has {x.size} states and {len(hist)} '
                             f'past inputs; this plant has {self._x.size} and '
                             f'{len(self._hist)} (another plant or sample time)')
        if not (np.all(np.isfinite(x)) and np.all(np.isfinite(hist))
                and math.isfinite(time) and math.isfinite(last)):
            raise PlantError('the saved plant state holds values that are not finite')
        self._x, self._hist, self.time, self._last = x, hist, time, last
        try:
            self._rng.bit_generator.state = snap['rng']
        except (KeyError, TypeError, ValueError):
            pass    # the noise restarts from its seed; the plant itself is restored

    def _delayed(self, lag):
        """Return the deviation input applied ``lag`` samples ago (lag >= 1)."""
        return self._hist[lag - 1]

    def output(self, noisy=True):
        """PV at the current instant (before the next ``update``)."""
        if self._fractional:
            held = self._delayed(self._m + 1)
        elif self._m > 0:
            held = self._delayed(self._m)
        else:
            # No dead time: a biproper plant feeds through the input that is
            # being held up to this instant, i.e. the previous sample's MV.
            held = self._last
        y = plant_output(self._c, self._x, self._d, held, self.pv0)
        for t, size in self.disturbance_steps:
            if self.time >= t - 1e-9 * self.sample_time:
                y += size
        if noisy and self.noise_std > 0.0:
            y += self.noise_std * self._rng.standard_normal()
        return y

    def update(self, mv):
        """Hold ``mv`` over the next sample and advance the state by one sample."""
        u = check_finite('plant input (MV)', mv) - self.mv0
        m = self._m
        now = u if m == 0 else self._delayed(m)
        # The compiled loop's own sums, so that both loops agree to the last bit.
        self._x = plant_advance(self._phi, self._x, self._g0, now, self._g1,
                                self._delayed(m + 1), self._fractional)
        self._hist.insert(0, u)
        self._hist.pop()
        self._last = u
        self.time += self.sample_time

    def frequency_response(self, z):
        """Return P(z) from MV to PV of the sampled plant, dead time included."""
        z = np.atleast_1d(np.asarray(z, dtype=complex))
        eye = np.eye(self._phi.shape[0])
        out = np.empty(len(z), dtype=complex)
        for i, zi in enumerate(z):
            x = np.linalg.solve(zi * eye - self._phi, self._g0 + self._g1 / zi)
            out[i] = (self._c @ x) * zi ** (-self._m)
        # the feedthrough sees the same held input as output() does
        d_delay = self._m + 1 if self._fractional or self._m == 0 else self._m
        return out + self._d * z ** (-d_delay)

    def simulate(self, mv, noisy=True):
        """Reset and return PV for each sample of the MV array (PV read before MV applies)."""
        self.reset()
        out = np.empty(len(mv))
        for k, u in enumerate(np.asarray(mv, dtype=np.float64)):
            out[k] = self.output(noisy)
            self.update(u)
        return out


def state_space(num: np.ndarray, den: np.ndarray) -> tuple[np.ndarray, ...]:
    """Return ``(A, B, C, D)`` of ``num(s)/den(s)`` (den[0] != 0), controllable canonical form."""
    num, den = num / den[0], den / den[0]
    n = den.size - 1
    num = np.concatenate([np.zeros(n + 1 - num.size), num])
    d = num[:1].reshape(1, 1)
    if n == 0:
        # A static gain keeps one state that nothing drives or reads, as tf2ss gives it.
        return np.zeros((1, 1)), np.zeros((1, 1)), np.zeros((1, 1)), d
    a = np.zeros((n, n))
    a[0] = -den[1:]
    a[1:, :-1] = np.eye(n - 1)
    b = np.zeros((n, 1))
    b[0, 0] = 1.0
    c = (num[1:] - num[0] * den[1:]).reshape(1, n)
    return a, b, c, d


def zoh(a: np.ndarray, b: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Return ``(Phi, Gamma)``: ``x' = Ax + Bu`` over ``dt`` with ``u`` held."""
    n, m = b.shape
    block = np.zeros((n + m, n + m))
    block[:n, :n] = a
    block[:n, n:] = b
    whole = expm(dt * block)
    return whole[:n, :n], whole[:n, n:]
