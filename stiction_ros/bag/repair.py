"""
Repair a bag whose recorder died: rebuild the MCAP summary and ``metadata.yaml``.

Every message of every complete chunk is copied into a new, finished MCAP
file.  The damaged file is kept next to it (``.damaged``), so a repair never
loses anything, even if it is wrong.
"""

import os
from pathlib import Path
import shutil

from stiction_ros.bag.reader import BagReadError, mcap_files, read_bag
from stiction_ros.bag.writer import BagWriter
import yaml


def repair_bag(path: str | os.PathLike[str], compression: str = 'zstd') -> str:
    """Repair the bag directory ``path`` in place; return a one-line summary."""
    path = Path(path)
    if not path.is_dir():
        raise BagReadError(f'{path}: repair works on a bag directory')
    files = mcap_files(path)
    if len(files) != 1:
        raise BagReadError(f'{path}: repair handles one .mcap file per bag, found {len(files)}')
    bag = read_bag(path)
    if bag.complete and (path / 'metadata.yaml').is_file():
        return f'{path}: complete, {sum(t.count for t in bag.topics.values())} messages; ' \
               'nothing to repair'
    src = files[0]
    tmp = path / '.repair'
    if tmp.exists():
        shutil.rmtree(tmp)
    writer = BagWriter(tmp, compression=compression, file_name=src.name)
    order: list[tuple[int, int, str, bytes]] = []
    for topic in bag.topics.values():
        try:
            qos = yaml.safe_load(topic.qos) if topic.qos else []
        except yaml.YAMLError:
            qos = []
        writer.add_topic(topic.name, topic.type, qos or [], topic.type_hash,
                         schema_data=topic.schema.data if topic.schema is not None else b'')
        order.extend((t, p, topic.name, d) for t, p, d in
                     zip(topic.log_time, topic.publish_time, topic.data))
    order.sort(key=lambda m: m[0])
    for log_time, publish_time, name, data in order:
        writer.write(name, data, log_time, publish_time)
    writer.close()
    damaged = src.with_name(src.name + '.damaged')
    os.replace(src, damaged)
    os.replace(tmp / src.name, src)
    os.replace(tmp / 'metadata.yaml', path / 'metadata.yaml')
    shutil.rmtree(tmp)
    return (f'{path}: recovered {len(order)} messages on {len(bag.topics)} topics; '
            f'the original is kept as {damaged.name}')
