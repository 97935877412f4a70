"""
Read a bag (rosbag2 directory or bare ``.mcap``), tolerating a truncated file.

The file is scanned from the start, so a bag whose recorder was killed
still yields every message of every complete chunk; the result then says
``complete = False`` with a warning instead of failing.  Chunks are indexed
in one compiled pass (``stiction_ros.kernels.mcap_scan``) and messages stay in the
decompressed chunk buffers; ``std_msgs/Float64`` topics decode straight into
numpy, other types through ``mcap_ros2``.
"""

from dataclasses import dataclass, field
from io import BytesIO
import os
from pathlib import Path
import struct
from typing import Any, BinaryIO, Callable, Container, Generator
import zlib

import lz4.frame
from mcap.data_stream import ReadDataStream
from mcap.exceptions import McapError
from mcap.records import (
    Channel, Chunk, ChunkIndex, McapRecord, Message, Metadata, Schema, Statistics)
import numpy as np
from stiction_ros.bag.files import bag_files
from stiction_ros.errors import BagReadError
from stiction_ros.kernels.arrays import Bytes, Floats, Ints
from stiction_ros.kernels.mcap_scan import gather_float64, OP_CHANNEL, OP_SCHEMA, scan_chunk
import yaml
import zstandard

# The largest record or decompressed chunk believed: a bigger length field is corruption
# (rosbag2 and this package write chunks of about 1 MiB), and trusting it would allocate it.
RECORD_LIMIT = 256 * 2**20
# Messages held in a buffer: (buffer, offsets, lengths, log times, publish times).
Segment = tuple[Bytes, Ints, Ints, Ints, Ints]


@dataclass
class Topic:
    """
    The messages of one topic, in the order they were recorded.

    Messages stay where the reader found them: segments of (buffer, offsets,
    lengths) with their times, so a million of them cost a few arrays, not a
    million objects.
    """

    name: str
    type: str  # noqa: A003  (the ROS word for it)
    schema: Schema | None = None
    qos: str = ''
    type_hash: str = ''
    _segments: list[Segment] = field(default_factory=list, repr=False)
    _pending: list[tuple[bytes, int, int]] = field(default_factory=list, repr=False)

    def add(self, buf: Bytes, offsets: Ints, lengths: Ints, log_time: Ints,
            publish_time: Ints) -> None:
        """Append messages held in ``buf`` at ``offsets`` (arrays of equal length)."""
        self._flush()
        if len(offsets):
            self._segments.append((buf, offsets, lengths, log_time, publish_time))

    def adopt(self, other: 'Topic') -> None:
        """Take the messages of ``other`` (found before this topic's channel) first."""
        other._flush()
        self._flush()
        self._segments[:0] = other._segments

    def add_one(self, data: bytes, log_time: int, publish_time: int) -> None:
        """Append one message given as bytes (records outside chunks)."""
        self._pending.append((bytes(data), int(log_time), int(publish_time)))

    def _flush(self) -> None:
        if not self._pending:
            return
        pend, self._pending = self._pending, []
        lengths = np.array([len(d) for d, _, _ in pend], dtype=np.int64)
        offsets = np.concatenate(([0], np.cumsum(lengths)[:-1])).astype(np.int64)
        buf = np.frombuffer(b''.join(d for d, _, _ in pend), dtype=np.uint8)
        self._segments.append((buf, offsets, lengths,
                               np.array([t for _, t, _ in pend], dtype=np.int64),
                               np.array([t for _, _, t in pend], dtype=np.int64)))

    def _column(self, i: int) -> Ints:
        self._flush()
        if not self._segments:
            return np.empty(0, dtype=np.int64)
        return np.concatenate([seg[i] for seg in self._segments])

    @property
    def count(self) -> int:
        """Return the number of messages."""
        return sum(len(seg[1]) for seg in self._segments) + len(self._pending)

    @property
    def log_time(self) -> Ints:
        """Return the log (receive) times in ns, an int64 array."""
        return self._column(3)

    @property
    def publish_time(self) -> Ints:
        """Return the publish (send) times in ns, an int64 array."""
        return self._column(4)

    @property
    def data(self) -> list[bytes]:
        """Return the serialised messages as a list of bytes."""
        self._flush()
        return [buf[o:o + n].tobytes() for buf, offs, lens, _, _ in self._segments
                for o, n in zip(offs.tolist(), lens.tolist())]

    def times(self) -> Floats:
        """Return the log (receive) times in seconds as a numpy array."""
        return self.log_time / 1e9

    def values(self) -> Floats | list[Any]:
        """Return the messages decoded: a float array for Float64, else decoded objects."""
        if self.type == 'std_msgs/msg/Float64':
            self._flush()
            parts = [gather_float64(buf, offs, lens) for buf, offs, lens, _, _ in self._segments]
            if all(p is not None for p in parts):
                # all() has ruled out None, which the checker cannot follow.
                return np.concatenate(parts) if parts else np.empty(0)  # type: ignore[arg-type]
            return np.array([m.data for m in self.decoded()], dtype=np.float64)
        return self.decoded()

    def decoded(self) -> list[Any]:
        """Return every message decoded by ``mcap_ros2`` from the bag's own schema."""
        from mcap_ros2.decoder import DecoderFactory
        if self.schema is None:
            raise BagReadError(f'{self.name}: no schema in the bag; cannot decode')
        decode = DecoderFactory().decoder_for('cdr', self.schema)
        if decode is None:
            # mcap_ros2 decodes ros2msg schemas only (an IDL or JSON one gives no decoder).
            raise BagReadError(
                f'{self.name}: schema {self.schema.name!r} is encoded as '
                f'{self.schema.encoding!r}; only ros2msg schemas (what rosbag2 writes) can be '
                'decoded')
        return [decode(d) for d in self.data]


