"""Hostile results tables: wide rows, error floods, extreme numbers, control
characters, formula injection in exports, non-ASCII digits. No database, no Django.

Bounds are counts and ratios (cells parsed, errors listed, memory against a normal
file's), never seconds. Run with ``pytest tests/labs/test_importers_hostile.py -p no:django``.
"""

from __future__ import annotations

import contextlib
import csv
import io
import random
import tracemalloc
import zipfile

import openpyxl
import pytest
from openpyxl.worksheet._reader import WorkSheetParser

from labs.importers import ImportErrors, parse_rows, parse_table, write_table
from labs.importers.errors import MAX_LISTED_ERRORS, RowError
from labs.importers.readers import MAX_COLUMNS
from labs.importers.validate import _error_order, validate_record
from labs.importers.values import escape_text, unescape_text

NAMES = ["device", "axis", "frequency_hz", "bench", "sensitivity", "expanded_uncertainty"]
HEADER = ",".join(NAMES).encode() + b"\n"
GOOD = ["MEMS 1", "X", "10", "linear", "418", "4.2"]


def csv_table(*rows: list[str], names: list[str] = NAMES) -> bytes:
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(names)
    writer.writerows(rows)
    return buffer.getvalue().encode()


def errors(data: bytes, **kwargs: object) -> list[tuple[int | None, str | None, str]]:
    with pytest.raises(ImportErrors) as caught:
        parse_table(data, **kwargs)  # type: ignore[arg-type]
    return [(e.row, e.field, e.message) for e in caught.value.errors]


def xlsx_with_sheet(sheet_xml: bytes) -> bytes:
    """A workbook whose only worksheet is ``sheet_xml`` (written by hand: openpyxl
    cannot write a row past column XFD)."""
    workbook = openpyxl.Workbook()
    workbook.active.title = "results"
    workbook.active.append(["x"])
    buffer = io.BytesIO()
    workbook.save(buffer)
    source = zipfile.ZipFile(io.BytesIO(buffer.getvalue()))
    out = io.BytesIO()
    with zipfile.ZipFile(out, "w", zipfile.ZIP_DEFLATED) as archive:
        for info in source.infolist():
            part = info.filename == "xl/worksheets/sheet1.xml"
            archive.writestr(info.filename, sheet_xml if part else source.read(info))
    return out.getvalue()


def sheet_xml(*rows: bytes) -> bytes:
    ns = b"http://schemas.openxmlformats.org/spreadsheetml/2006/main"
    return b'<worksheet xmlns="%s"><sheetData>%s</sheetData></worksheet>' % (ns, b"".join(rows))


def inline_row(number: int, values: list[str]) -> bytes:
    cells = b"".join(b'<c t="inlineStr"><is><t>%s</t></is></c>' % v.encode() for v in values)
    return b'<row r="%d">%s</row>' % (number, cells)


def wide_xlsx(n_cells: int) -> bytes:
    rng = random.Random(15)  # numbers that do not compress like a ZIP bomb
    cells = b"".join(b"<c><v>%d</v></c>" % rng.randrange(100) for _ in range(n_cells))
    return xlsx_with_sheet(sheet_xml(inline_row(1, NAMES), b'<row r="2">%s</row>' % cells))


def peak_bytes(action) -> int:
    tracemalloc.start()
    try:
        with contextlib.suppress(ImportErrors):
            action()
        return tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


def normal_csv(n_rows: int) -> bytes:
    rows = [
        ["MEMS 1", "XYZ"[i % 3], f"{1 + i // 3}", "linear", "418.25", "4.2"] for i in range(n_rows)
    ]
    return csv_table(*rows)


# --- A. one wide row ------------------------------------------------------------------------


