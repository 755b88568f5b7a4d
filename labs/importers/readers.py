"""Bytes of a CSV or XLSX file to a header and rows of cells, with the safety checks.

XLSX: the ZIP container is inspected before openpyxl sees it (size, compression
ratio, macros); openpyxl then reads it in read-only mode (defusedxml guards the
XML). Only one worksheet is read: the one named ``results`` (any case) if there
is one, else the first. Other worksheets are never opened. A formula in that
worksheet rejects the file.

Bounded work: a row with more than :data:`MAX_COLUMNS` cells (the most a worksheet can
have) stops the reading at once, before the row is split into cells (CSV) or its
cells parsed (XLSX, read cell by cell). Data rows keep only the cells under the
header's named columns (at most one per column of docs/interfaces.md §1); a row with
values elsewhere gets one error naming its number of cells and the header's.
"""

from __future__ import annotations

import csv
import io
import zipfile
from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from .errors import MAX_LISTED_ERRORS, ImportErrors, RowError, fatal
from .schema import COLUMNS
from .values import display, human_size, is_blank

if TYPE_CHECKING:
    from openpyxl.workbook.workbook import Workbook

MAX_UNCOMPRESSED_BYTES = 50 * 2**20
MAX_COMPRESSION_RATIO = 100
#: Members smaller than this are not judged by their ratio (tiny XML compresses well).
RATIO_CHECK_MIN_BYTES = 2**20
MAX_ZIP_MEMBERS = 10_000
#: A row with more cells than this (the column limit of Excel) is refused at once.
MAX_COLUMNS = 16_384
#: What a damaged worksheet's XML raises while it is read (ParseError is a SyntaxError).
XLSX_DAMAGE = (ValueError, IndexError, KeyError, TypeError, SyntaxError)

_ZIP_MAGIC = b"PK\x03\x04"
_OLE_MAGIC = b"\xd0\xcf\x11\xe0"
_MACRO_SUFFIXES = (".xlsm", ".xltm", ".xlam")
_TEMPLATE_HINT = f"the first row must be the header: {', '.join(COLUMNS)}"


@dataclass
class Sheet:
    """The header row and the non-empty data rows of a table, with sheet row numbers.

    ``header`` is the header row as read; each data row holds only the cells under
    its named (non-blank) cells, in order (a short row may hold fewer).
    """

    header_row: int
    header: list[object]
    rows: list[tuple[int, list[object]]]
    decimal_comma: bool = False
    errors: list[RowError] = field(default_factory=list)
    #: problems counted but not in ``errors`` (past MAX_LISTED_ERRORS)
    dropped: int = 0


HeaderCheck = Callable[[Sequence[object], int], object]


def read_sheet(
    data: bytes,
    *,
    filename: str | None,
    content_type: str | None,
    max_rows: int,
    header_check: HeaderCheck | None = None,
) -> Sheet:
    """Sniff the format from the content (ZIP magic = XLSX) and read the table.

    ``header_check(header, row)`` runs on the header before any data row is read (it
    raises :class:`ImportErrors` for a header that does not fit).
    """
    macro_name = (filename or "").lower().endswith(_MACRO_SUFFIXES)
    if macro_name or "macroenabled" in (content_type or "").lower():
        raise fatal("macro-enabled workbooks are refused; save the file as .xlsx or CSV")
    if data.startswith(_OLE_MAGIC):
        raise fatal("legacy .xls workbooks are not supported; save the file as .xlsx or CSV")
    if data.startswith(_ZIP_MAGIC):
        return read_xlsx(data, max_rows=max_rows, header_check=header_check)
    if (filename or "").lower().endswith(".xlsx"):
        raise fatal("the file name ends in .xlsx but the content is not an XLSX workbook")
    return read_csv(data, max_rows=max_rows, header_check=header_check)


def _blank_row(cells: Sequence[object]) -> bool:
    first = cells[0] if cells else None
    if type(first) is str and first and not first[0].isspace():
        return False  # the usual row: its first cell is plainly not blank
    return all(is_blank(cell) for cell in cells)


