"""
PI/PID controller in the chapter's form ``Kc (1 + 1/(Ti s) + Td s)``, sampled.

The integral uses past errors only (forward Euler), so for a constant error
``e`` applied from t = 0 the output at t = k Ts is exactly the textbook
``bias + Kc e (1 + t/Ti)``.  The derivative acts on PV (no kick on set-point
steps) through a first-order filter ``Td s / (1 + Td s / N)``.  Anti-windup by
conditional integration: the integral stops while the output is saturated and
the error would drive it further out.
"""

from stiction_ros.models.base import check_finite


class PID:
    """A sampled PID controller; ``Ti = 0`` disables the integral."""

    def __init__(self, Kc=1.0, Ti=0.0, Td=0.0, N=10.0, sample_time=1.0, op_min=0.0,
                 op_max=100.0, bias=50.0, action='reverse'):
        self.sample_time = check_finite('controller.sample_time', sample_time, 1e-9)
        self.set_gains(Kc=Kc, Ti=Ti, Td=Td, N=N, op_min=op_min, op_max=op_max, action=action)
        self.bias = check_finite('controller.bias', bias)
        self.reset()

    def set_gains(self, **changes):
        """Change tuning; all or nothing, effective from the next sample."""
        cur = {k: getattr(self, k, None) for k in
               ('Kc', 'Ti', 'Td', 'N', 'op_min', 'op_max', 'action')}
        cur.update(changes)
        kc = check_finite('controller.Kc', cur['Kc'])
        ti = check_finite('controller.Ti', cur['Ti'], 0.0)
        td = check_finite('controller.Td', cur['Td'], 0.0)
        n = check_finite('controller.N', cur['N'], 1.0, 1000.0)
        lo = check_finite('controller.op_min', cur['op_min'])
        hi = check_finite('controller.op_max', cur['op_max'])
        if lo >= hi:
            raise ValueError(f'controller.op_min ({lo}) must be below op_max ({hi})')
        if cur['action'] not in ('reverse', 'direct'):
            raise ValueError(
                f"controller.action must be 'reverse' (OP rises when PV is below SP) "
                f"or 'direct', got {cur['action']!r}")
        self.Kc, self.Ti, self.Td, self.N = kc, ti, td, n
        self.op_min, self.op_max, self.action = lo, hi, cur['action']

    def reset(self, op=None, pv=None):
        """Start bumplessly at output ``op`` (default: the bias) with PV ``pv``."""
        self._i = 0.0 if op is None else float(op) - self.bias
        self._d = 0.0
        self._pv_prev = pv
        self.op = self.bias if op is None else float(op)

    def snapshot(self):
        """Return the controller's memory (integral, derivative filter, last PV and OP)."""
        return {'i': self._i, 'd': self._d, 'pv_prev': self._pv_prev, 'op': self.op}

    def restore(self, snap):
        """Continue from a :meth:`snapshot`, so that a restarted controller does not bump OP."""
        try:
            values = [snap['i'], snap['d'], snap['op']]
            pv = snap['pv_prev']
            values = [check_finite(f'saved controller {k}', v)
                      for k, v in zip(('i', 'd', 'op'), values)]
            pv = None if pv is None else check_finite('saved controller pv_prev', pv)
        except (KeyError, TypeError) as err:
            raise ValueError(f'the saved controller state lacks or mangles {err}') from None
        self._i, self._d, self.op = values
        self._pv_prev = pv

    def update(self, sp, pv):
        """Return OP for set point ``sp`` and measurement ``pv`` at this sample."""
        sp = check_finite('set point', sp)
        pv = check_finite('process value', pv)
        sign = 1.0 if self.action == 'reverse' else -1.0
        e = sign * (sp - pv)
        if self.Td > 0.0 and self._pv_prev is not None:
            ts = self.sample_time
            a = self.Td / (self.Td + self.N * ts)
            self._d = a * self._d - sign * self.Kc * self.N * a * (pv - self._pv_prev)
        self._pv_prev = pv
        raw = self.bias + self.Kc * e + self._i + self._d
        op = min(max(raw, self.op_min), self.op_max)
        if self.Ti > 0.0:
            di = self.Kc * self.sample_time / self.Ti * e
            # Integrate only while that does not push a saturated output further out.
            if op == raw or (raw > self.op_max and di < 0.0) or (raw < self.op_min and di > 0.0):
                self._i += di
        self.op = op
        return op
