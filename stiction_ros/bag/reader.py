"""
Read a bag (rosbag2 directory or bare ``.mcap``), tolerating a truncated file.

The file is scanned from the start, so a bag whose recorder was killed
still yields every message of every complete chunk; the result then says
``complete = False`` with a warning instead of failing.  Chunks are indexed
in one compiled pass (``chunk_scan.py``) and messages stay in the
decompressed chunk buffers; ``std_msgs/Float64`` topics decode straight into
numpy, other types through ``mcap_ros2``.
"""

from dataclasses import dataclass, field
from io import BytesIO
from pathlib import Path
import struct

import lz4.frame
from mcap.data_stream import ReadDataStream
from mcap.exceptions import McapError
from mcap.records import Channel, Chunk, Footer, Message, Metadata, Schema
import numpy as np
from stiction_ros.bag.chunk_scan import gather_float64, OP_CHANNEL, OP_SCHEMA, scan_chunk
import yaml
import zstandard

RECORD_LIMIT = 256 * 2**20


class BagReadError(ValueError):
    """The input is not a readable bag; the message names the file and the problem."""


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
    schema: object = None
    qos: str = ''
    type_hash: str = ''
    _segments: list = field(default_factory=list, repr=False)
    _pending: list = field(default_factory=list, repr=False)

    def add(self, buf, offsets, lengths, log_time, publish_time):
        """Append messages held in ``buf`` at ``offsets`` (arrays of equal length)."""
        self._flush()
        if len(offsets):
            self._segments.append((buf, offsets, lengths, log_time, publish_time))

    def add_one(self, data, log_time, publish_time):
        """Append one message given as bytes (records outside chunks)."""
        self._pending.append((bytes(data), int(log_time), int(publish_time)))

    def _flush(self):
        if not self._pending:
            return
        pend, self._pending = self._pending, []
        lengths = np.array([len(d) for d, _, _ in pend], dtype=np.int64)
        offsets = np.concatenate(([0], np.cumsum(lengths)[:-1])).astype(np.int64)
        buf = np.frombuffer(b''.join(d for d, _, _ in pend), dtype=np.uint8)
        self._segments.append((buf, offsets, lengths,
                               np.array([t for _, t, _ in pend], dtype=np.int64),
                               np.array([t for _, _, t in pend], dtype=np.int64)))

    def _column(self, i):
        self._flush()
        if not self._segments:
            return np.empty(0, dtype=np.int64)
        return np.concatenate([seg[i] for seg in self._segments])

    @property
    def count(self):
        """Return the number of messages."""
        return sum(len(seg[1]) for seg in self._segments) + len(self._pending)

    @property
    def log_time(self):
        """Return the log (receive) times in ns, an int64 array."""
        return self._column(3)

    @property
    def publish_time(self):
        """Return the publish (send) times in ns, an int64 array."""
        return self._column(4)

    @property
    def data(self):
        """Return the serialised messages as a list of bytes."""
        self._flush()
        return [buf[o:o + n].tobytes() for buf, offs, lens, _, _ in self._segments
                for o, n in zip(offs.tolist(), lens.tolist())]

    def times(self):
        """Return the log (receive) times in seconds as a numpy array."""
        return self.log_time / 1e9

    def values(self):
        """Return the messages decoded: a float array for Float64, else decoded objects."""
        if self.type == 'std_msgs/msg/Float64':
            self._flush()
            parts = [gather_float64(buf, offs, lens) for buf, offs, lens, _, _ in self._segments]
            if all(p is not None for p in parts):
                return np.concatenate(parts) if parts else np.empty(0)
            return np.array([m.data for m in self.decoded()], dtype=np.float64)
        return self.decoded()

    def decoded(self):
        """Return every message decoded by ``mcap_ros2`` from the bag's own schema."""
        from mcap_ros2.decoder import DecoderFactory
        if self.schema is None:
            raise BagReadError(f'{self.name}: no schema in the bag; cannot decode')
        decode = DecoderFactory().decoder_for('cdr', self.schema)
        return [decode(d) for d in self.data]


@dataclass
class Bag:
    """What a bag holds: topics by name, whether the file was complete, warnings."""

    path: Path
    topics: dict
    complete: bool
    warnings: list
    metadata: dict = None

    def topic(self, name):
        """Return a topic by exact name, or by its last name component (``op``)."""
        if name in self.topics:
            return self.topics[name]
        hits = [t for n, t in self.topics.items() if n.rsplit('/', 1)[-1] == name.lstrip('/')]
        if len(hits) == 1:
            return hits[0]
        if not hits:
            raise BagReadError(f'{self.path}: no topic {name!r}; topics: {sorted(self.topics)}')
        raise BagReadError(f'{self.path}: {name!r} is ambiguous: {sorted(t.name for t in hits)}')


def mcap_files(path):
    """Return the MCAP files of a bag directory (in order) or ``[path]`` for a file."""
    path = Path(path)
    if not path.exists():
        raise BagReadError(f'{path}: no such file or directory')
    if path.is_file():
        return [path]
    meta = path / 'metadata.yaml'
    if meta.is_file():
        try:
            info = yaml.safe_load(meta.read_text(encoding='utf-8'))['rosbag2_bagfile_information']
            files = [path / f for f in info['relative_file_paths']]
            if files and all(f.is_file() for f in files):
                return files
        except (yaml.YAMLError, KeyError, TypeError):
            pass
    files = sorted(path.glob('*.mcap'))
    if not files:
        raise BagReadError(f'{path}: no .mcap file in this directory')
    return files