def _short(value: object) -> str:
    text = display(value)
    return text if len(text) <= 40 else text[:40] + "…"


class Shape:
    """The header's shape: data rows are cut to the cells under its named columns.

    ``width`` is ``None`` until the header is read. A row's values outside the named
    columns (under a blank header cell, or past the last header cell) give one error
    for the row, which names its number of cells and the header's.
    """

    def __init__(
        self, header_check: HeaderCheck | None = None, cap: int | None = MAX_LISTED_ERRORS
    ) -> None:
        self.header_check = header_check
        self.cap = cap  # row errors and formula cells kept; the rest only counted
        self.width: int | None = None
        self.keep: list[int] = []
        self.plain = True
        self.errors: list[RowError] = []
        self.dropped = 0  # row errors counted past MAX_LISTED_ERRORS (rows come in order)
        self.row = 1  # the row being read, and its cells so far (CSV: delimiters)
        self.cells = 0
        self._keep_set: set[int] = set()
        self.formulas_dropped = 0  # XLSX formula cells counted past MAX_LISTED_ERRORS

    def set_header(self, header: Sequence[object], row: int) -> None:
        if self.header_check is not None:
            self.header_check(header, row)
        self.keep = [i for i, name in enumerate(header) if not is_blank(name)]
        self.width = self.keep[-1] + 1 if self.keep else 0
        self.plain = len(self.keep) == self.width
        self._keep_set = set(self.keep)

    def too_wide(self, row: int, cells: int | None = None) -> ImportErrors:
        """The error that stops reading: ``row`` has more cells than a worksheet can."""
        what = (
            f"a cell in column {cells:,}, past the {MAX_COLUMNS:,} columns a worksheet can have"
            if cells
            else f"more than {MAX_COLUMNS:,} cells, the most a worksheet can have"
        )
        header = "" if self.width is None else f", but the header has {self.width:,} columns"
        return fatal(f"has {what}{header}; the file was not read further", row=row)

    def fit(self, row: int, cells: list[object]) -> list[object]:
        """``cells`` cut to the named columns; values elsewhere are reported."""
        width, n = self.width or 0, len(cells)
        if self.plain and n <= width:
            return cells
        outside = [j for j in range(width, n) if not is_blank(cells[j])]
        if not self.plain:
            inside = [j for j in range(min(n, width)) if j not in self._keep_set]
            outside = [j for j in inside if not is_blank(cells[j])] + outside
        if outside:
            self.outside(row, outside[0], cells[outside[0]], len(outside), outside[-1] + 1)
        if self.plain:
            return cells[:width]
        return [cells[i] if i < n else None for i in self.keep]

    def outside(self, row: int, index: int, value: object, count: int, last: int) -> None:
        """Report the values of ``row`` outside the named columns: the first at ``index``."""
        if self.cap is not None and len(self.errors) >= self.cap:
            self.dropped += 1
            return
        width = self.width or 0
        shown = _short(value)
        if index >= width:
            message = (
                f"has {last:,} cells but the header has {width:,} columns: value {shown!r} "
                f"in column {index + 1} has no header"
            )
        else:
            message = f"value {shown!r} in column {index + 1}, which has no header"
        if count > 1:
            message += f" (nor have {count - 1:,} more values of this row)"
        self.errors.append(RowError(row, None, message))


def _split_header(
    records: Iterable[tuple[int, list[object]]], max_rows: int, shape: Shape
) -> tuple[int, list[object], list[tuple[int, list[object]]]]:
    """The first non-empty row is the header; empty rows are skipped."""
    header: tuple[int, list[object]] | None = None
    rows: list[tuple[int, list[object]]] = []
    fit = shape.fit
    for number, cells in records:
        if _blank_row(cells):
            continue
        if header is None:
            header = (number, cells)
            shape.set_header(cells, number)
            continue
        if len(rows) >= max_rows:
            raise fatal(f"the table has more than {max_rows} data rows, the limit; split it")
        rows.append((number, fit(number, cells)))
    if header is None:
        raise fatal(f"the table is empty; {_TEMPLATE_HINT}")
    return header[0], header[1], rows


