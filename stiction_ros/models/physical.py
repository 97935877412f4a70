"""
Force-balance (physical) valve model, eqs. 2.1-2.2 of the chapter.

The stem obeys ``M x'' = A*p - k*x - F0 + F_f`` with the friction of eq. 2.2:
Coulomb ``Fc`` and viscous ``Fv*v`` while sliding, up to ``Fs`` of static
friction while stuck, and optionally a Stribeck term
``Fc + (Fs-Fc)*exp(-(v/vs)^2)`` in place of ``Fc``.  The valve input ``u``
(% of span) commands the actuator pressure linearly between ``p_min`` and
``p_max``; the actuator pressure follows it through a first-order I/P lag
``tau_ip``.  The output is the stem position in % of the travel ``x_max``.

Stick/slip logic (no floating-point ``v == 0`` tests):

* Sliding in direction ``d`` (+1 opening, -1 closing), a *stop event* happens
  when the velocity changes sign (``d*v < 0``) or, with ``v_stick > 0``, when
  the stem decelerates inside the low-velocity band ``0 <= d*v < v_stick``
  (Karnopp's zero-velocity band).  At the event the stem sticks if the net
  force ``N = A*p - k*x - F0`` satisfies ``|N| <= Fs``; otherwise after a sign
  change it keeps sliding the other way, and after a band event it keeps
  sliding until the velocity really changes sign.  The band matters because
  the default valve is heavily over-damped (``Fv/(2*sqrt(k*M))`` is about
  100): after a move in one direction its velocity decays towards zero
  exponentially and never changes sign, so with ``v_stick = 0`` it would
  creep for ever and never need a breakaway (no slip jump) when the input
  moves on in the same direction.  ``v_stick = 0`` gives the pure
  sign-change rule.
* Stuck, the stem breaks away when ``|N| > Fs``, in the direction of ``N``.
* End stops at ``x = 0`` and ``x = x_max``: reaching one stops the stem
  (``v = 0``, stuck); it leaves only when ``N`` points away from the stop and
  exceeds ``Fs`` (the same breakaway rule, with the direction into the stop
  barred).

Integrators: ``'exact'`` propagates ``[x, v, p]`` between events with matrix
exponentials (the dynamics are linear with a constant input within a sample:
zero-order hold on the commanded pressure), finds velocity events on a sub-grid
of exact propagators (spacing Ts/2**q, at most a tenth of the mechanical time
scale and of ``tau_ip``) and refines their time by bisection with finer exact
propagators, down to 1e-10 s; the breakaway instant of a stuck stem is solved
in closed form, since the pressure is monotone within a sample.  The compiled
form that ``simulate`` runs is ``physical_exact.py`` (0.03 µs per 1 ms sample);
``_run_exact`` below is its pure-Python reference.
``'substep'`` takes semi-implicit steps of length ``substep`` (viscous friction
implicit, ``physical_substep.py``); it is the reference for ``'exact'`` and the
only integrator for the frictions of docs/EFFECTS.md that the exact
propagators cannot carry: the Stribeck term (non-linear sliding dynamics), a
static friction that grows with rest time (``dFs``, ``gamma``) and friction
that differs by direction (``asym``).  With any of them on, the ``'exact'``
setting falls back to ``'substep'`` internally.
"""

import math
from typing import Any

import numpy as np

from stiction_ros.kernels.arrays import Floats
from stiction_ros.kernels.loop_kinds import loop_args, LoopArgs, PHYSICAL_EXACT, PHYSICAL_SUBSTEP
from stiction_ros.kernels.physical_exact import run_exact
from stiction_ros.kernels.physical_layout import (
    _A, _ASYM, _DFS, _DP, _DT, _EP, _F0, _FC, _FOH, _FS, _FV, _GAMMA, _K, _M, _NCONST, _NSUB,
    _PMIN, _STRIB, _TAU, _TS, _VS, _VSTICK, _XMAX, S_DIR, S_P, S_STUCK, S_UPREV, S_X, S_Y,
    STATE_SIZE)
from stiction_ros.kernels.physical_substep import load_state, run_substep, store_state
from stiction_ros.models.base import ModelError, ValveModel

