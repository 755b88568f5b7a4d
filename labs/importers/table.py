"""Results tables (docs/interfaces.md §1): parse CSV/XLSX/JSON into rows, write CSV/XLSX.

Pure Python, no Django: the web upload, the REST API and the offline
``pt_compare`` command all call :func:`parse_table` or :func:`parse_rows`,
which share one validation (:func:`labs.importers.validate.validate_records`).
A table that does not fit raises :class:`ImportErrors` listing every problem.
"""

from __future__ import annotations

import contextlib
import csv
import datetime as dt
import gc
import io
import math
import os
import shutil
import zipfile
from collections.abc import Iterable, Iterator, Mapping, Sequence
from typing import Any, BinaryIO, Literal

from common.quantities import DEFAULT as DEFAULT_QUANTITY

from .columns import record_columns, sheet_columns, validate_columns
from .errors import RowError, fatal
from .readers import read_sheet
from .schema import COLUMNS, LabColumn, ResultRow, TableContext
from .validate import check_header, normalise_name
from .values import escape_text, format_number, human_size

MAX_BYTES = 5 * 2**20
MAX_ROWS = 100_000

__all__ = ["MAX_BYTES", "MAX_ROWS", "parse_rows", "parse_table", "write_table", "write_table_to"]


def parse_table(
    data: bytes,
    *,
    filename: str | None = None,
    content_type: str | None = None,
    lab_column: LabColumn = "optional",
    context: TableContext | None = None,
    max_bytes: int = MAX_BYTES,
    max_rows: int = MAX_ROWS,
) -> list[ResultRow]:
    """Parse a CSV or XLSX results table; raise :class:`ImportErrors` listing every problem.

    ``ResultRow.row`` is the spreadsheet row number (header = row 1). Header
    problems (unknown, repeated or missing columns) are reported alone, before
    any row is read. ``lab_column``: ``forbidden`` for a participant's upload,
    ``required`` for a coordinator's or ``pt_compare``'s table.
    """
    if len(data) > max_bytes:
        raise fatal(f"the file is {human_size(len(data))}; the limit is {human_size(max_bytes)}")
    with _gc_paused():
        sheet = read_sheet(
            data, filename=filename, content_type=content_type, max_rows=max_rows,
            header_check=lambda header, row: check_header(header, lab_column=lab_column, row=row),
        )  # fmt: skip
        names = check_header(sheet.header, lab_column=lab_column, row=sheet.header_row)
        # The rows hold the cells under the named header cells only (readers.Shape).
        columns, numbers, cell_errors = sheet_columns([n for n in names if n], sheet.rows)
        return validate_columns(
            columns,
            numbers,
            decimal_comma=sheet.decimal_comma,
            lab_column=lab_column,
            context=context,
            errors=[*sheet.errors, *cell_errors],
            dropped=sheet.dropped,
        )


@contextlib.contextmanager
def _gc_paused() -> Iterator[None]:
    """No cyclic garbage collection while a table is read.

    Reading 100,000 rows allocates millions of objects that all stay alive; the
    collector would walk them again and again for nothing (a third of the time).
    Reference counting still frees everything; the collector resumes afterwards.
    """
    was_enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if was_enabled:
            gc.enable()


def parse_rows(
    rows: Sequence[object],
    *,
    lab_column: LabColumn = "optional",
    context: TableContext | None = None,
    max_rows: int = MAX_ROWS,
) -> list[ResultRow]:
    """Validate results given as JSON objects (the API's ``{"results": [...]}``).

    Same columns and rules as :func:`parse_table`; keys are case-insensitive.
    Values may be JSON numbers or strings (decimal point only). ``row`` in
    results and errors is the 1-based index of the object in ``rows``.
    """
    if len(rows) > max_rows:
        raise fatal(f"{len(rows)} results were given; the limit is {max_rows}")
    errors: list[RowError] = []
    records: list[tuple[int, Mapping[str, object]]] = []
    names: dict[object, str] = {}
    with _gc_paused():
        for number, item in enumerate(rows, start=1):
            record, item_errors = _object_to_record(item, number, names)
            errors.extend(item_errors)
            if record is not None:
                records.append((number, record))
        columns, numbers = record_columns(records)
        return validate_columns(
            columns, numbers, lab_column=lab_column, context=context, errors=errors
        )