# --- CSV -------------------------------------------------------------------------------------


def decode_csv(data: bytes) -> str:
    """UTF-8 with or without BOM; anything else is refused with the offending byte."""
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as error:
        line = data[: error.start].count(b"\n") + 1
        byte = data[error.start : error.start + 1].hex()
        raise fatal(
            f"the file is not UTF-8 text: byte 0x{byte} at offset {error.start} (line {line}); "
            "save it as 'CSV UTF-8' or as .xlsx",
            row=line,
        ) from None


def sniff_delimiter(text: str) -> str:
    """Semicolon or comma, whichever the header line (first non-empty line) uses more."""
    header = next((line for line in text.splitlines() if line.strip()), "")
    unquoted = header.split('"')[::2]
    semicolons = sum(part.count(";") for part in unquoted)
    commas = sum(part.count(",") for part in unquoted)
    return ";" if semicolons > commas else ","


def counted_lines(lines: Iterable[str], delimiter: str, shape: Shape) -> Iterator[str]:
    """``lines`` as they are, refusing a row (lines since ``shape.cells`` was last reset to 0)
    with more than :data:`MAX_COLUMNS` cells before the CSV reader splits it."""
    for line in lines:
        shape.cells += line.count(delimiter)
        if shape.cells >= MAX_COLUMNS:
            raise shape.too_wide(shape.row)
        yield line


def csv_records(reader: Iterator[list[str]], shape: Shape) -> Iterator[tuple[int, list[object]]]:
    """Numbered rows of a reader that reads :func:`counted_lines`; malformed CSV is refused."""
    number = 0
    shape.row, shape.cells = 1, 0
    try:
        # A quoted cell may span lines; a spreadsheet shows it as one row.
        for number, cells in enumerate(reader, start=1):
            shape.row, shape.cells = number + 1, 0
            yield number, list(cells)
    except csv.Error as error:
        raise fatal(f"the CSV is malformed: {error}", row=number + 1) from None


def _csv_records(text: str, delimiter: str, shape: Shape) -> Iterator[tuple[int, list[object]]]:
    lines = counted_lines(io.StringIO(text, newline=""), delimiter, shape)
    return csv_records(csv.reader(lines, delimiter=delimiter, strict=True), shape)


def read_csv(data: bytes, *, max_rows: int, header_check: HeaderCheck | None = None) -> Sheet:
    text = decode_csv(data)
    delimiter = sniff_delimiter(text)
    shape = Shape(header_check)
    records = _csv_records(text, delimiter, shape)
    header_row, header, rows = _split_header(records, max_rows, shape)
    return Sheet(
        header_row, header, rows, delimiter == ";", errors=shape.errors, dropped=shape.dropped
    )


# --- XLSX ------------------------------------------------------------------------------------


def inspect_zip(data: bytes, *, limits: bool = True) -> None:
    """Refuse a ZIP bomb or a macro-enabled workbook before any XML is parsed.

    ``limits=False`` (a local file, read as a stream): only the macros are refused."""
    try:
        with zipfile.ZipFile(io.BytesIO(data)) as archive:
            members = archive.infolist()
    except (zipfile.BadZipFile, ValueError) as error:
        raise fatal(f"the file looks like XLSX but is not a readable workbook: {error}") from None
    if limits:
        _check_sizes(members)
    for member in members:
        if member.filename.lower().endswith("vbaproject.bin"):
            raise fatal(
                f"the workbook contains macros ({member.filename}); save it as .xlsx without macros"
            )


def _check_sizes(members: list[zipfile.ZipInfo]) -> None:
    if len(members) > MAX_ZIP_MEMBERS:
        raise fatal(f"the workbook holds {len(members)} parts; the limit is {MAX_ZIP_MEMBERS}")
    total = sum(member.file_size for member in members)
    if total > MAX_UNCOMPRESSED_BYTES:
        raise fatal(
            f"the workbook unpacks to {human_size(total)}; the limit is "
            f"{human_size(MAX_UNCOMPRESSED_BYTES)}"
        )
    for member in members:
        ratio = member.file_size / max(member.compress_size, 1)
        if member.file_size >= RATIO_CHECK_MIN_BYTES and ratio > MAX_COMPRESSION_RATIO:
            raise fatal(
                f"the workbook part {member.filename} is compressed {ratio:.0f}:1, the mark of "
                f"a ZIP bomb; the limit is {MAX_COMPRESSION_RATIO}:1"
            )


