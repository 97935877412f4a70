"""
``stiction-precompile``: compile the numba kernels into the cache, once after installing.

tools/bootstrap.sh and ``colcon build`` (setup.py) run it, so that the first
start of a node takes about 1 s, not the 5-10 s of compiling its kernels.
Where the package directory is read-only, numba keeps the cache in
``NUMBA_CACHE_DIR`` (or its per-user default) instead.
"""

import argparse
import sys

from stiction_ros.cli.text import description, pipe_safe


@pipe_safe
def main(argv: list[str] | None = None) -> int:
    """Run the command; return the process exit code."""
    ap = argparse.ArgumentParser(prog='stiction-precompile',
                                 description=description(__doc__))
    ap.parse_args(argv)
    from stiction_ros.app.precompile import precompile

    def say(text: str) -> None:
        print(text, file=sys.stderr)
    total = precompile(say)
    say(f'precompile: done in {total:.1f} s')
    return 0


if __name__ == '__main__':
    sys.exit(main())