def _object_to_record(
    item: object, number: int, names: dict[object, str]
) -> tuple[dict[str, object] | None, list[RowError]]:
    """One JSON object as a record; ``names`` remembers each key's column name."""
    if not isinstance(item, Mapping):
        return None, [RowError(number, None, "must be an object whose keys are column names")]
    record: dict[str, object] = {}
    errors = []
    for key, value in item.items():
        name = names.get(key) if type(key) is str else None
        if name is None:
            name = normalise_name(key)
            if type(key) is str:
                names[key] = name
        if name not in COLUMNS:
            errors.append(
                RowError(number, str(key), f"unknown field; allowed: {', '.join(COLUMNS)}")
            )
        elif name in record:
            errors.append(RowError(number, name, "is given more than once"))
        elif not (value is None or isinstance(value, str | int | float)):
            errors.append(RowError(number, name, "must be a string or a number"))
        else:
            record[name] = value
    return record, errors


def _cell(value: object) -> object:
    """A value as written: numbers stay numbers, text is escaped against formula execution."""
    if value is None:
        return ""
    if isinstance(value, bool):
        return str(value).upper()
    if isinstance(value, int | float):
        return value if math.isfinite(value) else format_number(float(value))
    if isinstance(value, dt.date):
        return value.isoformat()  # text in a workbook too: it reads back as written
    return escape_text(str(value))


#: Columns a default download leaves out when no row has a value there (for ``quantity``:
#: another kind than the magnitude): a table without labs, repeatability data, other
#: kinds or stated dates reads as it did before these columns existed.
_OPTIONAL_OUT = ("lab", "quantity", "repeat_sd", "n_repeats", "measured_on")
_NO_VALUE = (None, "", DEFAULT_QUANTITY)


def _default_columns(records: Sequence[Mapping[str, object]]) -> list[str]:
    present = {c for c in _OPTIONAL_OUT if any(r.get(c) not in _NO_VALUE for r in records)}
    return [c for c in COLUMNS if c not in _OPTIONAL_OUT or c in present]


def write_table(
    rows: Iterable[ResultRow | Mapping[str, object]],
    *,
    format: Literal["csv", "xlsx"] = "csv",
    columns: Sequence[str] | None = None,
    delimiter: str = ",",
    bom: bool = True,
) -> bytes:
    """Write a results table (downloads, templates) that :func:`parse_table` reads back.

    ``columns`` defaults to every column of docs/interfaces.md §1, ``lab``, ``repeat_sd``,
    ``n_repeats`` and ``measured_on`` only when a row has one (``quantity`` when a row is
    of another kind); mappings may carry other columns (scores). A date is written
    ``YYYY-MM-DD``.
    Numbers are written in full precision with a decimal point; text loses its control
    characters, then formula-like text gets a leading quote (:func:`~.values.escape_text`).
    CSV is UTF-8 with a BOM (for spreadsheets) unless ``bom=False``.
    """
    records = [r.as_record() if isinstance(r, ResultRow) else dict(r) for r in rows]
    names = list(columns) if columns is not None else _default_columns(records)
    if format not in ("csv", "xlsx"):
        raise ValueError(f"unknown format {format!r}; use 'csv' or 'xlsx'")
    buffer = io.BytesIO()
    write_table_to(buffer, records, format=format, columns=names, delimiter=delimiter, bom=bom)
    return buffer.getvalue()


