"""
A loop node's memory on disk, so that a node killed and restarted continues where it was.

A real valve keeps its position when its positioner restarts, and a real
process keeps running; a simulated one that restarts "at rest" or "at the
operating point" would put a jump into the loop that no plant makes.  So a
node with a ``state_file`` saves its state after every sample and reads it
back at start.

Saving must not cost the sample its timing: writing and renaming a file
took milliseconds here and made the nodes skip samples.  So the file is
memory-mapped and holds two slots; each save copies the state (JSON) into
the older slot, body first and header last, with a sequence number and a
CRC.  A copy into the mapping is in the kernel's page cache at once, so a
SIGKILL loses nothing written, and a save cut short leaves a slot whose CRC
fails while the other slot still holds the previous state.  (The page cache
survives the process, not the machine.)
"""

import json
import mmap
import os
from pathlib import Path
import struct
import zlib

from stiction_ros.errors import StateFileError

MAGIC = b'STIC'
# magic, sequence number, body length, CRC of the body
HEAD = struct.Struct('<4sQII')
MIN_SLOT = 32 * 1024


class StateStore:
    """The state file of one node, open for saving after every sample."""

    def __init__(self, path):
        """Open ``path`` for saving; what it held (read first, if wanted) is cleared."""
        self.path = Path(path)
        self.seq = 0
        self.slot = MIN_SLOT
        fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o644)
        try:
            # Cleared, so that no slot of an older state can outrank the new ones.
            os.ftruncate(fd, 0)
            os.ftruncate(fd, 2 * self.slot)
            self.map = mmap.mmap(fd, 2 * self.slot)
        finally:
            os.close(fd)

    def save(self, doc):
        """Store ``doc`` (JSON-able, finite numbers only) as the newest state."""
        body = json.dumps(doc, allow_nan=False, separators=(',', ':')).encode()
        if HEAD.size + len(body) > self.slot:
            self._grow(HEAD.size + len(body))
        self.seq += 1
        at = (self.seq % 2) * self.slot
        self.map[at + HEAD.size:at + HEAD.size + len(body)] = body
        self.map[at:at + HEAD.size] = HEAD.pack(MAGIC, self.seq, len(body), zlib.crc32(body))

    def _grow(self, need):
        # A new, larger file replaces the old one whole (rename), then is mapped instead.
        slot = max(self.slot, 1 << (need - 1).bit_length())
        tmp = self.path.with_name(self.path.name + '.tmp')
        with open(tmp, 'wb') as f:
            f.truncate(2 * slot)
        os.replace(tmp, self.path)
        self.map.close()
        fd = os.open(self.path, os.O_RDWR)
        try:
            self.map = mmap.mmap(fd, 2 * slot)
        finally:
            os.close(fd)
        self.slot = slot
        self.seq = 0

    def close(self):
        """Release the mapping (the file stays, for a restart)."""
        self.map.close()


def read(path):
    """Return the newest complete state in the file at ``path``, or raise StateFileError."""
    try:
        data = Path(path).read_bytes()
    except OSError as err:
        raise StateFileError(f'{path}: cannot read it ({err.strerror})') from None
    if len(data) < 2 * HEAD.size:
        raise StateFileError(f'{path}: holds no complete saved state')
    best = None
    for at in (0, len(data) // 2):
        magic, seq, size, crc = HEAD.unpack_from(data, at)
        body = data[at + HEAD.size:at + HEAD.size + size]
        if (magic == MAGIC and len(body) == size and zlib.crc32(body) == crc
                and (best is None or seq > best[0])):
            best = (seq, body)
    if best is None:
        raise StateFileError(f'{path}: holds no complete saved state')
    try:
        return json.loads(best[1])
    except (UnicodeDecodeError, json.JSONDecodeError) as err:
        raise StateFileError(f'{path}: the saved state is not JSON ({err})') from None


def load(path, node, sample_time):
    """Return the state saved at ``path`` by ``node``, or None if there is none."""
    path = Path(path)
    if not path.exists():
        return None
    doc = read(path)
    if not isinstance(doc, dict):
        raise StateFileError(f'{path}: not a saved state')
    if doc.get('node') != node:
        raise StateFileError(f'{path}: saved by a {doc.get("node")!r} node, not {node!r}')
    if doc.get('sample_time') != sample_time:
        raise StateFileError(f'{path}: saved at sample time {doc.get("sample_time")}, '
                             f'this node runs at {sample_time}')
    if not isinstance(doc.get('k'), int):
        raise StateFileError(f'{path}: no sample number')
    return doc