def read_bag(path):
    """Read every message of a bag; never raise on truncation, only on unreadable input."""
    path = Path(path)
    state = _ReadState()
    complete = True
    for file in mcap_files(path):
        n_before = state.count()
        try:
            with open(file, 'rb') as f:
                footer = False
                for rec in _records(f):
                    if isinstance(rec, Chunk):
                        state.chunk(file, rec)
                    elif isinstance(rec, Footer):
                        footer = True
                    else:
                        state.record(file, rec)
            if not footer:
                raise EOFError('no footer')
        except OSError as err:
            raise BagReadError(f'{file}: cannot read: {err.strerror or err}') from None
        except (McapError, EOFError, ValueError, KeyError, IndexError, struct.error) as err:
            if isinstance(err, BagReadError):
                raise
            n_file = state.count() - n_before
            if n_file == 0 and not state.channels:
                raise BagReadError(f'{file}: not a readable MCAP file ({_why(err)})') from None
            complete = False
            state.warnings.append(
                f'{file.name}: file ends early ({_why(err)}); read the {n_file} messages of '
                'its complete chunks. `stiction-bag repair` fixes the index.')
    meta = None
    if state.metadata:
        try:
            meta = yaml.safe_load(state.metadata)
        except yaml.YAMLError:
            state.warnings.append('rosbag2 metadata record is not valid YAML; ignored')
    return Bag(path=path, topics=state.topics, complete=complete, warnings=state.warnings,
               metadata=meta)


class _ReadState:
    """Schemas, channels and topics gathered over the files of one bag."""

    def __init__(self):
        self.schemas, self.channels, self.topics, self.warnings = {}, {}, {}, []
        self.metadata = None

    def count(self):
        return sum(t.count for t in self.topics.values())

    def record(self, file, rec):
        """Take one record found outside a chunk."""
        if isinstance(rec, Message):
            self._topic(file, rec.channel_id).add_one(rec.data, rec.log_time, rec.publish_time)
        elif isinstance(rec, Schema):
            self.schemas[rec.id] = rec
        elif isinstance(rec, Channel) and rec.id not in self.channels:
            self.channels[rec.id] = self.topics.setdefault(rec.topic, Topic(
                name=rec.topic, type=getattr(self.schemas.get(rec.schema_id), 'name', ''),
                schema=self.schemas.get(rec.schema_id),
                qos=rec.metadata.get('offered_qos_profiles', ''),
                type_hash=rec.metadata.get('topic_type_hash', '')))
        elif isinstance(rec, Metadata) and rec.name == 'rosbag2':
            self.metadata = rec.metadata.get('serialized_metadata', self.metadata)

    def chunk(self, file, chunk):
        """Index a chunk's records in one pass; its messages stay in its buffer."""
        buf = np.frombuffer(_decompress(file, chunk), dtype=np.uint8)
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

    def _topic(self, file, channel_id):
        topic = self.channels.get(channel_id)
        if topic is None:
            raise BagReadError(f'{file}: message on unknown channel {channel_id}')
        return topic


_MAGIC = b'\x89MCAP0\r\n'
# Record readers by opcode; every other record (message indexes, the summary) is skipped:
# the scan from the start needs none of them, and parsing an index costs per message.
_READERS = {0x03: Schema.read, 0x04: Channel.read, 0x06: Chunk.read, 0x0C: Metadata.read,
            0x02: Footer.read}


def _records(f):
    """Yield the records of an MCAP file from the start; raise EOFError where it ends early."""
    magic = f.read(len(_MAGIC))
    if magic != _MAGIC:
        raise ValueError('no MCAP magic at the start' if magic else 'empty file')
    while True:
        head = f.read(9)
        if len(head) < 9:
            raise EOFError('no footer' if not head else 'file ends inside a record header')
        op = head[0]
        length = int.from_bytes(head[1:], 'little')
        if length > RECORD_LIMIT:
            raise ValueError(f'a record claims {length} bytes, over the {RECORD_LIMIT}-byte '
                             'limit: the length field is corrupt')
        if op != 0x05 and op not in _READERS:
            f.seek(length, 1)
            continue
        body = f.read(length)
        if len(body) < length:
            raise EOFError('file ends inside a record')
        stream = ReadDataStream(BytesIO(body))
        rec = Message.read(stream, length) if op == 0x05 else _READERS[op](stream)
        yield rec
        if op == 0x02:
            return


def _decompress(file, chunk):
    if chunk.compression == '':
        return chunk.data
    if chunk.compression == 'zstd':
        return zstandard.decompress(chunk.data, chunk.uncompressed_size)
    if chunk.compression == 'lz4':
        return lz4.frame.decompress(chunk.data)
    raise BagReadError(f'{file}: chunks compressed with {chunk.compression!r}, which this '
                       'reader cannot decompress (zstd, lz4 or none)')


def _why(err):
    text = str(err).strip()
    return f'{type(err).__name__}: {text}' if text else type(err).__name__
