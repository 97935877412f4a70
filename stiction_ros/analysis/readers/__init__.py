"""
Load a loop recording from a bag, a CSV or a historian export into a :class:`Record`.

The format is detected from the path and the first bytes: a directory
(rosbag2) or an ``.mcap`` file or MCAP magic is a bag, a first line starting
``PROCESSDATA`` is a historian export, a spreadsheet (.xlsx, .xls, .ods, by
its bytes) is refused with the fix, anything else is read as CSV.  Every
problem with the input is an :class:`InputError` with a one-line message.
"""

from collections.abc import Mapping
from pathlib import Path

from stiction_ros.analysis.readers.bag_signals import read_bag_record
from stiction_ros.analysis.readers.csv_reader import read_csv_record
from stiction_ros.analysis.readers.historian import is_historian, read_historian_record
from stiction_ros.analysis.readers.sniff import decode, read_bytes, refuse_office_file
from stiction_ros.analysis.record import check_enough, InputError, MIN_VALID, Record

__all__ = ['detect_format', 'InputError', 'load_record', 'Record']

MCAP_MAGIC = b'\x89MCAP'


def detect_format(path: str | Path) -> str:
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
    head = read_bytes(path, 64)
    if not head.strip():
        # Blank lines before the data: the format is in the first bytes that are not blank.
        head = read_bytes(path).lstrip()[:64]
        if not head:
            raise InputError(f'{path}: empty file (no bytes, or blanks only): nothing to '
                             'read; export the recording again')
    if head.startswith(MCAP_MAGIC):
        return 'bag'
    refuse_office_file(path, head)
    if is_historian(head.decode('utf-8', errors='replace')):
        return 'historian'
    return 'csv'


def load_record(path: str | Path, namespace: str | None = None,
                window: tuple[float | None, float | None] | None = None,
                min_valid: int = MIN_VALID, columns: Mapping[str, str] | None = None,
                date_order: str | None = None) -> Record:
    """
    Return the :class:`Record` of a recording, restricted to ``window`` if given.

    ``namespace`` picks the bag topics (``/loop1`` for ``/loop1/op``; default:
    the one namespace that has an ``op``).  ``window`` is ``(t0, t1)`` in
    seconds from the start (either may be None).  ``columns`` maps ``t``,
    ``op``, ``mv``, ``pv``, ``sp``, ``mode`` to the CSV or historian columns that hold
    them (``{'op': 'FIC101.OP'}``), where the names do not say.
    ``date_order`` (``'dmy'`` or ``'mdy'``) orders a CSV's dates where no day
    over 12 does.  Raises
    :class:`InputError` if the input is unusable or has fewer than
    ``min_valid`` valid samples.
    """
    path = Path(path)
    columns = dict(columns) if columns else None
    kind = detect_format(path)
    if kind == 'bag':
        record = read_bag_record(path, namespace)
        if columns:
            record.notes.insert(0, '--columns ignored: a bag holds the topics op, mv, pv, sp '
                                '(pick a loop with --namespace)')
        if date_order:
            record.notes.insert(0, '--date-order ignored: a bag has no dates to read')
    else:
        text, note = decode(path, read_bytes(path))
        if kind == 'historian':
            record = read_historian_record(path, text, columns)
            if date_order:
                record.notes.insert(0, '--date-order ignored: a historian export names its '
                                    'time format in line 1')
        else:
            record = read_csv_record(path, text, columns, date_order)
        if note:
            record.notes.insert(0, note)
        if namespace is not None:
            record.notes.insert(0, f'namespace {namespace!r} ignored: not a bag')
    if window is not None:
        record = record.window(*window)
    return check_enough(record, min_valid)
