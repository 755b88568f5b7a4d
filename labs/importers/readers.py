"""Bytes of a CSV or XLSX file to a header and rows of cells, with the safety checks.

XLSX: the ZIP container is inspected before openpyxl sees it (size, compression
ratio, macros); openpyxl then reads it in read-only mode (defusedxml guards the
XML). Only one worksheet is read: the one named ``results`` (any case) if there
is one, else the first. Other worksheets are never opened. A formula in that
worksheet rejects the file.
"""

from __future__ import annotations

import csv
import io
import zipfile
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass, field

from .errors import ImportErrors, RowError, fatal
from .schema import COLUMNS
from .values import human_size, is_blank

MAX_UNCOMPRESSED_BYTES = 50 * 2**20
MAX_COMPRESSION_RATIO = 100
#: Members smaller than this are not judged by their ratio (tiny XML compresses well).
RATIO_CHECK_MIN_BYTES = 2**20
MAX_ZIP_MEMBERS = 10_000

_ZIP_MAGIC = b"PK\x03\x04"
_OLE_MAGIC = b"\xd0\xcf\x11\xe0"
_MACRO_SUFFIXES = (".xlsm", ".xltm", ".xlam")
_TEMPLATE_HINT = f"the first row must be the header: {', '.join(COLUMNS)}"


@dataclass
class Sheet:
    """The header row and the non-empty data rows of a table, with sheet row numbers."""

    header_row: int
    header: list[object]
    rows: list[tuple[int, list[object]]]
    decimal_comma: bool = False
    errors: list[RowError] = field(default_factory=list)


def read_sheet(
    data: bytes, *, filename: str | None, content_type: str | None, max_rows: int
) -> Sheet:
    """Sniff the format from the content (ZIP magic = XLSX) and read the table."""
    macro_name = (filename or "").lower().endswith(_MACRO_SUFFIXES)
    if macro_name or "macroenabled" in (content_type or "").lower():
        raise fatal("macro-enabled workbooks are refused; save the file as .xlsx or CSV")
    if data.startswith(_OLE_MAGIC):
        raise fatal("legacy .xls workbooks are not supported; save the file as .xlsx or CSV")
    if data.startswith(_ZIP_MAGIC):
        return read_xlsx(data, max_rows=max_rows)
    if (filename or "").lower().endswith(".xlsx"):
        raise fatal("the file name ends in .xlsx but the content is not an XLSX workbook")
    return read_csv(data, max_rows=max_rows)


def _blank_row(cells: Sequence[object]) -> bool:
    first = cells[0] if cells else None
    if type(first) is str and first and not first[0].isspace():
        return False  # the usual row: its first cell is plainly not blank
    return all(is_blank(cell) for cell in cells)


def _split_header(
    records: Iterable[tuple[int, list[object]]], max_rows: int
) -> tuple[int, list[object], list[tuple[int, list[object]]]]:
    """The first non-empty row is the header; empty rows are skipped."""
    header: tuple[int, list[object]] | None = None
    rows: list[tuple[int, list[object]]] = []
    for number, cells in records:
        if _blank_row(cells):
            continue
        if header is None:
            header = (number, cells)
            continue
        if len(rows) >= max_rows:
            raise fatal(f"the table has more than {max_rows} data rows, the limit; split it")
        rows.append((number, cells))
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


def _csv_records(text: str, delimiter: str) -> Iterator[tuple[int, list[object]]]:
    reader = csv.reader(io.StringIO(text, newline=""), delimiter=delimiter, strict=True)
    number = 0
    try:
        # A quoted cell may span lines; a spreadsheet shows it as one row.
        for number, cells in enumerate(reader, start=1):
            yield number, list(cells)
    except csv.Error as error:
        raise fatal(f"the CSV is malformed: {error}", row=number + 1) from None


def read_csv(data: bytes, *, max_rows: int) -> Sheet:
    text = decode_csv(data)
    delimiter = sniff_delimiter(text)
    header_row, header, rows = _split_header(_csv_records(text, delimiter), max_rows)
    return Sheet(header_row, header, rows, decimal_comma=delimiter == ";")


# --- XLSX ------------------------------------------------------------------------------------


def inspect_zip(data: bytes) -> None:
    """Refuse a ZIP bomb or a macro-enabled workbook before any XML is parsed."""
    try:
        with zipfile.ZipFile(io.BytesIO(data)) as archive:
            members = archive.infolist()
    except (zipfile.BadZipFile, ValueError) as error:
        raise fatal(f"the file looks like XLSX but is not a readable workbook: {error}") from None
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
        if member.filename.lower().endswith("vbaproject.bin"):
            raise fatal(
                f"the workbook contains macros ({member.filename}); save it as .xlsx without macros"
            )


def _pick_worksheet(workbook: object) -> object:
    sheets = list(workbook.worksheets)  # type: ignore[attr-defined]
    if not sheets:
        raise fatal("the workbook has no worksheet")
    named = [ws for ws in sheets if ws.title.strip().lower() == "results"]
    return (named or sheets)[0]


def _xlsx_records(
    worksheet: object, formulas: list[tuple[int, int, str, str]]
) -> Iterator[tuple[int, list[object]]]:
    """Cell values per row; formula cells are recorded in ``formulas`` and read as blank."""
    worksheet.reset_dimensions()  # type: ignore[attr-defined]
    for number, cells in enumerate(worksheet.iter_rows(min_row=1), start=1):  # type: ignore[attr-defined]
        values: list[object] = []
        for index, cell in enumerate(cells):
            if cell.data_type == "f":
                formulas.append((number, index, cell.coordinate, str(cell.value)))
                values.append(None)
            else:
                values.append(cell.value)
        yield number, values


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


def read_xlsx(data: bytes, *, max_rows: int) -> Sheet:
    inspect_zip(data)
    from openpyxl import load_workbook  # imported here: CSV-only callers do not pay for it

    formulas: list[tuple[int, int, str, str]] = []
    try:
        workbook = load_workbook(io.BytesIO(data), read_only=True, data_only=False)
    except Exception as error:  # openpyxl raises many types for a damaged file
        raise fatal(f"the workbook cannot be read: {error}") from None
    try:
        worksheet = _pick_worksheet(workbook)
        header_row, header, rows = _split_header(_xlsx_records(worksheet, formulas), max_rows)
    finally:
        workbook.close()
    errors = _formula_errors(formulas, header)
    if errors:
        raise ImportErrors(errors)
    return Sheet(header_row, header, rows)
