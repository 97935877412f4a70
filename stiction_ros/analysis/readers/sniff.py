"""
Tell spreadsheets from recordings by their first bytes, and decode a text file.

A spreadsheet is refused with the fix, whatever its name: an .xlsx is a zip
(``PK``) holding ``xl/workbook.xml``, an .ods a zip whose ``mimetype`` says
so, an .xls an OLE2 compound file (``D0 CF 11 E0``) with a ``Workbook``
stream.  openpyxl, which could read .xlsx, is not a dependency of this
package, and the sheet's dates would need its number formats; a CSV saved
from the sheet has neither problem.  Text is UTF-8 (a byte-order mark
allowed), UTF-16 with its mark (Excel's "Unicode Text"), or GB18030
(historian exports from Chinese-locale systems), with a note.
"""

import codecs
import zipfile

from stiction_ros.errors import InputError

ZIP = b'PK\x03\x04'
OLE2 = b'\xd0\xcf\x11\xe0\xa1\xb1\x1a\xe1'
# The fix for any workbook, here and in a batch that lists one it will not read.
AS_CSV = 'as CSV (File > Save As > CSV UTF-8)'
EXCEL = f'is an Excel workbook: save the sheet {AS_CSV} and pass that file'
ODS_TYPE = b'application/vnd.oasis.opendocument.spreadsheet'


def read_bytes(path: object, size: int | None = None) -> bytes:
    """Return the file's bytes (the first ``size`` only if given); InputError if unreadable."""
    try:
        with open(path, 'rb') as f:
            return f.read() if size is None else f.read(size)
    except OSError as err:
        raise InputError(f'{path}: cannot read: {err.strerror or err}') from None


def refuse_office_file(path: object, head: bytes) -> None:
    """Raise :class:`InputError` with the fix if ``head`` starts a spreadsheet or other archive."""
    if head.startswith(ZIP):
        try:
            with zipfile.ZipFile(path) as z:
                names = set(z.namelist())
                kind = z.read('mimetype')[:80] if 'mimetype' in names else b''
        except (zipfile.BadZipFile, OSError, KeyError, RuntimeError):
            raise InputError(f'{path}: a damaged zip archive (an .xlsx?), not a recording; if it '
                             'is a workbook, open it, save the sheet as CSV and pass that '
                             'file') from None
        if 'xl/workbook.xml' in names:
            raise InputError(f'{path} {EXCEL}')
        if kind.startswith(ODS_TYPE):
            raise InputError(f'{path} is an OpenDocument spreadsheet: save the sheet as CSV '
                             '(File > Save As > Text CSV) and pass that file')
        raise InputError(f'{path}: a zip archive, not a recording: extract it and pass the '
                         'CSV or bag inside')
    if head.startswith(OLE2):
        data = read_bytes(path)
        if 'Workbook'.encode('utf-16-le') in data or 'Book'.encode('utf-16-le') in data:
            raise InputError(f'{path} {EXCEL}')
        raise InputError(f'{path}: an old Microsoft Office document (OLE2), not a recording: '
                         'export the data as CSV and pass that file')


def decode(path: object, data: bytes) -> tuple[str, str | None]:
    """Return ``(text, note)`` of a text file's bytes; ``note`` says if not UTF-8."""
    if not data.strip():
        raise InputError(f'{path}: empty file (no bytes, or blanks only): nothing to read; '
                         'export the recording again')
    for bom, codec in ((codecs.BOM_UTF16_LE, 'utf-16-le'), (codecs.BOM_UTF16_BE, 'utf-16-be')):
        if data.startswith(bom):
            try:
                text = data[len(bom):].decode(codec)
            except UnicodeDecodeError as err:
                raise InputError(f'{path}: not UTF-16 text after its byte-order mark (byte '
                                 f'{err.start + len(bom)}); save it as CSV UTF-8') from None
            if '\0' in text:
                break
            return text, None
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
