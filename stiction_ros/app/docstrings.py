"""Docstrings as a terminal shows them: the ``--help`` of commands and nodes alike."""

import re

_ROLE = re.compile(r':(?:mod|func|class|meth|data):`~?([^`]+)`')


def plain(text: str) -> str:
    """Return docstring text without reStructuredText markup (``code``, :mod:`x`, ``::``)."""
    return _ROLE.sub(r'\1', text).replace('``', '').replace('::\n', ':\n')
