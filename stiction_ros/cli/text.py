"""What every command shares: its ``--help`` description, a quiet end on a closed pipe, pages."""

import argparse
import datetime
import functools
import json
import os
from pathlib import Path
import platform
import sys
from typing import Callable

from stiction_ros.app.docstrings import plain


def figure(v: float | None, digits: int = 3) -> str:
    """Return ``v`` with ``digits`` decimals for a study's table, '-' for none or NaN."""
    return '-' if v is None or v != v else f'{v:.{digits}f}'


def description(doc: str | None) -> str:
    """Return the first line of a module docstring, as plain text, for ``--help``."""
    lines = [line.strip() for line in (doc or '').strip().splitlines()]
    return plain(lines[0]) if lines else ''


def pipe_safe(main: Callable[..., int]) -> Callable[..., int]:
    """
    Wrap a command's ``main`` so that a reader that stops early, or Ctrl-C, ends it quietly.

    ``stiction-analyze DIR | head`` closes the pipe after ten lines; the next
    write raises BrokenPipeError.  The reader has what it asked for, so the
    command exits 0 without a traceback (and without the error Python would
    print when it flushes stdout at exit).  Ctrl-C ends it with one line and
    status 130, as a shell reports an interrupted command.
    """
    @functools.wraps(main)
    def run(*args: object, **kwargs: object) -> int:
        try:
            return main(*args, **kwargs)
        except BrokenPipeError:
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
            return 0
        except KeyboardInterrupt:
            # Ctrl-C is the user's choice, not a bug: one line and the shell's status.
            print(f'{os.path.basename(sys.argv[0]) or "stiction"}: interrupted',
                  file=sys.stderr)
            return 130
    return run


def write_study(study: dict, json_path: str, markdown_path: str,
                page: Callable[[dict], str]) -> None:
    """Write a study's JSON and its page (``page(study)``), creating their folders."""
    for path, text in ((json_path, json.dumps(study, indent=1) + '\n'),
                       (markdown_path, page(study))):
        Path(path).parent.mkdir(parents=True, exist_ok=True)
        Path(path).write_text(text, encoding='utf-8')


def save_study(prog: str, study: dict, args, page: Callable[[dict], str]) -> bool:
    """
    Write a study to ``args.json`` and ``args.markdown``; False after saying why it cannot.

    Hours of simulation end in these two files: a folder that cannot be
    written is one line on stderr, not a traceback.
    """
    try:
        write_study(study, args.json, args.markdown, page)
    except OSError as err:
        print(f'{prog}: error: cannot write {err.filename}: {err.strerror}', file=sys.stderr)
        return False
    return True


def seeded_parser(prog: str, doc: str | None, first_seed: int, seeds: int, page: str,
                  seeds_help: str | None = None) -> argparse.ArgumentParser:
    """
    Return the parser every seeded study starts from.

    ``--first-seed``, ``--seeds`` (default ``seeds``), ``--jobs`` (every core),
    ``--markdown docs/PAGE.md`` and ``--json docs/page.json`` for ``page``.
    """
    p = argparse.ArgumentParser(prog=prog, description=description(doc))
    p.add_argument('--first-seed', type=int, default=first_seed)
    p.add_argument('--seeds', type=int, default=seeds, help=seeds_help)
    p.add_argument('--jobs', type=int, default=os.cpu_count() or 1)
    p.add_argument('--markdown', default=f'docs/{page}.md')
    p.add_argument('--json', default=f'docs/{page.lower()}.json')
    return p


def run_stamp(jobs: int) -> dict:
    """Return when and on what a study ran, for its page: the date, the machine and jobs."""
    return {'date': datetime.date.today().isoformat(),
            'machine': f'{platform.machine()}, {os.cpu_count()} cores, {jobs} jobs'}


def run_seeded(prog: str, args, run: Callable, unit: str):
    """
    Run a seeded study with a progress bar; return it, or None after printing why not.

    ``args`` holds ``first_seed``, ``seeds`` and ``jobs``; ``run(seeds, jobs,
    progress)`` is the study's own runner and ``unit`` what the bar counts.
    A missing or damaged detector file is one line on stderr, not a traceback.
    """
    from stiction_ros.app.progress import Step, terminal_progress
    from stiction_ros.errors import DetectorFileError
    if args.seeds < 1 or args.jobs < 1 or args.first_seed < 0:
        print(f'{prog}: error: at least 1 seed and 1 job, and a first seed of 0 or more',
              file=sys.stderr)
        return None
    seeds = range(args.first_seed, args.first_seed + args.seeds)
    try:
        with terminal_progress() as say:
            return run(seeds, args.jobs, lambda i, n, s: say(Step(unit, i, n, f'{s:.0f} s')))
    except DetectorFileError as err:
        print(f'{prog}: error: {err}', file=sys.stderr)
        return None
