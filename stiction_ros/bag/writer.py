"""
Write a rosbag2 bag directory: ``NAME_0.mcap`` plus ``metadata.yaml``.

What a crash can cost: messages are buffered in the open chunk until it is
full or :meth:`BagWriter.flush_chunk` is called (the recorder calls it on a
timer), then the chunk is compressed, written and flushed to the OS.  A
killed recorder therefore loses only the open chunk; :mod:`.repair` rebuilds
the summary and ``metadata.yaml`` from the chunks on disk.
"""

import os
from pathlib import Path
from typing import Any, Iterable

from mcap.writer import CompressionType, IndexType, Writer
from stiction_ros import __version__
from stiction_ros.bag.metadata import bag_metadata, metadata_yaml, qos_yaml, serialized_metadata
from stiction_ros.bag.msg_definitions import schema_text
from stiction_ros.errors import BagError

COMPRESSION = {'zstd': CompressionType.ZSTD, 'lz4': CompressionType.LZ4,
               'none': CompressionType.NONE}
# Attachments are never written: an attachment index group would be empty,
# which strict validators flag.
INDEXES = IndexType.CHUNK | IndexType.MESSAGE | IndexType.METADATA


class _ChunkWriter(Writer):
    """The ``mcap`` writer, plus closing the open chunk on demand."""

    def close_chunk(self) -> None:
        # mcap 1.6 has no public call for this; its private method is stable
        # across 1.x and the recorder's SIGKILL test fails if it changes.  The
        # type checker sees no name-mangled attributes, hence the ignore.
        self._Writer__finalize_chunk()  # type: ignore[attr-defined]


class BagWriter:
    """A bag being written; add topics, then messages, then :meth:`close`."""

    def __init__(self, directory: str | os.PathLike[str], compression: str = 'zstd',
                 chunk_size: int = 256 * 1024, file_name: str | None = None) -> None:
        if compression not in COMPRESSION:
            raise BagError(f'compression {compression!r}: choose one of {sorted(COMPRESSION)}')
        self.directory = Path(directory)
        if self.directory.exists() and any(self.directory.iterdir()):
            raise BagError(f'{self.directory}: already exists and is not empty; '
                           'choose a new bag directory (nothing is overwritten)')
        try:
            self.directory.mkdir(parents=True, exist_ok=True)
            self.file_name = file_name or f'{self.directory.name}_0.mcap'
            self._file = open(self.directory / self.file_name, 'wb')
        except OSError as err:
            raise BagError(f'{self.directory}: cannot write the bag: {err.strerror}') from None
        self.compression = compression
        self._writer = _ChunkWriter(self._file, chunk_size=int(chunk_size),
                                    compression=COMPRESSION[compression], index_types=INDEXES)
        self._writer.start(profile='ros2', library=f'stiction_ros {__version__} (mcap-python)')
        self._schemas: dict[str, int] = {}
        self.topics: dict[str, dict[str, Any]] = {}
        self._start: int | None = None
        self._end: int | None = None
        self._closed = False
        # metadata.yaml is written now so that the directory is a recognisable
        # bag from the start; the rosbag2 record goes in once, at close
        # (validators warn about two records of the same name).
        self._write_metadata()

    def add_topic(self, name: str, type_name: str, qos_profiles: Iterable[dict[str, Any]],
                  type_hash: str = '', schema_data: bytes | None = None) -> int:
        """
        Register a topic once; return its channel id.

        The schema is the type's installed ``.msg`` text with its dependencies,
        unless ``schema_data`` (bytes, e.g. from another bag) is given.
        """
        if name in self.topics:
            return self.topics[name]['channel']
        if type_name not in self._schemas:
            data = schema_data if schema_data is not None else schema_text(type_name).encode()
            self._schemas[type_name] = self._writer.register_schema(
                name=type_name, encoding='ros2msg', data=data)
        channel = self._writer.register_channel(
            topic=name, message_encoding='cdr', schema_id=self._schemas[type_name],
            metadata={'offered_qos_profiles': qos_yaml(qos_profiles),
                      'topic_type_hash': type_hash})
        self.topics[name] = {'name': name, 'type': type_name, 'qos': list(qos_profiles),
                             'type_hash': type_hash, 'count': 0, 'channel': channel}
        return channel

    def write(self, topic: str, data: bytes, log_time: int,
              publish_time: int | None = None) -> None:
        """Append one CDR-serialised message (bytes) received at ``log_time`` (ns)."""
        entry = self.topics[topic]
        log_time = int(log_time)
        self._writer.add_message(
            channel_id=entry['channel'], log_time=log_time, data=bytes(data),
            publish_time=int(publish_time if publish_time is not None else log_time),
            sequence=entry['count'])
        entry['count'] += 1
        self._start = log_time if self._start is None else min(self._start, log_time)
        self._end = log_time if self._end is None else max(self._end, log_time)

    def flush_chunk(self) -> None:
        """Write the open chunk to disk now (bounds what a crash can lose)."""
        self._writer.close_chunk()
        self._file.flush()

    @property
    def message_count(self) -> int:
        """Return the number of messages written so far."""
        return sum(t['count'] for t in self.topics.values())

    def metadata(self) -> dict[str, Any]:
        """Return the bag metadata mapping for what was written so far."""
        return bag_metadata(self.file_name, list(self.topics.values()), self._start or 0,
                            self._end or 0)

    def _write_metadata(self) -> None:
        meta = self.metadata()
        tmp = self.directory / 'metadata.yaml.tmp'
        tmp.write_text(metadata_yaml(meta), encoding='utf-8')
        os.replace(tmp, self.directory / 'metadata.yaml')

    def close(self) -> None:
        """Finish the MCAP (summary and index) and write the final ``metadata.yaml``."""
        if self._closed:
            return
        self._closed = True
        self._writer.close_chunk()
        self._writer.add_metadata(
            'rosbag2', {'serialized_metadata': serialized_metadata(self.metadata())})
        self._writer.finish()
        self._file.close()
        self._write_metadata()
