"""What every command shares: its ``--help`` description, and a quiet end on a closed pipe."""

import functools
import os
import re
import sys
from typing import Callable

_ROLE = re.compile(r':(?:mod|func|class|meth|data):`~?([^`]+)`')


def plain(text: str) -> str:
    """Return docstring text without reStructuredText markup (``code``, :mod:`x`)."""
    return _ROLE.sub(r'\1', text).replace('``', '')


def description(doc: str | None) -> str:
    """Return the first line of a module docstring, as plain text, for ``--help``."""
    lines = [line.strip() for line in (doc or '').strip().splitlines()]
    return plain(lines[0]) if lines else ''


def pipe_safe(main: Callable[..., int]) -> Callable[..., int]:
    """
    Wrap a command's ``main`` so that a reader that stops early ends it quietly.

    ``stiction-analyze DIR | head`` closes the pipe after ten lines; the next
    write raises BrokenPipeError.  The reader has what it asked for, so the
    command exits 0 without a traceback (and without the error Python would
    print when it flushes stdout at exit).
    """
    @functools.wraps(main)
    def run(*args: object, **kwargs: object) -> int:
        try:
            return main(*args, **kwargs)
        except BrokenPipeError:
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
            return 0
    return run