# Finest bisection step when refining an event time, in seconds.
_T_RESOLUTION = 1e-10
# Most substeps per sample the substep integrator may take.
_MAX_SUBSTEPS = 100_000_000
# Sub-grid spacing as a fraction of the shortest time on which the sliding
# velocity can turn (mechanical time scale or tau_ip).
_GRID_FRACTION = 0.1


def _net_force(c: Floats, x: float, p: float) -> float:
    """Return ``A*p - k*x - F0``, the force that friction must balance (N)."""
    return c[_A] * p - c[_K] * x - c[_F0]


def _mech_time_scale(M: float, k: float, Fv: float) -> float:
    """
    Return the time scale (s) on which a sliding stem's velocity can change sign.

    Under-damped: 1/omega_d.  Over-damped: the slow pole's time constant; the
    fast pole (about M/Fv) only relaxes the velocity to its force balance and
    cannot make it change sign on its own.
    """
    a = Fv / M
    w2 = k / M
    disc = a * a - 4.0 * w2
    if disc < 0.0:
        return 1.0 / math.sqrt(-disc / 4.0)
    slow = 2.0 * w2 / (a + math.sqrt(disc))
    return 1.0 / slow


def _event(w: Floats, d: float, signwait: bool, c: Floats) -> bool:
    """Whether state ``w`` of a stem sliding in direction ``d`` is past an event."""
    x = w[0]
    if x > c[_XMAX] or x < 0.0:
        return True
    dv = d * w[1]
    if dv < 0.0:
        return True
    if signwait or dv >= c[_VSTICK]:
        return False
    acc = (c[_A] * w[2] - c[_K] * x - c[_FV] * w[1] + w[4]) / c[_M]
    return d * acc < 0.0


def _run_exact(u: Floats, y: Floats, state: Floats, c: Floats, phis: Floats, hs: Floats, q: int,
               jmax: int) -> None:
    """
    Advance ``state`` over inputs ``u`` with exact propagators (the pure-Python reference).

    ``phis[j]`` propagates ``w = [x, v, p, p_cmd, -F0 - d*Fc]`` sliding over
    ``hs[j] = Ts / 2**j``; level ``q`` is the event-detection sub-grid and
    level ``jmax`` the finest bisection step.
    """
    A = c[_A]
    k = c[_K]
    F0 = c[_F0]
    xmax = c[_XMAX]
    tau = c[_TAU]
    Fc = c[_FC]
    Fs = c[_FS]
    ts = c[_TS]
    hmin = hs[jmax]
    x, v, p, stuck, d, signwait = load_state(state, xmax)
    w = np.empty(5)
    for i in range(u.shape[0]):
        ui = u[i]
        ui = 0.0 if ui < 0.0 else 100.0 if ui > 100.0 else ui
        pc = c[_PMIN] + ui * 0.01 * c[_DP]
        if tau <= 0.0:
            p = pc
        t = 0.0
        while ts - t >= hmin:
            if stuck:
                rem = ts - t
                base = k * x + F0
                n0 = A * p - base
                tb = -1.0
                pb = p
                if n0 > Fs and x < xmax:
                    tb = 0.0
                    d = 1.0
                elif n0 < -Fs and x > 0.0:
                    tb = 0.0
                    d = -1.0
                elif tau > 0.0:
                    ninf = A * pc - base
                    # p moves monotonically to pc, so only one threshold can be met.
                    if ninf > Fs and x < xmax:
                        pb = (base + Fs) / A
                        tb = tau * math.log((p - pc) / (pb - pc))
                        d = 1.0
                    elif ninf < -Fs and x > 0.0:
                        pb = (base - Fs) / A
                        tb = tau * math.log((p - pc) / (pb - pc))
                        d = -1.0
                if tb < 0.0 or tb >= rem:
                    if tau > 0.0:
                        p = pc + (p - pc) * math.exp(-rem / tau)
                    break
                t += tb
                p = pb
                v = 0.0
                stuck = False
                signwait = False
            w[0] = x
            w[1] = v
            w[2] = p
            w[3] = pc
            w[4] = -F0 - d * Fc
            while True:
                rem = ts - t
                j = q
                while hs[j] > rem and j < jmax:
                    j += 1
                if hs[j] > rem:
                    break
                w1 = phis[j] @ w
                if not _event(w1, d, signwait, c):
                    w = w1
                    t += hs[j]
                    continue
                # Bisection: no event at w (time t), an event at w1 (t + hs[jj-1]).
                for jj in range(j + 1, jmax + 1):
                    wm = phis[jj] @ w
                    if _event(wm, d, signwait, c):
                        w1 = wm
                    else:
                        w = wm
                        t += hs[jj]
                t += hmin
                w = w1
                xe = w[0]
                if xe > xmax or xe < 0.0:
                    w[0] = xmax if xe > xmax else 0.0
                    w[1] = 0.0
                    stuck = True
                elif abs(A * w[2] - k * xe - F0) <= Fs:
                    w[1] = 0.0
                    stuck = True
                elif d * w[1] < 0.0:
                    d = -d
                    signwait = False
                    w[4] = -F0 - d * Fc
                else:
                    signwait = True
                if stuck:
                    break
            x = w[0]
            v = w[1]
            p = w[2]
            if not stuck:
                break
        y[i] = x / xmax * 100.0
    store_state(state, x, v, p, stuck, d, signwait, xmax)


