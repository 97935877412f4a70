"""
Progress on stderr that fits the terminal it is shown in.

The app functions report progress through ``say(str)``.  A line that counts
(a search level, a candidate fit, a recording of a batch) is a :class:`Step`:
still a ``str``, so any ``say`` can print or log it as it is, but one that a
terminal display draws as a single updating bar instead of a line per step.

:func:`terminal_progress` picks the display: on a terminal, a rich status
line with a bar (lines that tell something are printed above it); elsewhere
(a log, a pipe) whole lines wrapped to the terminal width, a counted step
only when it ends or every ``PLAIN_EVERY`` seconds; nothing when disabled.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
import shutil
import sys
import textwrap
import threading
import time
from typing import Callable, TextIO

# A log gets a counted step's line this often at most while it runs (and when it ends):
# a run of minutes shows it is alive without a line per candidate fit.
PLAIN_EVERY = 10.0
# Below this width wrapping would leave no room for words; such a terminal wraps itself.
MIN_WIDTH = 20
CONTINUATION = '    '


class Step(str):
    """
    A progress line that counts: ``kano: search level 1/5, 5646 evaluations``.

    The text is ``f'{task} {done}/{total}'`` and ``f', {detail}'`` when there
    is one; a display draws steps of the same ``task`` and ``total`` as one bar.
    """

    task: str
    done: int
    total: int
    detail: str

    def __new__(cls, task: str, done: int, total: int, detail: str = '') -> Step:
        """Return the step ``done`` of ``total`` of ``task``."""
        self = super().__new__(cls, f'{task} {done}/{total}' + (f', {detail}' if detail else ''))
        self.task, self.done, self.total, self.detail = task, int(done), int(total), detail
        return self

    @property
    def finished(self) -> bool:
        """Return whether this is the task's last step."""
        return self.done >= self.total

    def key(self) -> tuple[str, int]:
        """Return what makes two steps parts of one task: its name and its total."""
        return self.task, self.total


def terminal_width() -> int:
    """Return the width lines must fit: ``COLUMNS``, else the terminal's, else 80."""
    return max(shutil.get_terminal_size().columns, MIN_WIDTH)


def wrap(text: str, width: int) -> list[str]:
    """
    Return ``text`` as lines of at most ``width`` characters, continuations indented.

    A word longer than ``width`` (a file's path) keeps a line of its own, whole,
    so that it can still be copied.
    """
    lines = []
    for part in text.splitlines() or ['']:
        lines += textwrap.wrap(part, width, subsequent_indent=CONTINUATION,
                               break_on_hyphens=False, break_long_words=False) or ['']
    return lines


class PlainLines:
    """Progress as whole lines, wrapped to the terminal width: for a log or a pipe."""

    def __init__(self, stream: TextIO, every: float = PLAIN_EVERY,
                 clock: Callable[[], float] = time.monotonic) -> None:
        self.stream, self.every, self.clock = stream, every, clock
        self._lock = threading.Lock()
        self._since: dict[tuple[str, int], float] = {}
        self._ended: tuple[str, int] | None = None

    def __call__(self, msg: str) -> None:
        """Write ``msg``; a :class:`Step` only when it ends or is ``every`` s after the last."""
        with self._lock:
            if isinstance(msg, Step) and not self._due(msg):
                return
            if not isinstance(msg, Step):
                self._ended = None
            width = terminal_width()
            self.stream.write(''.join(line + '\n' for line in wrap(msg, width)))
            self.stream.flush()

    def _due(self, step: Step) -> bool:
        now, key = self.clock(), step.key()
        if step.finished:
            # Threads that finish together may both report the last count: write it once.
            due = self._ended != key
            self._since.pop(key, None)
            self._ended = key
            return due
        self._ended = None
        started = self._since.setdefault(key, now)
        if now - started >= self.every:
            self._since[key] = now
            return True
        return False


class LiveDisplay:
    """
    Progress on a terminal: one live status line, with a bar while a step counts.

    Lines that tell something (what was read, a phase, a finished count) are
    printed above the status line, wrapped to the terminal's width; the status
    line itself is cut to it.  Use it as a context manager.
    """

    def __init__(self, stream: TextIO) -> None:
        # Imported here: rich is needed only when a terminal shows the progress.
        from rich.console import Console
        from rich.progress import BarColumn, Progress, SpinnerColumn, TextColumn, \
            TimeElapsedColumn
        from rich.table import Column
        self.console = Console(file=stream, highlight=False, markup=False, emoji=False)
        text = TextColumn('{task.description}', markup=False,
                          table_column=Column(ratio=1, no_wrap=True, overflow='ellipsis'))
        self.progress = Progress(SpinnerColumn(), text, BarColumn(bar_width=16),
                                 TimeElapsedColumn(), console=self.console, transient=True,
                                 expand=True)
        self.task = self.progress.add_task('starting', total=None)
        self._lock = threading.Lock()
        self._shown: tuple[str, int] | None = None
        self._ended: tuple[str, int] | None = None

    @staticmethod
    def usable(stream: TextIO) -> bool:
        """Return whether ``stream`` is a terminal that can redraw a line (and rich is here)."""
        try:
            from rich.console import Console
        except ImportError:  # pragma: no cover - an install without rich (rosdep has none)
            return False
        console = Console(file=stream)
        return console.is_terminal and not console.is_dumb_terminal

    def __enter__(self) -> LiveDisplay:
        """Start drawing the status line."""
        self.progress.start()
        return self

    def __exit__(self, *exc: object) -> None:
        """Remove the status line."""
        self.progress.stop()

    def __call__(self, msg: str) -> None:
        """Show ``msg``: a :class:`Step` on the bar, anything else above it and as the status."""
        from rich.text import Text
        with self._lock:
            if not isinstance(msg, Step):
                self._shown = self._ended = None
                self.console.print(Text(msg))
                self._restart(msg, None)
                return
            if msg.key() != self._shown:
                self._shown = msg.key()
                self._restart(msg, msg.total)
            self.progress.update(self.task, description=msg, completed=msg.done)
            if msg.finished and self._ended != msg.key():
                self._ended = msg.key()
                self.console.print(Text(msg))

    def _restart(self, description: str, total: int | None) -> None:
        # A new task, not an update: rich cannot turn a counted bar back into a pulse,
        # and the elapsed time is the new phase's.
        self.progress.remove_task(self.task)
        self.task = self.progress.add_task(description, total=total)


def print_nothing(msg: str) -> None:
    """Drop a progress line (``--quiet``)."""


@contextmanager
def terminal_progress(enabled: bool = True,
                      stream: TextIO | None = None) -> Iterator[Callable[[str], None]]:
    """
    Yield the ``say`` that shows progress on ``stream`` (default stderr) as it fits.

    A live status line where ``stream`` is a terminal; plain lines wrapped to
    the terminal width (``COLUMNS``, else 80) where it is a file or a pipe;
    nothing when ``enabled`` is False.
    """
    stream = sys.stderr if stream is None else stream
    if not enabled:
        yield print_nothing
    elif stream.isatty() and LiveDisplay.usable(stream):
        with LiveDisplay(stream) as display:
            yield display
    else:
        yield PlainLines(stream)