@dataclass
class Bag:
    """What a bag holds: topics by name, whether the file was complete, warnings."""

    path: Path
    topics: dict[str, Topic]
    complete: bool
    warnings: list[str]
    metadata: dict[str, Any] | None = None

    def topic(self, name: str) -> Topic:
        """Return a topic by exact name, or by its last name component (``op``)."""
        if name in self.topics:
            return self.topics[name]
        hits = [t for n, t in self.topics.items() if n.rsplit('/', 1)[-1] == name.lstrip('/')]
        if len(hits) == 1:
            return hits[0]
        if not hits:
            raise BagReadError(f'{self.path}: no topic {name!r}; topics: {sorted(self.topics)}')
        raise BagReadError(f'{self.path}: {name!r} is ambiguous: {sorted(t.name for t in hits)}')


def read_bag(path: str | os.PathLike[str]) -> Bag:
    """Read every message of a bag; never raise on damage, only on unreadable input."""
    path = Path(path)
    state = _ReadState()
    found = bag_files(path)
    state.warnings.extend(found.notes)
    complete = not found.missing
    for file in found.files:
        n_before = state.count()
        try:
            with open(file, 'rb') as f:
                frames = _Framing(f)
                try:
                    for op, body in frames.records():
                        state.take(file, op, body)
                except (EOFError, ValueError) as err:
                    _rescue(file, frames, state, err)
                    raise
        except OSError as err:
            raise BagReadError(f'{file}: cannot read: {err.strerror or err}') from None
        except (EOFError, ValueError) as err:
            n_file = state.count() - n_before
            if n_file == 0 and not state.channels and not state.orphans:
                raise BagReadError(f'{file}: not a readable MCAP file ({_why(err)}); no '
                                   'message in it can be read: copy or record it again') from None
            complete = False
            state.warnings.append(
                f'{file.name}: file ends early ({_why(err)}); read the {n_file} messages of '
                f'its complete chunks. `stiction-bag repair {path}` rebuilds the index'
                f'{" and metadata.yaml" if path.is_dir() else ""} (the damaged file is kept).')
        stats = state.statistics.pop(file, None)
        if stats is not None and stats != state.count() - n_before:
            complete = False
            state.warnings.append(f'{file.name}: its statistics record counts {stats} '
                                  f'messages, {state.count() - n_before} were read')
    state.finish()
    complete = complete and not state.lost
    meta = None
    if state.metadata:
        try:
            meta = yaml.safe_load(state.metadata)
        except yaml.YAMLError:
            state.warnings.append('rosbag2 metadata record is not valid YAML; ignored')
    return Bag(path=path, topics=state.topics, complete=complete, warnings=state.warnings,
               metadata=meta)


