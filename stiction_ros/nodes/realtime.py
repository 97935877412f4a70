"""
Wall-time scheduling of the loop nodes: the timer's phase, SCHED_FIFO and its guard.

A node under SCHED_FIFO runs as soon as its timer is due, ahead of every
normal process.  That is what a loop wants while the node keeps up; a node
that cannot (1 kHz on a small machine: every tick is due before the last one
ended) never sleeps, and a few of them hold every core.  The recorder, the
launcher that should stop them, even a shell, then get only what the
kernel's real-time throttling leaves, which is nothing on a machine where
throttling borrows across cores (seen: a 1 kHz run on 2 cores that never
ended).  :class:`CpuWatch` spots a process that has used a whole core for
several seconds, and the node returns to the normal scheduler.
"""

import os
import time
from typing import Any

# A node that keeps up sleeps most of each sample: 5-10 % of a core at 100 Hz,
# measured.  One that has used 90 % of a core for 3 s in a row is not keeping up.
CPU_LIMIT = 0.9
WINDOWS = 3


def set_fifo(priority: int) -> None:
    """
    Put every thread of this process under SCHED_FIFO at ``priority`` (0: the normal one).

    Every thread: the DDS threads that hand messages to the executor too, or
    it could wait for them behind the normal scheduler (priority inversion).
    ``SCHED_RESET_ON_FORK``: a child process starts on the normal scheduler.
    Raises OSError (no CAP_SYS_NICE) or AttributeError (not Linux).
    """
    if priority > 0:
        policy, param = os.SCHED_FIFO | os.SCHED_RESET_ON_FORK, os.sched_param(priority)
    else:
        policy, param = os.SCHED_OTHER, os.sched_param(0)
    for tid in os.listdir('/proc/self/task'):
        try:
            os.sched_setscheduler(int(tid), policy, param)
        except ProcessLookupError:
            pass                        # a thread that ended since the listing


class CpuWatch:
    """
    Say when a process has used more than ``limit`` of a core for ``windows`` windows in a row.

    Fed (wall seconds, process CPU seconds) about once a second; pure, so it is
    tested without a node or a scheduler.
    """

    def __init__(self, limit: float = CPU_LIMIT, windows: int = WINDOWS) -> None:
        if not (limit > 0.0 and windows >= 1):
            raise ValueError('CpuWatch needs limit > 0 and windows >= 1')
        self.limit, self.windows = limit, windows
        self._last: tuple[float, float] | None = None
        self._over = 0
        self.share = 0.0

    def update(self, wall: float, cpu: float) -> bool:
        """Add a reading; return True when the last ``windows`` windows were all over the limit."""
        if self._last is not None and wall > self._last[0]:
            self.share = (cpu - self._last[1]) / (wall - self._last[0])
            self._over = self._over + 1 if self.share > self.limit else 0
        self._last = (wall, cpu)
        return self._over >= self.windows


def align_timer(timer: Any, ts_ns: int, phase_ns: int, slack_ns: int = 50_000,
                tries: int = 20) -> None:
    """
    Put an rclpy ``timer``'s ticks just after ``phase_ns`` into each sample of the system clock.

    Every process on the machine then shares the same grid of phases.  The
    timer's grid is fixed when it is reset, so a reset that lands late (a
    sleep that overran, a busy machine) would offset every tick of the run
    (by 0.5-1.5 ms, measured); it is redone until the offset is under
    ``slack_ns``.
    """
    for _ in range(tries):
        wait = (phase_ns - time.time_ns()) % ts_ns
        if wait > 2_000_000:
            time.sleep((wait - 1_000_000) / 1e9)
        while (time.time_ns() - phase_ns) % ts_ns > slack_ns // 2:
            pass  # the last millisecond spun: sleep overruns it
        timer.reset()
        offset = (time.time_ns() + timer.time_until_next_call() - phase_ns) % ts_ns
        if offset <= slack_ns:
            return
