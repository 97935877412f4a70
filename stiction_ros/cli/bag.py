"""
``stiction-bag``: look into a bag, or repair one whose recorder was killed.

Examples::

    stiction-bag info out/demo_bag
    stiction-bag repair out/demo_bag     # rebuilds the index and metadata.yaml

Exit status 2, with one line on stderr, when the bag cannot be read or repaired.
"""

import argparse
import sys

from stiction_ros.bag.reader import BagReadError, read_bag
from stiction_ros.bag.repair import repair_bag
from stiction_ros.bag.writer import BagError
from stiction_ros.cli.text import description, pipe_safe


def info(path):
    """Return a short description of a bag: topics, types, counts, time span."""
    bag = read_bag(path)
    lines = [f'bag: {bag.path} ({"complete" if bag.complete else "INCOMPLETE"})']
    for t in bag.topics.values():
        span = ''
        if t.count:
            times = t.times()
            span = f'  {times[0]:.3f} .. {times[-1]:.3f} s'
        lines.append(f'  {t.name:24} {t.type:28} {t.count:8d} msgs{span}')
    lines += [f'warning: {w}' for w in bag.warnings]
    return '\n'.join(lines)


@pipe_safe
def main(argv=None):
    """Run the command; return the process exit code."""
    ap = argparse.ArgumentParser(prog='stiction-bag', description=description(__doc__))
    sub = ap.add_subparsers(dest='command', required=True)
    sub.add_parser('info', help='topics, types and message counts').add_argument('bag')
    rp = sub.add_parser('repair', help='rebuild the index and metadata.yaml of a killed bag '
                        '(a bag directory, or a bare .mcap file: the index only)')
    rp.add_argument('bag')
    args = ap.parse_args(argv)
    try:
        print(info(args.bag) if args.command == 'info' else repair_bag(args.bag))
    except (BagReadError, BagError) as err:
        print(f'stiction-bag: error: {err}', file=sys.stderr)
        return 2
    return 0


if __name__ == '__main__':
    sys.exit(main())
