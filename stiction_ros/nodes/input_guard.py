"""
What a loop node knows about the health of its input: rejected values and staleness.

Plain Python (no rclpy), so the rules are testable alone; ``sampled.py`` wires
it to the subscription callbacks and publishes :meth:`InputGuard.status` on
``diagnostics`` (in the loop's namespace; ``/diagnostics`` without one).  A
value is rejected when it is not finite or its magnitude exceeds ``limit`` (a
percent signal of 1e300 is as wrong as a NaN); the node then holds its last
good value.  The input is stale when no good value has
arrived for ``stale_after`` seconds.  A sample at which the node acted
without a new value since the previous sample (a message lost or late) is
*held*: counted, and a WARN until a report finds no new one.
"""

import math

OK, WARN, ERROR = 0, 1, 2


class InputGuard:
    """Accepts or rejects the values of one input topic and says how it is doing."""

    def __init__(self, topic, limit, stale_after, lag=0):
        self.topic = topic
        # The sample a value of this input belongs to, relative to the node's own: 0 for
        # one published earlier in the same sample, 1 for one from the sample before.
        self.lag = lag
        self.sample = None
        self.limit = float(limit)
        self.stale_after = float(stale_after)
        self.last_good = None  # (time s, value)
        self.rejected = 0
        self._reported = 0
        self.last_bad = None
        self.fresh = False          # a good value arrived since the node last acted
        self.held = 0
        self._held_reported = 0

    def check(self, value, now, sample=None):
        """Return True if ``value`` (received at ``now`` s, sent in ``sample``) may be used."""
        if math.isfinite(value) and abs(value) <= self.limit:
            self.last_good = (now, value)
            self.fresh = True
            self.sample = sample
            return True
        self.rejected += 1
        self.last_bad = value
        return False

    def acted(self, k=None):
        """
        Note that the node acted at sample ``k``; return True if it did so on a held value.

        Held: no new value since the node last acted, or (when ``k`` and the
        value's sample are known) the newest value is from an earlier sample than
        ``k - lag``, so its message came late.
        """
        late = k is not None and self.sample is not None and self.sample < k - self.lag
        held = self.last_good is not None and (not self.fresh or late)
        self.held += held
        self.fresh = False
        return held

    def status(self, now):
        """Return (level, message, {key: value}) of the input at ``now`` s."""
        fresh = self.rejected - self._reported
        self._reported = self.rejected
        held = self.held - self._held_reported
        self._held_reported = self.held
        values = {'rejected_total': str(self.rejected), 'held_samples_total': str(self.held)}
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
        late = (f'{held} sample(s) since the last report acted on a held {self.topic} '
                '(message lost or late); ' if held else '')
        if fresh or held:
            return WARN, f'{bad}{late}holding the last good value', values
        return OK, f'{self.topic} valid', values