class Physical(ValveModel):
    """
    Pneumatic valve from Newton's law with Coulomb, viscous and static friction.

    Parameters are SI (see ``PARAMS``); defaults are the USP lab valve of
    MODELS.md.  The input ``u`` (%, clipped to [0, 100]) commands the pressure
    ``p_cmd = p_min + u/100*(p_max - p_min)``, held constant over each sample
    of length ``sample_time``; the actuator pressure follows it with time
    constant ``tau_ip`` (0: instantly).  The output is ``x/x_max*100``.

    State layout (all memory, so ``step`` and ``simulate`` agree):
    ``[y %, x m, v m/s, p Pa, stuck 0/1, direction +-1, waiting-for-sign-change 0/1,
    time at rest s]``.

    With ``stribeck=True``, ``dFs > 0`` or ``asym != 0`` the ``'exact'``
    integrator falls back to ``'substep'`` internally.

    ``v_stick`` is an addition to eq. 2.2 (Karnopp's zero-velocity band, see
    the module docstring): without it the over-damped default valve never
    comes to rest after a one-way move.  ``v_stick = 0`` is the pure rule.

    Cross-checks (``ModelError``): ``Fs >= Fc``; ``p_max > p_min``; the stem
    must be able to move, which here means both (1) at full pressure the
    actuator lifts the closed stem off its seat, ``A*p_max - F0 > Fs``, and
    (2) after an opening stroke the pressure range can reverse the friction,
    ``A*(p_max - p_min) > Fs + Fc`` (quasi-static S below 100 %), both with
    ``Fs`` and ``Fc`` at their largest (``Fs + dFs``, times ``1 + |asym|``); and, where
    substeps are used, ``dt*sqrt(k/M) < 1`` for a stable spring update.
    """

    name = 'physical'
    PARAMS = {
        'M': (1.6, 1e-4, 1e5, 'mass of the moving parts (kg)'),
        'k': (210490.0, 1.0, 1e10, 'spring constant (N/m)'),
        'A': (0.0445, 1e-6, 100.0, 'diaphragm area (m^2)'),
        'F0': (2550.0, 0.0, 1e8, 'spring preload at x = 0 (N)'),
        'x_max': (0.029, 1e-5, 10.0, 'stem travel (m)'),
        'p_min': (41368.0, 0.0, 1e8, 'actuator pressure at u = 0 % (Pa)'),
        'p_max': (180000.0, 1.0, 1e8, 'actuator pressure at u = 100 % (Pa)'),
        'tau_ip': (3.571, 0.0, 1e4, 'I/P first-order time constant (s); 0: none'),
        'Fc': (700.0, 0.0, 1e8, 'Coulomb (kinetic) friction (N)'),
        'Fs': (780.0, 0.0, 1e8, 'static friction (N), at least Fc'),
        'Fv': (125000.0, 0.0, 1e10, 'viscous friction coefficient (N*s/m)'),
        'vs': (5e-4, 1e-9, 100.0, 'Stribeck velocity (m/s)'),
        'stribeck': (False, 'choice', (False, True),
                     'use Fc + (Fs-Fc)*exp(-(v/vs)^2) as sliding friction'),
        'dFs': (0.0, 0.0, 1e8, 'static friction gained by a long rest (N): '
                'Fs + dFs*t/(t + gamma) after t s at rest'),
        'gamma': (60.0, 1e-3, 1e7, 'rest time at which half of dFs is reached (s)'),
        'asym': (0.0, -0.9, 0.9, 'friction forces times (1 + asym) opening, (1 - asym) closing'),
        'hold': ('zoh', 'choice', ('zoh', 'foh'),
                 'input between samples: zoh holds it, foh ramps it from the previous one'),
        'v_stick': (1e-7, 0.0, 1e-2,
                    'stem sticks when decelerating below this speed with |N| <= Fs (m/s); '
                    '0: only at a velocity sign change'),
        'sample_time': (1.0, 1e-5, 1000.0, 'loop sample time Ts (s)'),
        'integrator': ('exact', 'choice', ('exact', 'substep'),
                       'exact: matrix exponentials and events; substep: fixed steps'),
        'substep': (1e-5, 1e-8, 1.0, 'internal step of the substep integrator (s)'),
    }

    @classmethod
    def _validate(cls, values: dict[str, Any]) -> dict[str, Any]:
        """Check ranges, then the physical cross-checks."""
        out = super()._validate(values)
        n = cls.name
        if out['p_max'] <= out['p_min']:
            raise ModelError(f'{n}: p_max = {out["p_max"]} must exceed p_min = {out["p_min"]}')
        if out['Fs'] < out['Fc']:
            raise ModelError(
                f'{n}: static friction Fs = {out["Fs"]} N is below Coulomb friction '
                f'Fc = {out["Fc"]} N; Fs >= Fc is required')
        # The most static friction the stem can meet: after a long rest, in its worse direction.
        fs_max = (out['Fs'] + out['dFs']) * (1.0 + abs(out['asym']))
        lift = out['A'] * out['p_max'] - out['F0']
        if lift <= fs_max:
            raise ModelError(
                f'{n}: the stem cannot move: at p_max the actuator net force A*p_max - F0 = '
                f'{lift:.6g} N does not exceed the static friction (Fs + dFs)*(1 + |asym|) = '
                f'{fs_max:.6g} N, so the stem never leaves its seat')
        span = out['A'] * (out['p_max'] - out['p_min'])
        fc_max = out['Fc'] * (1.0 + abs(out['asym']))
        if span <= fs_max + fc_max:
            raise ModelError(
                f'{n}: the stem cannot move both ways: the actuator force range '
                f'A*(p_max - p_min) = {span:.6g} N does not exceed the static plus Coulomb '
                f'friction {fs_max + fc_max:.6g} N, so a stroke can never be reversed')
        if out['integrator'] == 'substep' or _needs_substeps(out):
            dt, nsub = _substep_length(out['sample_time'], out['substep'])
            if nsub > _MAX_SUBSTEPS:
                raise ModelError(
                    f'{n}: sample_time/substep = {nsub} substeps per sample is too many '
                    f'(at most {_MAX_SUBSTEPS:.0e})')
            if dt * math.sqrt(out['k'] / out['M']) >= 1.0:
                raise ModelError(
                    f'{n}: substep {dt:.3g} s is too long for the spring: it must be below '
                    f'sqrt(M/k) = {math.sqrt(out["M"] / out["k"]):.3g} s')
        return out

    def _on_params_changed(self) -> None:
        """Recompute the constants and the exact propagators; the state is kept."""
        pr = self._params
        c = np.zeros(_NCONST)
        c[_M] = pr['M']
        c[_K] = pr['k']
        c[_A] = pr['A']
        c[_F0] = pr['F0']
        c[_XMAX] = pr['x_max']
        c[_PMIN] = pr['p_min']
        c[_DP] = pr['p_max'] - pr['p_min']
        c[_TAU] = pr['tau_ip']
        c[_FC] = pr['Fc']
        c[_FS] = pr['Fs']
        c[_FV] = pr['Fv']
        c[_VS] = pr['vs']
        c[_TS] = pr['sample_time']
        c[_VSTICK] = pr['v_stick']
        dt, nsub = _substep_length(pr['sample_time'], pr['substep'])
        c[_DT] = dt
        c[_EP] = math.exp(-dt / pr['tau_ip']) if pr['tau_ip'] > 0.0 else 0.0
        c[_NSUB] = nsub
        c[_STRIB] = 1.0 if pr['stribeck'] else 0.0
        c[_DFS] = pr['dFs']
        c[_GAMMA] = pr['gamma']
        c[_ASYM] = pr['asym']
        c[_FOH] = 1.0 if pr['hold'] == 'foh' else 0.0
        self._c = c
        self._use_exact = pr['integrator'] == 'exact' and not _needs_substeps(pr)
        if self._use_exact:
            self._build_propagators()

    def _build_propagators(self) -> None:
        """Tabulate ``expm(F*Ts/2**j)`` for the sub-grid level and every bisection level."""
        # Imported here: scipy.linalg costs the analyzer's start-up 0.1 s it never needs.
        from scipy.linalg import expm
        pr = self._params
        ts = pr['sample_time']
        scale = _mech_time_scale(pr['M'], pr['k'], pr['Fv'])
        if pr['tau_ip'] > 0.0:
            scale = min(scale, pr['tau_ip'])
        h_grid = _GRID_FRACTION * scale
        q = max(0, math.ceil(math.log2(ts / h_grid)))
        jmax = max(q + 8, math.ceil(math.log2(ts / _T_RESOLUTION)))
        F = np.zeros((5, 5))
        F[0, 1] = 1.0
        F[1, 0] = -pr['k'] / pr['M']
        F[1, 1] = -pr['Fv'] / pr['M']
        F[1, 2] = pr['A'] / pr['M']
        F[1, 4] = 1.0 / pr['M']
        if pr['tau_ip'] > 0.0:
            F[2, 2] = -1.0 / pr['tau_ip']
            F[2, 3] = 1.0 / pr['tau_ip']
        hs = ts * 0.5 ** np.arange(jmax + 1)
        # Levels coarser than the sub-grid are never used; NaN makes misuse loud.
        phis = np.full((jmax + 1, 5, 5), np.nan)
        for j in range(q, jmax + 1):
            phis[j] = expm(F * hs[j])
        self._phis = phis
        self._hs = hs
        self._q = q
        self._jmax = jmax

    # -- helpers for users and tests --------------------------------------
    def p_cmd(self, u: float) -> float:
        """Commanded actuator pressure (Pa) for input ``u`` (%), clipped to [0, 100]."""
        uc = min(max(float(u), 0.0), 100.0)
        return self._params['p_min'] + uc / 100.0 * (self._params['p_max'] - self._params['p_min'])

    def net_force(self, state: Floats | None = None) -> float | None:
        """Return ``A*p - k*x - F0`` (N), the force friction balances, of ``state`` or now."""
        s = self.state if state is None else state
        if s is None:
            return None
        return float(_net_force(self._c, s[S_X], s[S_P]))

    @property
    def stuck(self) -> bool | None:
        """Whether the stem is at rest (stuck or at a stop); None before the first sample."""
        return None if self.state is None else bool(self.state[S_STUCK] > 0.5)

    # -- kernel -------------------------------------------------------------
    def rest_input(self, y0: float) -> float:
        """Return the input (%) whose pressure balances the spring with the stem at ``y0``."""
        pr = self._params
        p = (pr['k'] * y0 / 100.0 * pr['x_max'] + pr['F0']) / pr['A']
        return min(max((p - pr['p_min']) / (pr['p_max'] - pr['p_min']) * 100.0, 0.0), 100.0)

    def _initial_state(self, u0: float, y0: float | None) -> Floats:
        pr = self._params
        pc = self.p_cmd(u0)
        if y0 is None:
            x = (pr['A'] * pc - pr['F0']) / pr['k']
            x = min(max(x, 0.0), pr['x_max'])
        else:
            x = y0 / 100.0 * pr['x_max']
        state = np.zeros(STATE_SIZE)
        state[S_Y] = x / pr['x_max'] * 100.0
        state[S_X] = x
        state[S_P] = pc
        state[S_STUCK] = 1.0
        state[S_DIR] = 1.0
        state[S_UPREV] = min(max(float(u0), 0.0), 100.0)
        return state

    def _run(self, u: Floats, y: Floats, state: Floats) -> None:
        if self._use_exact:
            run_exact(u, y, state, self._c, self._phis, self._hs, self._q, self._jmax)
        else:
            run_substep(u, y, state, self._c)

    def loop_args(self) -> LoopArgs:
        """Return the compiled loop's arguments for this valve."""
        if self._use_exact:
            return loop_args(PHYSICAL_EXACT, (), self._c, self._phis, self._hs, self._q,
                             self._jmax)
        return loop_args(PHYSICAL_SUBSTEP, (), self._c)

    def _run_reference(self, u: Floats, y: Floats, state: Floats) -> None:
        # The exact integrator's pure-Python form; the substep one has only its compiled form.
        if self._use_exact:
            _run_exact(u, y, state, self._c, self._phis, self._hs, self._q, self._jmax)
        else:
            run_substep(u, y, state, self._c)


