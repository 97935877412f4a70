"""
Which MCAP files a bag holds, in the order to read them.

A rosbag2 directory names its files in ``metadata.yaml``; without it (a
recorder killed before writing it) the files are taken in rosbag2's own
numbering, ``NAME_0`` .. ``NAME_11``, not in the order of their names as text.
Whatever ``metadata.yaml`` says, every ``.mcap`` file in the directory is read,
so that a file it leaves out is not lost; where it disagrees with the folder
(unreadable, a file missing, a file it does not name) a note says so.
"""

from dataclasses import dataclass, field
import os
from pathlib import Path

from stiction_ros.errors import BagReadError
import yaml


@dataclass
class BagFiles:
    """The files of a bag in reading order, and what ``metadata.yaml`` got wrong."""

    files: list[Path]
    notes: list[str] = field(default_factory=list)
    missing: list[str] = field(default_factory=list)


def mcap_files(path: str | os.PathLike[str]) -> list[Path]:
    """Return the MCAP files of a bag directory (in order) or ``[path]`` for a file."""
    return bag_files(path).files


def bag_files(path: str | os.PathLike[str]) -> BagFiles:
    """
    Return the MCAP files of a bag directory or ``[path]`` for a file, with notes.

    ``missing`` names the files ``metadata.yaml`` lists that the directory lacks:
    their messages are gone, so the bag is not complete.
    """
    path = Path(path)
    if not path.exists():
        raise BagReadError(f'{path}: no such file or directory')
    if path.is_file():
        return BagFiles([path])
    # rosbag2 numbers a split bag's files NAME_0 .. NAME_11: in that order, not as text.
    # Hidden files are not the recorder's: macOS leaves ._NAME.mcap beside a copied file.
    present = sorted((f for f in path.glob('*.mcap')
                      if f.is_file() and not f.name.startswith('.')), key=_split_order)
    meta = path / 'metadata.yaml'
    if not meta.is_file():
        if not present:
            raise BagReadError(f'{path}: no .mcap file in this directory')
        return BagFiles(present)
    named, why = _named(meta)
    if named is None:
        if not present:
            raise BagReadError(f'{path}: no .mcap file in this directory, and its '
                               f'metadata.yaml is {why}')
        return BagFiles(present, [f'metadata.yaml is {why}; read the {len(present)} .mcap '
                                  "file(s) in the folder in rosbag2's numbering"])
    out = BagFiles([])
    for name in named:
        f = path / name
        if Path(name).is_absolute() or '..' in Path(name).parts:
            # A metadata.yaml that names ../../etc/passwd (damaged or hostile) must not
            # make the reader open it.  The name is checked, not where it leads: a bag's
            # files may be links into a store (git-annex, DVC).
            out.notes.append(f'metadata.yaml names {name!r}, outside the bag; not read')
        elif not f.is_file():
            out.missing.append(name)
        elif f not in out.files:
            out.files.append(f)
    if out.missing:
        out.notes.append(f'metadata.yaml names {", ".join(out.missing)}, not in the bag: '
                         'its messages are missing')
    extra = [f for f in present if f not in out.files]
    if extra:
        out.notes.append(f'{", ".join(f.name for f in extra)} in the folder, not named in '
                         'metadata.yaml; read after the files it names')
        out.files.extend(extra)
    if not out.files:
        raise BagReadError(f'{path}: no .mcap file in this directory'
                           + (f' ({out.notes[0]})' if out.notes else ''))
    return out


def _named(meta: Path) -> tuple[list[str] | None, str]:
    """Return the file names ``metadata.yaml`` lists, or None and why it cannot be read."""
    try:
        doc = yaml.safe_load(meta.read_text(encoding='utf-8'))
    except UnicodeDecodeError:
        return None, 'not UTF-8 text'
    except yaml.YAMLError:
        return None, 'not valid YAML'
    except OSError as err:
        return None, f'unreadable ({err.strerror or err})'
    info = doc.get('rosbag2_bagfile_information') if isinstance(doc, dict) else None
    names = info.get('relative_file_paths') if isinstance(info, dict) else None
    if not isinstance(names, list) or not names \
            or not all(isinstance(n, str) and n for n in names):
        return None, 'not rosbag2 metadata (no list of relative_file_paths)'
    return names, ''


def _split_order(file: Path) -> tuple:
    """Return a sort key that puts ``x_2.mcap`` before ``x_10.mcap``."""
    stem, _, index = file.stem.rpartition('_')
    return (stem, int(index), '') if stem and index.isdigit() else (file.stem, -1, file.name)