def open_workbook(data: bytes) -> Workbook:
    """The workbook read-only, its worksheets not parsed yet (see :func:`_xlsx_records`).

    openpyxl's ``load_workbook(read_only=True)`` parses every worksheet that lacks a
    ``<dimension>`` element whole, just to size it; the worksheets here are never sized.
    """
    from openpyxl.reader.excel import ExcelReader  # imported here: CSV-only callers do not pay
    from openpyxl.worksheet._read_only import ReadOnlyWorksheet

    class Unsized(ReadOnlyWorksheet):
        def _get_size(self) -> None:
            pass

    class Reader(ExcelReader):
        def read_worksheets(self) -> None:
            for sheet, rel in self.parser.find_sheets():
                if rel.target in self.valid_files and "chartsheet" not in rel.Type:
                    worksheet = Unsized(self.wb, sheet.name, rel.target, self.shared_strings)
                    worksheet.sheet_state = sheet.state
                    self.wb._sheets.append(worksheet)

    try:
        reader = Reader(io.BytesIO(data), read_only=True, data_only=False, keep_links=False)
        reader.read()
    except Exception as error:  # openpyxl raises many types for a damaged file
        raise fatal(f"the workbook cannot be read: {error}") from None
    return reader.wb


def _pick_worksheet(workbook: Workbook) -> object:
    sheets = list(workbook.worksheets)
    if not sheets:
        raise fatal("the workbook has no worksheet")
    named = [ws for ws in sheets if ws.title.strip().lower() == "results"]
    return (named or sheets)[0]


def _xlsx_records(
    worksheet: object, formulas: list[tuple[int, int, str, str]], shape: Shape | None = None
) -> Iterator[tuple[int, list[object]]]:
    """Cell values per row, read cell by cell; formula cells are recorded in ``formulas``
    (the first MAX_LISTED_ERRORS) and read as blank.

    The worksheet's XML is parsed here with openpyxl's own cell parser, each cell as its
    element ends: openpyxl's row reader would parse every cell of a row (millions in a
    hostile file) before handing it over. A row with more than :data:`MAX_COLUMNS`
    cells, or a cell past that column, stops the reading; so a row never holds more
    elements than that. Once ``shape`` knows the header, cells past it are not kept
    (only reported, if not blank).
    """
    # openpyxl only where a workbook is read: CSV-only callers (pt_compare) never load it
    from openpyxl.utils import get_column_letter
    from openpyxl.worksheet._reader import CELL_TAG, ROW_TAG, WorkSheetParser
    from openpyxl.xml.functions import iterparse

    shape = shape or Shape()
    book = worksheet.parent  # type: ignore[attr-defined]
    parser = WorkSheetParser(
        None, worksheet._shared_strings, data_only=False, epoch=book.epoch,  # type: ignore[attr-defined]
        date_formats=book._date_formats, timedelta_formats=book._timedelta_formats,
    )  # fmt: skip
    parse_cell, cap = parser.parse_cell, shape.cap
    last = 0  # rows out of order or repeated are skipped, as openpyxl does
    values: dict[int, object] = {}
    found: list[tuple[int, str | None, str]] = []  # this row's formulas
    count = outside = first_out = last_out = 0
    first_value: object = None
    parser.row_counter = shape.row = 1  # the row of cells without a coordinate (a guess)
    with worksheet._get_source() as source:  # type: ignore[attr-defined]
        for _, element in iterparse(source):
            tag = element.tag
            if tag == CELL_TAG:
                count += 1
                try:
                    cell = parse_cell(element)
                except ValueError:  # a number that is none: its text, checked with its row
                    if (cell := _uncast_cell(parser, element)) is None:  # broken otherwise
                        raise
                column = cell["column"]
                if count > MAX_COLUMNS or column > MAX_COLUMNS:
                    shape.row = cell["row"]
                    raise shape.too_wide(shape.row, column if column > MAX_COLUMNS else None)
                value = cell["value"]
                if cell["data_type"] == "f":
                    found.append((column, element.get("r"), str(value)))
                    value = None
                width = shape.width
                if width is not None and column > width:
                    if not is_blank(value):
                        outside += 1
                        if outside == 1:
                            first_out, first_value = column, value
                        last_out = column if outside == 1 else max(last_out, column)
                    continue
                values[column] = value
            elif tag == ROW_TAG:
                number = _row_number(element.get("r"), last)
                element.clear()
                row_values, row_formulas = values, found
                row_outside, row_first, row_value, row_last = (
                    outside, first_out, first_value, last_out
                )  # fmt: skip
                values, found, count, outside = {}, [], 0, 0
                parser.col_counter, parser.row_counter = 0, number + 1
                if number <= last:
                    continue
                last = shape.row = number
                for column, coordinate, text in row_formulas:
                    if cap is None or len(formulas) < cap:
                        where = coordinate or f"{get_column_letter(column)}{number}"
                        formulas.append((number, column - 1, where, text))
                    else:
                        shape.formulas_dropped += 1
                cells: list[object] = [None] * max(row_values, default=0)
                for column, value in row_values.items():
                    cells[column - 1] = value
                if row_outside:
                    shape.outside(number, row_first - 1, row_value, row_outside, row_last)
                yield number, cells


