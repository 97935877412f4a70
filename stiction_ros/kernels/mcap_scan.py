"""
Index the records of a decompressed MCAP chunk in one compiled pass.

A chunk is a run of ``opcode (1 byte) | length (u64) | body`` records; a
Message body is ``channel_id u16 | sequence u32 | log_time u64 |
publish_time u64 | data``.  Parsing each record into a Python object costs
microseconds, so :func:`scan_chunk` only walks the lengths and writes the
message fields into arrays; Schema and Channel records, a few per bag, are
returned by position for ``mcap``'s own parser.  A record that runs past the
end of the chunk stops the scan and is reported, never read.
"""

import numpy as np
from numpy.typing import NDArray

from stiction_ros._jit import njit
from stiction_ros.kernels.arrays import Bytes, Floats, Ints

OP_SCHEMA = 0x03
OP_CHANNEL = 0x04
OP_MESSAGE = 0x05
# opcode + record length + channel id + sequence + log time + publish time
_HEAD = 9
_MSG_FIXED = 2 + 4 + 8 + 8


@njit(cache=True, inline='always')
def _u64(b: Bytes, p: int | np.int64) -> np.uint64:
    v = np.uint64(0)
    for i in range(8):
        v |= np.uint64(b[p + i]) << np.uint64(8 * i)
    return v


@njit(cache=True)
def scan_chunk(b: Bytes) -> tuple[NDArray[np.uint16], Ints, Ints, Ints, Ints, Ints,
                                  int | np.int64]:
    """
    Return ``(channel, log, publish, offset, length, others, end)`` of chunk bytes ``b``.

    The first five are per message (offset and length of its data in ``b``);
    ``others`` is an (n, 3) array of ``opcode, offset of body, body length``
    for every other record; ``end`` is where the scan stopped (``len(b)`` when
    every record was whole).
    """
    n = b.shape[0]
    cap = n // (_HEAD + _MSG_FIXED) + 1
    chan = np.empty(cap, dtype=np.uint16)
    log = np.empty(cap, dtype=np.int64)
    pub = np.empty(cap, dtype=np.int64)
    off = np.empty(cap, dtype=np.int64)
    ln = np.empty(cap, dtype=np.int64)
    others = np.empty((16, 3), dtype=np.int64)
    m = 0
    k = 0
    p: int | np.int64 = 0
    while p + _HEAD <= n:
        op = b[p]
        size = _u64(b, p + 1)
        body = p + _HEAD
        if size > np.uint64(n - body):
            break
        size_i = np.int64(size)
        if op == OP_MESSAGE:
            if size_i < _MSG_FIXED:
                break
            chan[m] = np.uint16(b[body]) | (np.uint16(b[body + 1]) << np.uint16(8))
            log[m] = np.int64(_u64(b, body + 6))
            pub[m] = np.int64(_u64(b, body + 14))
            off[m] = body + _MSG_FIXED
            ln[m] = size_i - _MSG_FIXED
            m += 1
        else:
            if k == others.shape[0]:
                grown = np.empty((2 * k, 3), dtype=np.int64)
                grown[:k] = others
                others = grown
            others[k, 0] = op
            others[k, 1] = body
            others[k, 2] = size_i
            k += 1
        p = body + size_i
    return chan[:m], log[:m], pub[:m], off[:m], ln[:m], others[:k], p


def gather_float64(buf: Bytes, offsets: Ints, lengths: Ints) -> Floats | None:
    """
    Return the float64 of ``std_msgs/Float64`` CDR messages, or None if any is not one.

    Each must be 12 bytes: the little-endian CDR header ``00 01 00 00``, then
    the value (``rclpy.serialization`` writes exactly this).
    """
    if offsets.size == 0:
        return np.empty(0)
    if not np.all(lengths == 12):
        return None
    head = buf[offsets[:, None] + np.arange(4)]
    if not (np.all(head[:, 0] == 0) and np.all(head[:, 1] == 1) and np.all(head[:, 2:] == 0)):
        return None
    raw = buf[offsets[:, None] + 4 + np.arange(8)]
    return np.ascontiguousarray(raw).view('<f8').ravel().copy()
