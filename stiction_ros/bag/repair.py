"""
Repair a bag whose recorder died: rebuild the MCAP summary and ``metadata.yaml``.

A bare ``.mcap`` file (copied out of its bag, or cut short) is repaired the
same way, without a ``metadata.yaml``.

Every message of every complete chunk is copied into a new, finished MCAP
file.  The damaged file is kept next to it (``.damaged``), so a repair never
loses anything, even if it is wrong.
"""

import os
from pathlib import Path
import shutil

from stiction_ros.bag.files import bag_files
from stiction_ros.bag.reader import BagReadError, read_bag
from stiction_ros.bag.writer import BagWriter
import yaml


def repair_bag(path: str | os.PathLike[str], compression: str = 'zstd') -> str:
    """
    Repair the bag directory or bare ``.mcap`` file ``path`` in place; return a summary.

    A bag directory gets its ``metadata.yaml`` rebuilt too; a bare file has none.
    """
    path = Path(path)
    if not path.exists():
        raise BagReadError(f'{path}: no such file or directory')
    notes: list[str] = []
    if path.is_file() and path.suffix.lower() == '.mcap':
        folder, files = path.parent, [path]
        tmp = folder / f'.repair-{path.name}'
    elif path.is_dir():
        found = bag_files(path)
        folder, files, notes = path, found.files, found.notes
        tmp = path / '.repair'
    else:
        raise BagReadError(f'{path}: repair works on a bag directory or an .mcap file')
    if len(files) != 1:
        raise BagReadError(f'{path}: repair handles one .mcap file per bag, found {len(files)}')
    bag = read_bag(path)
    if bag.complete and not notes and (path.is_file() or (path / 'metadata.yaml').is_file()):
        return f'{path}: complete, {sum(t.count for t in bag.topics.values())} messages; ' \
               'nothing to repair'
    src = files[0]
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
    # A second repair keeps the first original too: the next free name.
    damaged = src.with_name(src.name + '.damaged')
    k = 1
    while damaged.exists():
        k += 1
        damaged = src.with_name(f'{src.name}.damaged{k}')
    os.replace(src, damaged)
    os.replace(tmp / src.name, src)
    if path.is_dir():
        os.replace(tmp / 'metadata.yaml', folder / 'metadata.yaml')
    shutil.rmtree(tmp)
    said = ''.join(f'; {note}' for note in notes)
    return (f'{path}: recovered {len(order)} messages on {len(bag.topics)} topics; '
            f'the original is kept as {damaged.name}{said} (the new metadata.yaml names '
            'only the files present)' if notes else
            f'{path}: recovered {len(order)} messages on {len(bag.topics)} topics; '
            f'the original is kept as {damaged.name}')
