"""
``stiction-precompile``: compile the numba kernels into the cache, once after installing.

tools/bootstrap.sh and ``colcon build`` (setup.py) run it, so that the first
start of a node takes about 1 s, not the 5-10 s of compiling its kernels, and
an analysis starts without numba (kernels built ahead of time).
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
    ap.add_argument('--if-stale', action='store_true',
                    help='only rebuild the ahead-of-time kernels, and only when a kernel '
                         'source changed since they were built')
    ap.add_argument('--development', action='store_true',
                    help="also the simulated corpus's kernels (the detector's training, the "
                         'studies and the tests draw it): tools/bootstrap.sh gives this')
    args = ap.parse_args(argv)

    def say(text: str) -> None:
        print(text, file=sys.stderr)
    if args.if_stale:
        from stiction_ros._jit import ahead_of_time_status
        status = ahead_of_time_status()
        if status == 'fresh' or status.endswith('is set'):
            return 0
        from stiction_ros.app.precompile import build_kernels
        say(f'precompile: built kernels {status.split(" (")[0]}')
        build_kernels(say)
        return 0
    from stiction_ros.app.precompile import precompile
    total = precompile(say, development=args.development)
    say(f'precompile: done in {total:.1f} s')
    return 0


if __name__ == '__main__':
    sys.exit(main())