def write_table_to(
    out: BinaryIO,
    rows: Iterable[ResultRow | Mapping[str, object]],
    *,
    format: Literal["csv", "xlsx"],
    columns: Sequence[str],
    delimiter: str = ",",
    bom: bool = True,
    when: dt.datetime | None = None,
) -> int:
    """:func:`write_table` into ``out``, a row at a time (bounded memory: the rows may be a
    generator over a million results); the number of rows.  ``columns`` is required (the
    default columns need every row first).  ``when`` fixes the workbook's dates (its
    properties and its ZIP entries), so an XLSX written twice is the same bytes."""
    table = ([_cell(rec.get(name)) for name in columns] for rec in _records(rows))
    if format == "csv":
        return _write_csv(out, list(columns), table, delimiter=delimiter, bom=bom)
    if format == "xlsx":
        return _write_xlsx(out, list(columns), table, when)
    raise ValueError(f"unknown format {format!r}; use 'csv' or 'xlsx'")


def _records(rows: Iterable[ResultRow | Mapping[str, object]]) -> Iterator[Mapping[str, object]]:
    return (r.as_record() if isinstance(r, ResultRow) else r for r in rows)


def _write_csv(
    out: BinaryIO, names: list[str], table: Iterable[list[object]], *, delimiter: str, bom: bool
) -> int:
    text = io.TextIOWrapper(out, encoding="utf-8", newline="", write_through=True)
    try:
        text.write("\ufeff" if bom else "")
        writer = csv.writer(text, delimiter=delimiter, lineterminator="\r\n")
        writer.writerow(names)
        n = 0
        for row in table:
            writer.writerow([repr(v) if isinstance(v, float) else v for v in row])
            n += 1
        text.flush()
    finally:
        text.detach()  # ``out`` stays open: it is the caller's
    return n


class _FixedDatesZip(zipfile.ZipFile):
    """openpyxl's ZIP with every entry dated ``date_time`` (not the clock's, nor a file's)."""

    date_time: tuple[int, int, int, int, int, int] = (1980, 1, 1, 0, 0, 0)

    def _info(self, name: str) -> zipfile.ZipInfo:
        info = zipfile.ZipInfo(name, date_time=self.date_time)
        info.compress_type = self.compression
        info.external_attr = 0o644 << 16
        return info

    def writestr(self, zinfo_or_arcname: Any, data: Any, *args: Any, **kwargs: Any) -> None:
        if isinstance(zinfo_or_arcname, str):
            zinfo_or_arcname = self._info(zinfo_or_arcname)
        super().writestr(zinfo_or_arcname, data, *args, **kwargs)

    def write(self, filename: Any, arcname: Any = None, *args: Any, **kwargs: Any) -> None:
        # a write-only sheet's rows, from its temporary file: copied, not read whole
        large = os.path.getsize(filename) > zipfile.ZIP64_LIMIT // 2
        member = self._info(arcname)
        with open(filename, "rb") as src, self.open(member, "w", force_zip64=large) as dst:
            shutil.copyfileobj(src, dst, 2**20)


def _write_xlsx(
    out: BinaryIO, names: list[str], table: Iterable[list[object]], when: dt.datetime | None
) -> int:
    # openpyxl only where a workbook is written: CSV downloads never load it
    from openpyxl import Workbook
    from openpyxl.writer.excel import ExcelWriter

    workbook = Workbook(write_only=True)
    sheet = workbook.create_sheet("results")
    sheet.append(names)
    n = 0
    for row in table:
        # Text cells come from escape_text: no control characters (XML cannot hold them),
        # and none starts with "=", which openpyxl would write as a formula.
        sheet.append(row)
        n += 1
    stamp = (when or dt.datetime.now(dt.UTC)).astimezone(dt.UTC).replace(tzinfo=None, microsecond=0)
    workbook.properties.created = workbook.properties.modified = stamp
    archive = _FixedDatesZip(out, "w", zipfile.ZIP_DEFLATED, allowZip64=True)
    archive.date_time = (max(stamp.year, 1980), stamp.month, stamp.day, stamp.hour,
                         stamp.minute, stamp.second)  # fmt: skip
    ExcelWriter(workbook, archive).save()  # what openpyxl's save_workbook does, dates fixed
    return n