def _needs_substeps(pr: dict[str, Any]) -> bool:
    # The exact propagators assume constant friction forces in each direction.
    return (bool(pr['stribeck']) or pr['dFs'] > 0.0 or pr['asym'] != 0.0
            or pr['hold'] == 'foh')


def _substep_length(ts: float, substep: float) -> tuple[float, int]:
    """Return ``(dt, n)``: ``n`` equal substeps of length ``dt <= substep`` filling ``ts``."""
    n = max(1, math.ceil(ts / substep - 1e-9))
    return ts / n, n


def quasi_static_sj(**params: Any) -> dict[str, float]:
    """
    Return the data-driven equivalent ``dict(S, J, S_rest, D, gain)`` of a physical valve.

    Quasi-static motion (no inertia, no viscous force, no I/P lag) maps the
    friction onto the input axis through the actuator force span
    ``A*(p_max - p_min)``:

    * ``S = (Fs + Fc)/(A*dp)*100``: input travel after a reversal before the
      stem moves (deadband plus stickband), in % of input;
    * ``J = (Fs - Fc)/(A*dp)*100``: slip jump, expressed on the input axis
      (multiply by ``gain`` for % of stem travel);
    * ``D = (F0/A - p_min)/dp*100``: input where the frictionless spring
      balance leaves the seat (offset of the MV-OP line);
    * ``gain = A*dp/(k*x_max)``: stem % per input % along that line, so a
      stem position ``y`` maps back to the input axis as ``D + y/gain``.

    Unknown names raise ``ModelError``; missing ones take ``Physical``'s defaults.
    """
    unknown = set(params) - set(Physical.PARAMS)
    if unknown:
        raise ModelError(f'quasi_static_sj: unknown parameter(s) {sorted(unknown)}')
    pr = {k: spec[0] for k, spec in Physical.PARAMS.items()}
    pr.update(params)
    dp = float(pr['p_max']) - float(pr['p_min'])
    if dp <= 0.0:
        raise ModelError('quasi_static_sj: p_max must exceed p_min')
    span = float(pr['A']) * dp
    return {
        'S': (float(pr['Fs']) + float(pr['Fc'])) / span * 100.0,
        'J': (float(pr['Fs']) - float(pr['Fc'])) / span * 100.0,
        # from rest with no friction stored, each direction needs Fs: 2 Fs wide
        'S_rest': 2.0 * float(pr['Fs']) / span * 100.0,
        'D': (float(pr['F0']) / float(pr['A']) - float(pr['p_min'])) / dp * 100.0,
        'gain': span / (float(pr['k']) * float(pr['x_max'])),
    }