def test_a_csv_row_of_millions_of_cells_is_refused_at_once_with_one_error() -> None:
    limit = 5 * 2**20
    row = b",".join([b"12"] * (limit // 3))[: limit - len(HEADER) - 1]
    data = HEADER + row + b"\n"
    assert len(data) <= limit and data.count(b",") > 1_700_000
    assert errors(data) == [
        (
            2,
            None,
            f"has more than {MAX_COLUMNS:,} cells, the most a worksheet can have, but the header "
            "has 6 columns; the file was not read further",
        )
    ]


def test_a_wide_csv_row_costs_less_memory_than_a_normal_file_of_its_size() -> None:
    wide = HEADER + b",".join([b"12"] * 350_000) + b"\n"
    normal = normal_csv(len(wide) // 28)
    assert abs(len(normal) - len(wide)) < len(wide) // 5
    baseline = peak_bytes(lambda: parse_table(normal))
    assert peak_bytes(lambda: parse_table(wide)) < baseline


def test_a_row_with_values_past_the_header_gets_one_error_naming_both_widths() -> None:
    data = csv_table([*GOOD, *(["x"] * 50)])
    assert errors(data) == [
        (
            2,
            None,
            "has 56 cells but the header has 6 columns: value 'x' in column 7 has no header "
            "(nor have 49 more values of this row)",
        )
    ]
    assert len(parse_table(csv_table([*GOOD, "", " ", ""]))) == 1  # blank cells are fine


@pytest.fixture
def parse_cell_calls(monkeypatch: pytest.MonkeyPatch) -> list[int]:
    """How many cells openpyxl's cell parser was asked to read."""
    calls = [0]
    original = WorkSheetParser.parse_cell

    def counted(self, element):
        calls[0] += 1
        return original(self, element)

    monkeypatch.setattr(WorkSheetParser, "parse_cell", counted)
    return calls


def test_a_xlsx_row_of_200k_cells_stops_after_the_column_limit(parse_cell_calls) -> None:
    data = wide_xlsx(200_000)
    assert errors(data) == [
        (
            2,
            None,
            f"has a cell in column {MAX_COLUMNS + 1:,}, past the {MAX_COLUMNS:,} columns a "
            "worksheet can have, but the header has 6 columns; the file was not read further",
        )
    ]
    assert parse_cell_calls[0] == len(NAMES) + MAX_COLUMNS + 1


def test_a_xlsx_row_repeating_one_coordinate_is_stopped_by_its_cell_count(
    parse_cell_calls,
) -> None:
    rng = random.Random(15)
    cells = b"".join(b'<c r="A2"><v>%d</v></c>' % rng.randrange(100) for _ in range(100_000))
    data = xlsx_with_sheet(sheet_xml(inline_row(1, NAMES), b'<row r="2">%s</row>' % cells))
    [(row, field, message)] = errors(data)
    assert (row, field) == (2, None)
    assert message.startswith(f"has more than {MAX_COLUMNS:,} cells")
    assert parse_cell_calls[0] == len(NAMES) + MAX_COLUMNS + 1


def test_a_worksheet_that_is_not_read_costs_nothing() -> None:
    """openpyxl's read-only loader parsed every worksheet without a ``<dimension>`` whole,
    just to size it, also the ones never read."""
    rows = [inline_row(1, NAMES)]
    rows += [inline_row(n, [*GOOD[:2], str(n), *GOOD[3:]]) for n in range(2, 12)]

    def book(other: bytes) -> bytes:
        workbook = openpyxl.Workbook()
        workbook.active.title = "results"
        workbook.create_sheet("other")
        buffer = io.BytesIO()
        workbook.save(buffer)
        parts = {"xl/worksheets/sheet1.xml": sheet_xml(*rows), "xl/worksheets/sheet2.xml": other}
        source, out = zipfile.ZipFile(io.BytesIO(buffer.getvalue())), io.BytesIO()
        with zipfile.ZipFile(out, "w", zipfile.ZIP_DEFLATED) as archive:
            for info in source.infolist():
                archive.writestr(info.filename, parts.get(info.filename) or source.read(info))
        return out.getvalue()

    rng = random.Random(3)
    big = b"".join(b"<c><v>%d</v></c>" % rng.randrange(100) for _ in range(200_000))
    small, large = book(sheet_xml(inline_row(1, ["x"]))), book(sheet_xml(b"<row>%s</row>" % big))
    assert len(parse_table(large)) == 10
    assert peak_bytes(lambda: parse_table(large)) < 2 * peak_bytes(lambda: parse_table(small))


def test_xlsx_cells_past_the_header_are_reported_not_kept() -> None:
    data = xlsx_with_sheet(sheet_xml(inline_row(1, NAMES), inline_row(2, [*GOOD, "", "7", "8"])))
    assert errors(data) == [
        (
            2,
            None,
            "has 9 cells but the header has 6 columns: value '7' in column 8 has no header "
            "(nor have 1 more values of this row)",
        )
    ]


def test_a_damaged_worksheet_is_a_clear_error() -> None:
    data = xlsx_with_sheet(sheet_xml(inline_row(1, NAMES), inline_row(2, ["MEMS&#0;1"])))
    [(row, field, message)] = errors(data)
    assert (row, field) == (None, None)
    assert message.startswith("the worksheet cannot be read: reference to invalid character")


# --- A. every error listing stops at 1,000 --------------------------------------------------


def test_3000_bad_rows_list_the_first_1000_and_count_the_rest() -> None:
    data = csv_table(*[["MEMS 1", "W", f"{i + 1}", "linear", "418", "4.2"] for i in range(3000)])
    with pytest.raises(ImportErrors) as caught:
        parse_table(data)
    found = caught.value
    assert (len(found.errors), found.total, found.more) == (MAX_LISTED_ERRORS, 3000, 2000)
    assert found.errors[0].row == 2 and found.errors[-1].row == 1001
    assert str(found).splitlines()[-1] == "... and 2,000 more problems"
    listed = found.as_dicts()
    assert len(listed) == MAX_LISTED_ERRORS + 1
    assert listed[-1] == {"row": None, "field": None, "message": "... and 2,000 more problems"}


def test_the_listed_problems_are_the_first_in_row_and_column_order() -> None:
    """The column-wise validator keeps only part of each column's problems: the ones kept
    are still exactly the first 1,000 of the whole table."""
    rng = random.Random(7)
    records = []
    for i in range(1500):
        record = dict(zip(NAMES, GOOD, strict=True)) | {"frequency_hz": str(i + 1)}
        for name in rng.sample(["axis", "bench", "sensitivity", "expanded_uncertainty"], 2):
            record[name] = "-1" if name in ("sensitivity", "expanded_uncertainty") else "?"
        records.append(record)
    every: list[RowError] = []
    for number, record in enumerate(records, start=1):
        every.extend(validate_record(record, number))  # type: ignore[arg-type]
    every.sort(key=_error_order)
    with pytest.raises(ImportErrors) as caught:
        parse_rows(records)
    assert caught.value.total == len(every) == 3000
    assert caught.value.errors == every[:MAX_LISTED_ERRORS]


def test_3000_rows_wider_than_the_header_list_1000() -> None:
    data = csv_table(*[[*GOOD[:2], f"{i + 1}", *GOOD[3:], "x"] for i in range(3000)])
    with pytest.raises(ImportErrors) as caught:
        parse_table(data)
    assert (len(caught.value.errors), caught.value.total) == (MAX_LISTED_ERRORS, 3000)


# --- B. numbers the statistics can carry ----------------------------------------------------

RANGE = "must be between 1e-30 and 1e30 (the range the statistics can carry)"


@pytest.mark.parametrize(
    ("changes", "field", "message"),
    [
        ({"sensitivity": "1e308"}, "sensitivity", f"{RANGE}, got 1e+308"),
        ({"sensitivity": "1e-300"}, "sensitivity", f"{RANGE}, got 1e-300"),
        ({"expanded_uncertainty": "1e-300"}, "expanded_uncertainty", f"{RANGE}, got 1e-300"),
        ({"coverage_factor": "1e-31"}, "coverage_factor", f"{RANGE}, got 1e-31"),
        ({"dof": "1e-300"}, "dof", f"{RANGE}, got 1e-300"),
        ({"dof": "1e31"}, "dof", f"{RANGE}, got 1e+31"),
        ({"frequency_hz": "1e40"}, "frequency_hz", f"{RANGE}, got 1e+40"),
        ({"amplitude_m_s2": "1e-40"}, "amplitude_m_s2", f"{RANGE}, got 1e-40"),
        (
            {"sensitivity": "1e-29", "expanded_uncertainty": "1e-3%"},
            "expanded_uncertainty",
            f"U is 1e-34; it {RANGE}",
        ),
        (
            {"expanded_uncertainty": "1e-29", "coverage_factor": "100"},
            "expanded_uncertainty",
            f"gives u = U/k = 1e-31; u {RANGE}",
        ),
        (
            {"sensitivity": "1e-30", "unit": "mg/LSB", "expanded_uncertainty": "0.1%"},
            "sensitivity",
            f"is 1.01972e+32 after the conversion from mg/LSB; it {RANGE}",
        ),
    ],
)
def test_b_numbers_outside_the_safe_range_are_refused(changes, field, message) -> None:
    record = dict(zip(NAMES, GOOD, strict=True)) | changes
    names = list(record)
    data = csv_table([record[n] for n in names], names=names)
    assert errors(data) == [(2, field, message)]
    with pytest.raises(ImportErrors) as caught:  # the JSON path shares the rule
        parse_rows([record])
    assert [(e.row, e.field, e.message) for e in caught.value.errors] == [(1, field, message)]


def test_b_json_and_xlsx_numbers_are_checked_too() -> None:
    with pytest.raises(ImportErrors) as caught:
        parse_rows([dict(zip(NAMES, GOOD, strict=True)) | {"sensitivity": 1e-300}])
    assert [(e.field, e.message) for e in caught.value.errors] == [
        ("sensitivity", f"{RANGE}, got 1e-300")
    ]
    workbook = openpyxl.Workbook()
    workbook.active.append(NAMES)
    workbook.active.append(["MEMS 1", "X", 10, "linear", 1e308, 4.2])
    buffer = io.BytesIO()
    workbook.save(buffer)
    assert errors(buffer.getvalue()) == [(2, "sensitivity", f"{RANGE}, got 1e+308")]


def test_b_the_ends_of_the_range_and_infinite_dof_are_accepted() -> None:
    record = dict(zip(NAMES, GOOD, strict=True)) | {
        "sensitivity": "1e30", "expanded_uncertainty": "2e-30", "dof": "inf",
    }  # fmt: skip
    [row] = parse_rows([record])
    assert (row.sensitivity, row.standard_uncertainty, row.dof) == (1e30, 1e-30, float("inf"))


# --- C. control characters in cells ---------------------------------------------------------

CONTROL = "remove it (NUL and other control characters cannot be stored)"


def control(code: str, position: int) -> str:
    return f"contains the control character U+{code} at position {position}; {CONTROL}"


@pytest.mark.parametrize(
    ("field", "value", "message"),
    [
        ("note", "a\x00b", control("0000", 2)),
        ("device", "MEMS\x001", control("0000", 5)),
        ("sensitivity", "41\x008", control("0000", 3)),
        ("note", "\x01=HYPERLINK(1)", control("0001", 1)),
        ("expanded_uncertainty", "\x1c4.2", control("001C", 1)),
    ],
)
def test_c_control_characters_are_refused_naming_row_and_column(field, value, message) -> None:
    record = dict(zip(NAMES, GOOD, strict=True)) | {field: value}
    names = list(record)
    assert errors(csv_table([record[n] for n in names], names=names)) == [(2, field, message)]
    with pytest.raises(ImportErrors) as caught:
        parse_rows([record])
    assert [(e.row, e.field, e.message) for e in caught.value.errors] == [(1, field, message)]


def test_c_a_lone_surrogate_from_json_is_refused() -> None:
    with pytest.raises(ImportErrors) as caught:
        parse_rows([dict(zip(NAMES, GOOD, strict=True)) | {"note": "ok \ud800"}])
    assert [(e.field, e.message) for e in caught.value.errors] == [("note", control("D800", 4))]


def test_c_tabs_and_line_breaks_in_a_note_are_kept() -> None:
    [row] = parse_rows([dict(zip(NAMES, GOOD, strict=True)) | {"note": "plate B\n\tbolted"}])
    assert row.note == "plate B\n\tbolted"


# --- D. formulas in exports -----------------------------------------------------------------

HOSTILE = [
    '\x01=HYPERLINK("http://evil.example","x")',
    "\x00+1+1",
    "\x1f@SUM(A1)",
    " =1+1",
    "\uff1d1+1",
    "\x0b-2",
]


def test_d_escape_removes_control_characters_before_looking_for_a_formula() -> None:
    assert escape_text('\x01=HYPERLINK("http://evil.example","x")') == (
        '\'=HYPERLINK("http://evil.example","x")'
    )
    assert [escape_text(s)[:1] for s in HOSTILE] == ["'"] * len(HOSTILE)
    for text in ["plain", "'quoted", "'=x", "''=x", "-3 dB", " =1", "\uff1d1", "a\tb"]:
        assert unescape_text(escape_text(text)) == text


def test_d_exported_xlsx_and_csv_carry_no_formula() -> None:
    rows = [{"device": "MEMS 1", "axis": "X", "note": text} for text in HOSTILE]
    book = openpyxl.load_workbook(io.BytesIO(write_table(rows, format="xlsx")))
    notes = [row[-1] for row in book.active.iter_rows(min_row=2)]
    assert [cell.data_type for cell in notes] == ["s"] * len(HOSTILE)
    assert [cell.value[:1] for cell in notes] == ["'"] * len(HOSTILE)
    assert notes[0].value == '\'=HYPERLINK("http://evil.example","x")'
    lines = list(csv.reader(io.StringIO(write_table(rows, bom=False).decode())))
    assert [line[-1][:1] for line in lines[1:]] == ["'"] * len(HOSTILE)


# --- E. ASCII digits only -------------------------------------------------------------------


@pytest.mark.parametrize("digits", ["٤٢٠", "４２０", "४२०", "4２0"])
def test_e_non_ascii_digits_are_refused_in_csv_json_and_xlsx(digits: str) -> None:
    message = f"must be a number, got {digits!r}"
    data = csv_table(["MEMS 1", "X", "10", "linear", digits, "4.2"])
    assert errors(data) == [(2, "sensitivity", message)]
    with pytest.raises(ImportErrors) as caught:
        parse_rows([dict(zip(NAMES, GOOD, strict=True)) | {"frequency_hz": digits}])
    assert [(e.field, e.message) for e in caught.value.errors] == [("frequency_hz", message)]
    workbook = openpyxl.Workbook()
    workbook.active.append(NAMES)
    workbook.active.append(["MEMS 1", "X", 10, "linear", 418, f"{digits}%"])
    buffer = io.BytesIO()
    workbook.save(buffer)
    assert errors(buffer.getvalue()) == [
        (2, "expanded_uncertainty", f"must be a number or a percentage, got '{digits}%'")
    ]
