"""
What a loop node knows about the health of its input: rejected values and staleness.

Plain Python (no rclpy), so the rules are testable alone; ``sampled.py`` wires
it to the subscription callbacks and publishes :meth:`InputGuard.status` on
``/diagnostics``.  A value is rejected when it is not finite or its magnitude
exceeds ``limit`` (a percent signal of 1e300 is as wrong as a NaN); the node
then holds its last good value.  The input is stale when no good value has
arrived for ``stale_after`` seconds.
"""

import math

OK, WARN, ERROR = 0, 1, 2


class InputGuard:
    """Accepts or rejects the values of one input topic and says how it is doing."""

    def __init__(self, topic, limit, stale_after):
        self.topic = topic
        self.limit = float(limit)
        self.stale_after = float(stale_after)
        self.last_good = None  # (time s, value)
        self.rejected = 0
        self._reported = 0
        self.last_bad = None

    def check(self, value, now):
        """Return True if ``value`` (received at ``now`` s) may be used."""
        if math.isfinite(value) and abs(value) <= self.limit:
            self.last_good = (now, value)
            return True
        self.rejected += 1
        self.last_bad = value
        return False

    def status(self, now):
        """Return (level, message, {key: value}) of the input at ``now`` s."""
        fresh = self.rejected - self._reported
        self._reported = self.rejected
        values = {'rejected_total': str(self.rejected)}
        if self.last_good is None:
            return WARN, f'no valid {self.topic} received yet', values
        age = now - self.last_good[0]
        values['last_good'] = repr(self.last_good[1])
        values['age_s'] = f'{age:.3f}'
        # Rejections are reported in any case: an input can be both stale and bad.
        bad = (f'rejected {fresh} {self.topic} value(s) since the last report (last '
               f'{self.last_bad!r}: not finite or beyond +-{self.limit:g}); ' if fresh else '')
        if age > self.stale_after:
            return (ERROR, f'{self.topic} stale: nothing valid for {age:.1f} s; {bad}holding '
                    f'{self.last_good[1]:.6g}', values)
        if fresh:
            return WARN, f'{bad}holding the last good value', values
        return OK, f'{self.topic} valid', values
