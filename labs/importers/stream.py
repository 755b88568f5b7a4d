"""A long results table read and checked a chunk at a time (docs/interfaces.md §1), no Django.

:func:`parse_table` holds a whole table in memory, which suits one laboratory's
upload. A coordinator's import of a whole round (a million rows) is read from a
stream instead: :func:`read_chunks` yields the rows of ``chunk_rows`` data rows at a
time with their problems, checked by the same column-wise validation
(:func:`labs.importers.columns.check_columns`), so every message is the one an
upload would give. Checks that join chunks (duplicates, completeness) are the
caller's, which knows the participants and the measurement points.
"""

from __future__ import annotations

import codecs
import csv
import io
import itertools
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import BinaryIO

from .columns import check_columns, sheet_columns
from .errors import RowError, fatal
from .readers import (
    _OLE_MAGIC,
    _TEMPLATE_HINT,
    _ZIP_MAGIC,
    XLSX_DAMAGE,
    Shape,
    _blank_row,
    _formula_errors,
    _pick_worksheet,
    _xlsx_records,
    counted_lines,
    csv_records,
    inspect_zip,
    open_workbook,
    sniff_delimiter,
)
from .schema import LabColumn, ResultRow, TableContext
from .table import _gc_paused
from .validate import _error_order, check_header

__all__ = ["Chunk", "read_chunks"]

Records = Iterator[tuple[int, list[object]]]


@dataclass
class Chunk:
    """Good rows of one chunk and the problems of its other rows, in row order."""

    rows: list[ResultRow]
    errors: list[RowError] = field(default_factory=list)
    n_rows: int = 0


def read_chunks(
    stream: BinaryIO,
    *,
    filename: str | None = None,
    lab_column: LabColumn = "required",
    context: TableContext | None = None,
    chunk_rows: int = 50_000,
    limits: bool = True,
) -> Iterator[Chunk]:
    """The data rows of a CSV or XLSX table, ``chunk_rows`` at a time.

    Header problems and unreadable files raise :class:`ImportErrors` before any
    chunk; row numbers are the ones :func:`~labs.importers.parse_table` gives.
    ``limits=False`` (a local file): no size limit on an XLSX workbook's parts.
    """
    head = stream.read(4)
    if (filename or "").lower().endswith((".xlsm", ".xltm", ".xlam")):
        raise fatal("macro-enabled workbooks are refused; save the file as .xlsx or CSV")
    if head.startswith(_OLE_MAGIC):
        raise fatal("legacy .xls workbooks are not supported; save the file as .xlsx or CSV")
    if head.startswith(_ZIP_MAGIC):
        yield from _xlsx_chunks(head + stream.read(), lab_column, context, chunk_rows, limits)
        return
    if (filename or "").lower().endswith(".xlsx"):
        raise fatal("the file name ends in .xlsx but the content is not an XLSX workbook")
    shape = Shape(cap=None)  # a chunk's problems are all counted
    records, decimal_comma = _csv_records(head, stream, shape)
    number, header = _header(records)
    names = check_header(header, lab_column=lab_column, row=number)
    shape.set_header(header, number)
    yield from _chunks(records, names, decimal_comma, lab_column, context, chunk_rows, shape)


def _header(records: Records) -> tuple[int, list[object]]:
    for number, cells in records:
        if not _blank_row(cells):
            return number, cells
    raise fatal(f"the table is empty; {_TEMPLATE_HINT}")


def _chunks(
    records: Records,
    names: list[str],
    decimal_comma: bool,
    lab_column: LabColumn,
    context: TableContext | None,
    chunk_rows: int,
    shape: Shape,
    drain: Callable[[], list[RowError]] = list,
) -> Iterator[Chunk]:
    """``drain`` returns the problems found while reading (XLSX formula cells) since last;
    rows are cut to the header's named cells (``shape``), whose row errors go along."""
    batch: list[tuple[int, list[object]]] = []
    named = [name for name in names if name]
    found: list[RowError] = []
    shape.errors = found
    fit = shape.fit
    for number, cells in records:
        if not _blank_row(cells):
            batch.append((number, fit(number, cells)))
        if len(batch) >= chunk_rows:
            yield _check(batch, named, decimal_comma, lab_column, context, [*found, *drain()])
            batch, shape.errors = [], []
            found = shape.errors
    leftover = [*found, *drain()]
    if batch or leftover:
        yield _check(batch, named, decimal_comma, lab_column, context, leftover)