# What a damaged record can raise while it is parsed or decompressed.
_DAMAGE = (McapError, EOFError, ValueError, KeyError, IndexError, struct.error,
           OverflowError, zstandard.ZstdError, RuntimeError, MemoryError)


class _ReadState:
    """Schemas, channels and topics gathered over the files of one bag."""

    schemas: dict[int, Schema]
    channels: dict[int, Topic]
    topics: dict[str, Topic]
    warnings: list[str]
    metadata: str | None
    orphans: dict[int, Topic]
    statistics: dict[Path, int]
    lost: int

    def __init__(self) -> None:
        self.schemas, self.channels, self.topics, self.warnings = {}, {}, {}, []
        self.metadata = None
        # Records skipped as damaged: their messages are gone, so the bag is not complete.
        self.lost = 0
        # Messages whose channel record was lost with a damaged chunk, by channel id:
        # the summary repeats every channel, so they are bound when it comes.
        self.orphans = {}
        self.statistics = {}

    def count(self) -> int:
        return (sum(t.count for t in self.topics.values())
                + sum(t.count for t in self.orphans.values()))

    def take(self, file: Path, op: int, body: bytes) -> None:
        """Parse one record found outside a chunk; a damaged one is skipped with a warning."""
        rec = None
        try:
            rec = _READERS[op](ReadDataStream(BytesIO(body)), len(body)) if op == 0x05 \
                else _READERS[op](ReadDataStream(BytesIO(body)))
            if isinstance(rec, Chunk):
                self.chunk(file, rec)
            elif isinstance(rec, Statistics):
                self.statistics[file] = rec.message_count
            else:
                self.record(file, rec)
        except _DAMAGE as err:
            what = {0x06: 'a chunk', 0x05: 'a message'}.get(op, f'a record (opcode {op:#04x})')
            if isinstance(rec, Chunk):
                # Said by its times, so that the engineer knows which stretch is gone.
                what += (f' (log time {rec.message_start_time * 1e-9:.3f}-'
                         f'{rec.message_end_time * 1e-9:.3f} s)')
            self.lost += 1
            self.warnings.append(f'{file.name}: {what} is damaged ({_why(err)}); skipped, '
                                 'its messages are lost')

    def record(self, file: Path, rec: McapRecord) -> None:
        """Take one parsed record: from outside a chunk, or a schema or channel in one."""
        if isinstance(rec, Message):
            self._topic(file, rec.channel_id).add_one(rec.data, rec.log_time, rec.publish_time)
        elif isinstance(rec, Schema):
            self.schemas.setdefault(rec.id, rec)
        elif isinstance(rec, Channel) and rec.id not in self.channels:
            self.channels[rec.id] = self.topics.setdefault(rec.topic, Topic(
                name=rec.topic, type=getattr(self.schemas.get(rec.schema_id), 'name', ''),
                schema=self.schemas.get(rec.schema_id),
                qos=rec.metadata.get('offered_qos_profiles', ''),
                type_hash=rec.metadata.get('topic_type_hash', '')))
            orphan = self.orphans.pop(rec.id, None)
            if orphan is not None:
                self.channels[rec.id].adopt(orphan)
        elif isinstance(rec, Metadata) and rec.name == 'rosbag2':
            self.metadata = rec.metadata.get('serialized_metadata', self.metadata)

    def chunk(self, file: Path, chunk: Chunk) -> None:
        """Index a chunk's records in one pass; its messages stay in its buffer."""
        data = _decompress(chunk)
        if chunk.uncompressed_crc and zlib.crc32(data) != chunk.uncompressed_crc:
            # None of a damaged chunk's bytes can be trusted, so it is left out whole.
            raise ValueError('its CRC does not match')
        buf = np.frombuffer(data, dtype=np.uint8)
        chan, log, pub, off, ln, others, end = scan_chunk(buf)
        if end != buf.size:
            raise EOFError(f'a record in the chunk at log time {chunk.message_start_time} '
                           'runs past its end')
        # Schemas and channels come before the messages that use them, by the format.
        for op, body, size in others:
            if op in (OP_SCHEMA, OP_CHANNEL):
                stream = ReadDataStream(BytesIO(buf[body:body + size].tobytes()))
                self.record(file, Schema.read(stream) if op == OP_SCHEMA
                            else Channel.read(stream))
        for cid in np.unique(chan):
            sel = np.flatnonzero(chan == cid)
            self._topic(file, int(cid)).add(buf, off[sel], ln[sel], log[sel], pub[sel])

    def _topic(self, file: Path, channel_id: int) -> Topic:
        topic = self.channels.get(channel_id)
        if topic is None:
            topic = self.orphans.setdefault(channel_id, Topic(name=f'channel {channel_id}',
                                                              type=''))
        return topic

    def finish(self) -> None:
        """Warn about messages whose channel never appeared."""
        for cid, topic in sorted(self.orphans.items()):
            self.warnings.append(f'{topic.count} messages on channel {cid}, which no channel '
                                 'record defines (a damaged chunk held it); left out')
        self.orphans = {}


