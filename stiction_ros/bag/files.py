"""
Which MCAP files a bag holds, in the order to read them.

A rosbag2 directory names its files in ``metadata.yaml``; without it (a
recorder killed before writing it) the files are taken in rosbag2's own
numbering, ``NAME_0`` .. ``NAME_11``, not in the order of their names as text.
"""

import os
from pathlib import Path

from stiction_ros.errors import BagReadError
import yaml


def mcap_files(path: str | os.PathLike[str]) -> list[Path]:
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
            # Only files inside the bag: a metadata.yaml that names ../../etc/passwd
            # (damaged or hostile) must not make the reader open it.
            inside = path.resolve()
            if files and all(f.is_file() and f.resolve().is_relative_to(inside) for f in files):
                return files
        except (yaml.YAMLError, KeyError, TypeError, UnicodeDecodeError):
            pass
    # rosbag2 numbers a split bag's files NAME_0 .. NAME_11: in that order, not as text.
    files = sorted(path.glob('*.mcap'), key=_split_order)
    if not files:
        raise BagReadError(f'{path}: no .mcap file in this directory')
    return files


def _split_order(file: Path) -> tuple:
    """Return a sort key that puts ``x_2.mcap`` before ``x_10.mcap``."""
    stem, _, index = file.stem.rpartition('_')
    return (stem, int(index), '') if stem and index.isdigit() else (file.stem, -1, file.name)
