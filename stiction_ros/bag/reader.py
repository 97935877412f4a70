"""
Read a bag (rosbag2 directory or bare ``.mcap``), tolerating a truncated file.

The file is scanned from the start, so a bag whose recorder was killed
still yields every message of every complete chunk; the result then says
``complete = False`` with a warning instead of failing.  ``std_msgs/Float64``
topics decode straight into numpy; other types through ``mcap_ros2``.
"""

from dataclasses import dataclass, field
from pathlib import Path
import struct

from mcap.exceptions import McapError
from mcap.records import Channel, Footer, Message, Metadata, Schema
from mcap.stream_reader import StreamReader
import numpy as np
import yaml

# Little-endian CDR encapsulation header, then the float64 at offset 4.
_CDR_LE = b'\x00\x01\x00\x00'
RECORD_LIMIT = 256 * 2**20


class BagReadError(ValueError):
    """The input is not a readable bag; the message names the file and the problem."""


@dataclass
class Topic:
    """The messages of one topic, in the order they were recorded."""

    name: str
    type: str  # noqa: A003  (the ROS word for it)
    schema: object = None
    qos: str = ''
    type_hash: str = ''
    log_time: list = field(default_factory=list)
    publish_time: list = field(default_factory=list)
    data: list = field(default_factory=list)

    @property
    def count(self):
        """Return the number of messages."""
        return len(self.data)

    def times(self):
        """Return the log (receive) times in seconds as a numpy array."""
        return np.asarray(self.log_time, dtype=np.int64) / 1e9

    def values(self):
        """Return the messages decoded: a float array for Float64, else decoded objects."""
        if self.type == 'std_msgs/msg/Float64':
            if all(len(d) == 12 and d[:4] == _CDR_LE for d in self.data):
                raw = np.frombuffer(b''.join(self.data), dtype=np.dtype(
                    [('head', 'V4'), ('value', '<f8')]))
                return raw['value'].copy()
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
    schemas, channels, topics, warnings = {}, {}, {}, []
    complete, metadata = True, None
    for file in mcap_files(path):
        n_before = sum(t.count for t in topics.values())
        try:
            with open(file, 'rb') as f:
                footer = False
                for rec in StreamReader(f, record_size_limit=RECORD_LIMIT).records:
                    if isinstance(rec, Message):
                        topic = channels.get(rec.channel_id)
                        if topic is None:
                            raise BagReadError(f'{file}: message on unknown channel '
                                               f'{rec.channel_id}')
                        topic.log_time.append(rec.log_time)
                        topic.publish_time.append(rec.publish_time)
                        topic.data.append(rec.data)
                    elif isinstance(rec, Schema):
                        schemas[rec.id] = rec
                    elif isinstance(rec, Channel) and rec.id not in channels:
                        channels[rec.id] = topics.setdefault(rec.topic, Topic(
                            name=rec.topic, type=getattr(schemas.get(rec.schema_id), 'name', ''),
                            schema=schemas.get(rec.schema_id),
                            qos=rec.metadata.get('offered_qos_profiles', ''),
                            type_hash=rec.metadata.get('topic_type_hash', '')))
                    elif isinstance(rec, Metadata) and rec.name == 'rosbag2':
                        metadata = rec.metadata.get('serialized_metadata', metadata)
                    elif isinstance(rec, Footer):
                        footer = True
            if not footer:
                raise EOFError('no footer')
        except OSError as err:
            raise BagReadError(f'{file}: cannot read: {err.strerror or err}') from None
        except (McapError, EOFError, ValueError, KeyError, IndexError, struct.error) as err:
            if isinstance(err, BagReadError):
                raise
            n_file = sum(t.count for t in topics.values()) - n_before
            if n_file == 0 and not channels:
                raise BagReadError(f'{file}: not a readable MCAP file ({_why(err)})') from None
            complete = False
            warnings.append(f'{file.name}: file ends early ({_why(err)}); read the {n_file} '
                            'messages of its complete chunks. `stiction-bag repair` fixes '
                            'the index.')
    meta = None
    if metadata:
        try:
            meta = yaml.safe_load(metadata)
        except yaml.YAMLError:
            warnings.append('rosbag2 metadata record is not valid YAML; ignored')
    return Bag(path=path, topics=topics, complete=complete, warnings=warnings, metadata=meta)


def _why(err):
    text = str(err).strip()
    return f'{type(err).__name__}: {text}' if text else type(err).__name__
