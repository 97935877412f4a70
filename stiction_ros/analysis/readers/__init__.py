"""
Load a loop recording from a bag, a CSV or a historian export into a :class:`Record`.

The format is detected from the path and the first bytes: a directory
(rosbag2) or an ``.mcap`` file or MCAP magic is a bag, a first line starting
``PROCESSDATA`` is a historian export, anything else is read as CSV.  Every
problem with the input is an :class:`InputError` with a one-line message.
"""

from pathlib import Path

from stiction_ros.analysis.readers.bag_signals import read_bag_record
from stiction_ros.analysis.readers.csv_reader import read_csv_record
from stiction_ros.analysis.readers.historian import is_historian, read_historian_record
from stiction_ros.analysis.record import check_enough, InputError, MIN_VALID, Record

__all__ = ['detect_format', 'InputError', 'load_record', 'Record']

MCAP_MAGIC = b'\x89MCAP'


def detect_format(path):
    """Return ``'bag'``, ``'historian'`` or ``'csv'`` for the input at ``path``."""
    path = Path(path)
    if not path.exists():
        raise InputError(f'{path}: no such file or directory')
    if path.is_dir():
        if (path / 'metadata.yaml').is_file() or any(path.glob('*.mcap')):
            return 'bag'
        raise InputError(f'{path}: a directory without a bag (no metadata.yaml or .mcap file)')
    if path.suffix.lower() == '.mcap':
        return 'bag'
    head = _read(path, 64)
    if not head.strip():
        raise InputError(f'{path}: empty file')
    if head.startswith(MCAP_MAGIC):
        return 'bag'
    if is_historian(head.decode('utf-8', errors='replace')):
        return 'historian'
    return 'csv'


def load_record(path: str | Path, namespace: str | None = None,
                window: tuple[float | None, float | None] | None = None,
                min_valid: int = MIN_VALID) -> Record:
    """
    Return the :class:`Record` of a recording, restricted to ``window`` if given.

    ``namespace`` picks the bag topics (``/loop1`` for ``/loop1/op``; default:
    the one namespace that has an ``op``).  ``window`` is ``(t0, t1)`` in
    seconds from the start (either may be None).  Raises :class:`InputError`
    if the input is unusable or has fewer than ``min_valid`` valid samples.
    """
    path = Path(path)
    kind = detect_format(path)
    if kind == 'bag':
        record = read_bag_record(path, namespace)
    else:
        text, note = _text(path)
        if kind == 'historian':
            record = read_historian_record(path, text)
        else:
            record = read_csv_record(path, text)
        if note:
            record.notes.insert(0, note)
        if namespace is not None:
            record.notes.insert(0, f'namespace {namespace!r} ignored: not a bag')
    if window is not None:
        record = record.window(*window)
    return check_enough(record, min_valid)


def _read(path, size=None):
    try:
        with open(path, 'rb') as f:
            return f.read() if size is None else f.read(size)
    except OSError as err:
        raise InputError(f'{path}: cannot read: {err.strerror or err}') from None


def _text(path):
    data = _read(path)
    if not data.strip():
        raise InputError(f'{path}: empty file')
    if b'\0' in data:
        raise InputError(f'{path}: not a text file (it holds NUL bytes), nor a bag')
    try:
        return data.decode('utf-8-sig'), None
    except UnicodeDecodeError as err:
        where = err.start
    try:
        # historian exports from Chinese-locale systems may be GB18030
        return data.decode('gb18030'), f'read as GB18030: byte {where} is not UTF-8'
    except UnicodeDecodeError:
        raise InputError(f'{path}: not UTF-8 text (byte {where})') from None
