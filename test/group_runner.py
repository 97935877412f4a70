"""
Run node commands the way ``ros2 launch`` does, for the shutdown tests.

Usage: ``python group_runner.py SPEC.json RESULT.json``.  SPEC is
``{"nodes": {name: argv}, "logs": DIR or null, "tty": bool}``.

The runner is started as a session leader (``start_new_session``), and the
nodes it starts share its process group, as the processes of one launch do:
a signal to the group, or Ctrl-C on its terminal, reaches all of them at
once.  With ``tty`` the runner's stdin (a pseudo-terminal) becomes the
session's controlling terminal with this group in the foreground, and the
nodes inherit it on stdin, stdout and stderr; else node output goes to
``DIR/NAME.log``.  Like launch, on the first SIGINT or SIGTERM it sends
SIGINT to each node itself, so every node gets the signal twice.  It waits
for every node (after ``deadline`` seconds SIGUSR1, on which a node prints
its stacks, then SIGKILL a second later), writes
``{name: exit code}`` to RESULT and exits 0.
"""

import fcntl
import json
import os
import signal
import subprocess
import sys
import termios
import time


def main(spec_path, result_path, deadline=30.0):
    """Start the nodes, forward the first stop signal, write their exit codes."""
    spec = json.loads(open(spec_path, encoding='utf-8').read())
    got = []
    for signum in (signal.SIGINT, signal.SIGTERM):
        signal.signal(signum, lambda s, f: got.append(s))
    if spec['tty']:
        fcntl.ioctl(0, termios.TIOCSCTTY, 0)
    procs = {}
    for name, argv in spec['nodes'].items():
        if spec['tty']:
            out = None
        else:
            out = open(os.path.join(spec['logs'], f'{name}.log'), 'ab')
        procs[name] = subprocess.Popen(argv, stdin=None if spec['tty'] else subprocess.DEVNULL,
                                       stdout=out, stderr=None if out is None else out)
    stop_at, asked = None, False
    while any(p.poll() is None for p in procs.values()):
        if got and stop_at is None:
            stop_at = time.monotonic()
            for p in procs.values():
                if p.poll() is None:
                    p.send_signal(signal.SIGINT)
        late = stop_at is not None and time.monotonic() > stop_at + deadline
        if late and not asked:
            # A SIGKILL alone would leave no clue of where a node hangs: ask for its stacks.
            asked = True
            for p in procs.values():
                if p.poll() is None:
                    p.send_signal(signal.SIGUSR1)
        if late and time.monotonic() > stop_at + deadline + 1.0:
            for p in procs.values():
                if p.poll() is None:
                    p.kill()
        time.sleep(0.01)
    with open(result_path, 'w', encoding='utf-8') as f:
        json.dump({name: p.returncode for name, p in procs.items()}, f)
    return 0


if __name__ == '__main__':
    sys.exit(main(sys.argv[1], sys.argv[2]))