_MAGIC = b'\x89MCAP0\r\n'
# Record readers by opcode; every other record (message indexes, the rest of the summary)
# is skipped: the scan from the start needs none of them, and parsing an index costs per
# message.
_READERS: dict[int, Callable[..., McapRecord]] = {
    0x03: Schema.read, 0x04: Channel.read, 0x05: Message.read, 0x06: Chunk.read,
    0x0B: Statistics.read, 0x0C: Metadata.read}


class _Framing:
    """The records of an MCAP file, and where the last whole one ended."""

    def __init__(self, f: BinaryIO) -> None:
        self.f = f
        self.size = os.fstat(f.fileno()).st_size
        self.good_end = 0

    def records(self) -> Generator[tuple[int, bytes], None, None]:
        """
        Yield ``(opcode, body)`` of the records the reader uses, up to the footer.

        Only the framing is checked here: EOFError where the file ends early,
        ValueError where it is not MCAP or a length field is impossible.
        """
        magic = self.f.read(len(_MAGIC))
        if magic != _MAGIC:
            raise ValueError('no MCAP magic at the start' if magic else 'empty file')
        if not (yield from self.walk(_READERS, self.size)):
            raise EOFError('no footer')

    def walk(self, wanted: Container[int],
             end: int) -> Generator[tuple[int, bytes], None, bool]:
        """
        Yield ``(opcode, body)`` of the ``wanted`` records from here to ``end``.

        Returns True if it stopped at the footer record.
        """
        f = self.f
        self.good_end = f.tell()
        while f.tell() < end:
            head = f.read(9)
            if len(head) < 9:
                raise EOFError('no footer' if not head else 'file ends inside a record header')
            op = head[0]
            length = int.from_bytes(head[1:], 'little')
            _check_length(length, end - f.tell())
            if op == 0x02:
                return True
            if op not in wanted:
                f.seek(length, 1)
            else:
                yield op, f.read(length)
            self.good_end = f.tell()
        return False


def _check_length(length: int, left: int) -> None:
    if length > RECORD_LIMIT:
        raise ValueError(f'a record claims {length} bytes, over the {RECORD_LIMIT}-byte '
                         'limit: the length field is corrupt')
    if length > left:
        # Checked before reading: read(n) allocates n bytes first.
        raise EOFError('file ends inside a record')