def _uncast_cell(parser: Any, element: Any) -> dict[str, Any] | None:
    """A numeric cell whose text is no number (``nan``, ``inf``, ``0x10``, which no
    spreadsheet writes) read as that text: the row's checks then name its row and column,
    where openpyxl's cast made the whole worksheet "unreadable".  ``None`` for a cell that
    is not a numeric one with a value (its ``ValueError`` stands)."""
    from openpyxl.worksheet._reader import VALUE_TAG

    if element.get("t", "n") != "n" or element.find(VALUE_TAG) is None:
        return None
    if element.get("r") is None:
        parser.col_counter -= 1  # already counted by the failed parse
    element.set("t", "str")
    return parser.parse_cell(element)


def _row_number(given: str | None, previous: int) -> int:
    """A ``<row r="...">`` number as openpyxl reads it; the next row when absent."""
    if given is None:
        return previous + 1
    try:
        return int(given)
    except ValueError:
        value = float(given)
        if not value.is_integer():
            raise ValueError(f"{given} is not a valid row number") from None
        return int(value)


def _formula_errors(
    formulas: Sequence[tuple[int, int, str, str]], header: Sequence[object]
) -> list[RowError]:
    errors = []
    for number, index, coordinate, text in formulas:
        name = str(header[index]).strip().lower() if index < len(header) and header[index] else None
        errors.append(
            RowError(
                number,
                name if name in COLUMNS else None,
                f"cell {coordinate} contains a formula ({text[:40]}); formulas are refused, "
                "paste the values instead",
            )
        )
    return errors


def read_xlsx(data: bytes, *, max_rows: int, header_check: HeaderCheck | None = None) -> Sheet:
    inspect_zip(data)
    formulas: list[tuple[int, int, str, str]] = []
    shape = Shape(header_check)
    workbook = open_workbook(data)
    try:
        worksheet = _pick_worksheet(workbook)
        records = _xlsx_records(worksheet, formulas, shape)
        header_row, header, rows = _split_header(records, max_rows, shape)
    except XLSX_DAMAGE as error:
        raise fatal(f"the worksheet cannot be read: {error}") from None
    finally:
        workbook.close()
    errors = _formula_errors(formulas, header)
    if errors:
        raise ImportErrors(errors, total=len(errors) + shape.formulas_dropped)
    return Sheet(header_row, header, rows, errors=shape.errors, dropped=shape.dropped)