def _check(
    batch: list[tuple[int, list[object]]],
    names: list[str],
    decimal_comma: bool,
    lab_column: LabColumn,
    context: TableContext | None,
    extra: list[RowError],
) -> Chunk:
    with _gc_paused():
        columns, numbers, errors = sheet_columns(names, batch)
        rows, problems = check_columns(
            columns, numbers, decimal_comma=decimal_comma, lab_column=lab_column, context=context
        )
    errors.extend(problems)
    errors.extend(extra)
    return Chunk(rows, sorted(errors, key=_error_order), len(batch))


# --- CSV -------------------------------------------------------------------------------------


def _csv_records(head: bytes, stream: BinaryIO, shape: Shape) -> tuple[Records, bool]:
    """Records of a UTF-8 CSV stream; the delimiter is sniffed on the first non-empty line."""
    # The 4 bytes already read may hold whole lines (a file that starts with blank lines).
    lines = _lines(itertools.chain(io.BytesIO(head + stream.readline()), stream))
    first: list[str] = []
    for line in lines:
        first.append(line)
        if line.strip():
            break
    delimiter = sniff_delimiter(first[-1] if first else "")
    counted = counted_lines(itertools.chain(first, lines), delimiter, shape)
    reader = csv.reader(counted, delimiter=delimiter, strict=True)
    return csv_records(reader, shape), delimiter == ";"


def _lines(raw_lines: Iterator[bytes]) -> Iterator[str]:
    """Decoded lines (UTF-8, a leading BOM dropped); a bad byte is refused as an upload's is.

    Decoded line by line so that the line and offset of a bad byte are exact; a lone
    ``\r`` ends a line too, as in :func:`labs.importers.readers.read_csv`.
    """
    offset = 0
    for number, raw in enumerate(raw_lines, start=1):
        skip = 3 if number == 1 and raw.startswith(codecs.BOM_UTF8) else 0
        try:
            line = raw[skip:].decode("utf-8")
        except UnicodeDecodeError as error:
            start = skip + error.start
            raise fatal(
                f"the file is not UTF-8 text: byte 0x{raw[start : start + 1].hex()} at offset "
                f"{offset + start} (line {number}); save it as 'CSV UTF-8' or as .xlsx",
                row=number,
            ) from None
        offset += len(raw)
        if "\r" in line.rstrip("\r\n"):
            yield from line.splitlines(keepends=True)
        else:
            yield line


# --- XLSX ------------------------------------------------------------------------------------


def _xlsx_chunks(
    data: bytes,
    lab_column: LabColumn,
    context: TableContext | None,
    chunk_rows: int,
    limits: bool = True,
) -> Iterator[Chunk]:
    """The worksheet read row by row (openpyxl read-only); the ZIP checks of an upload apply."""
    inspect_zip(data, limits=limits)
    workbook = open_workbook(data)
    try:
        found: list[tuple[int, int, str, str]] = []
        shape = Shape(cap=None)  # a chunk's problems are all counted
        records = _xlsx_records(_pick_worksheet(workbook), found, shape)
        number, header = _header(records)
        names = check_header(header, lab_column=lab_column, row=number)
        shape.set_header(header, number)

        def drain() -> list[RowError]:
            errors = _formula_errors(found, header)
            found.clear()
            return errors

        yield from _chunks(records, names, False, lab_column, context, chunk_rows, shape, drain)
    except XLSX_DAMAGE as error:
        raise fatal(f"the worksheet cannot be read: {error}") from None
    finally:
        workbook.close()