def _rescue(file: Path, frames: _Framing, state: _ReadState, err: Exception) -> None:
    """
    Read the chunks after a break in the framing through the summary's chunk index.

    A damaged length field makes the rest of the file unreadable from the
    start, but a whole file ends with a footer that points at a summary
    listing every chunk and channel.  Does nothing if there is none.
    """
    after = frames.good_end
    try:
        summary = _summary(frames)
    except (EOFError, ValueError, struct.error, OverflowError, McapError):
        return
    if summary is None:
        return
    records, chunks = summary
    for op, body in records:
        state.take(file, op, body)
    taken = 0
    for start, length in chunks:
        if start < after:
            continue
        try:
            _check_length(length - 9, frames.size - start - 9)
        except (EOFError, ValueError):
            continue
        frames.f.seek(start + 9)    # the index's length, not the (perhaps damaged) header's
        state.take(file, 0x06, frames.f.read(length - 9))
        taken += 1
    state.warnings.append(f'{file.name}: unreadable from byte {after} ({_why(err)}); read '
                          f'{taken} chunks after it through the summary index')


def _summary(frames: _Framing) -> tuple[list[tuple[int, bytes]], list[tuple[int, int]]] | None:
    """Return the summary's (schema and channel records, chunk (offset, length) list), or None."""
    f = frames.f
    footer_at = frames.size - len(_MAGIC) - 29
    if footer_at < len(_MAGIC):
        return None
    f.seek(footer_at)
    footer = f.read(29 + len(_MAGIC))
    if footer[0] != 0x02 or footer[29:] != _MAGIC:
        return None
    start = int.from_bytes(footer[9:17], 'little')
    if not len(_MAGIC) <= start < footer_at:
        return None
    f.seek(start)
    records, chunks = [], []
    for op, body in frames.walk((0x03, 0x04, 0x08), footer_at):
        if op == 0x08:
            index = ChunkIndex.read(ReadDataStream(BytesIO(body)))
            chunks.append((index.chunk_start_offset, index.chunk_length))
        else:
            records.append((op, body))
    return records, sorted(chunks)


def _decompress(chunk: Chunk) -> bytes:
    size = chunk.uncompressed_size
    if size > RECORD_LIMIT:
        raise ValueError(f'a chunk claims {size} bytes uncompressed, over the '
                         f'{RECORD_LIMIT}-byte limit: the chunk header is corrupt')
    if chunk.compression == '':
        return chunk.data
    # Output in pieces, never past the chunk's stated size: a damaged header could
    # claim terabytes, and both libraries allocate the whole claimed size at once.
    if chunk.compression == 'zstd':
        declared = zstandard.frame_content_size(chunk.data)
        if declared not in (-1, size):
            raise ValueError(f'a zstd frame claims {declared} bytes, the chunk {size}')
        reader = zstandard.ZstdDecompressor().stream_reader(chunk.data)
        return _pieces(lambda n: reader.read(n), size)
    if chunk.compression == 'lz4':
        lz4d = lz4.frame.LZ4FrameDecompressor()
        first = [chunk.data]

        def more(n: int) -> bytes:
            if lz4d.eof:
                return b''
            return lz4d.decompress(first.pop() if first else b'', max_length=n)
        return _pieces(more, size)
    raise ValueError(f'compressed with {chunk.compression!r}, which this reader cannot '
                     'decompress (zstd, lz4 or none)')


def _pieces(read: Callable[[int], bytes], size: int, piece: int = 1 << 20) -> bytes:
    """Return exactly ``size`` bytes from ``read(n)`` calls, or raise ValueError."""
    parts, got = [], 0
    while got <= size:
        part = read(min(piece, size + 1 - got))
        if not part:
            break
        parts.append(part)
        got += len(part)
    if got != size:
        raise ValueError(f'a chunk decompresses to {"more than " if got > size else ""}'
                         f'{got} bytes, its header says {size}')
    return b''.join(parts)


def _why(err: BaseException) -> str:
    text = str(err).strip()
    # The engineer reads what is wrong with the file, not which exception said so.
    if isinstance(err, EOFError):
        return f'cut short: {text}' if text else 'cut short'
    return text or type(err).__name__
