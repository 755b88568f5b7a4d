"""Results-table importer (docs/interfaces.md §1): no database, no Django.

Run with ``pytest tests/labs/test_importers.py -p no:django``.
"""

from __future__ import annotations

import csv
import dataclasses
import io
import math
import subprocess
import sys
import zipfile

import openpyxl
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from labs.importers import (
    ImportErrors,
    PointKey,
    ResultRow,
    RowError,
    TableContext,
    missing_points,
    parse_rows,
    parse_table,
    write_table,
)

BASE = {
    "device": "MEMS 1",
    "axis": "X",
    "frequency_hz": "10",
    "bench": "linear",
    "sensitivity": "418",
    "expanded_uncertainty": "4.2",
}


def table(*records: dict[str, str], sep: str = ",", header: list[str] | None = None) -> bytes:
    """CSV bytes for ``records`` (dicts of column -> text), header from the first record."""
    names = header or list(dict.fromkeys(name for record in records for name in record))
    buffer = io.StringIO()
    writer = csv.writer(buffer, delimiter=sep, lineterminator="\n")
    writer.writerow(names)
    writer.writerows([[r.get(n, "") for n in names] for r in records])
    return buffer.getvalue().encode()


def row_with(**changes: str) -> dict[str, str]:
    return {**BASE, **changes}


def errors(data: bytes, **kwargs: object) -> list[tuple[int | None, str | None, str]]:
    with pytest.raises(ImportErrors) as caught:
        parse_table(data, **kwargs)  # type: ignore[arg-type]
    return [(e.row, e.field, e.message) for e in caught.value.errors]


def xlsx(rows: list[list[object]], *, title: str = "Sheet", extra_first: bool = False) -> bytes:
    workbook = openpyxl.Workbook()
    sheet = workbook.active
    if extra_first:
        sheet.title = "readme"
        sheet.append(["this sheet is not read"])
        sheet = workbook.create_sheet("Results")
    else:
        sheet.title = title
    for values in rows:
        sheet.append(values)
    buffer = io.BytesIO()
    workbook.save(buffer)
    return buffer.getvalue()


# --- happy paths and formats ---------------------------------------------------------------


def test_minimal_row_gets_the_defaults() -> None:
    [row] = parse_table(table(BASE))
    assert row == ResultRow(
        row=2, device="MEMS 1", axis="X", frequency_hz=10.0, bench="linear", sensitivity=418.0,
        expanded_uncertainty=4.2,
    )  # fmt: skip
    assert (row.direction, row.unit, row.coverage_factor, row.dof, row.lab, row.note) == (
        "vertical", "D/(m/s^2)", 2.0, None, None, "",
    )  # fmt: skip
    assert row.standard_uncertainty == pytest.approx(2.1)
    assert row.original_unit is None


def test_all_columns_are_read() -> None:
    record = row_with(
        bench="Curvilinear", direction="Radial", amplitude_m_s2="14.8", unit="LSB/(m/s^2)",
        coverage_factor="2.5", dof="12", lab="L07", note=" mounted on plate B ", axis="z",
    )  # fmt: skip
    [row] = parse_table(table(record))
    assert (row.axis, row.bench, row.direction, row.amplitude_m_s2) == (
        "Z",
        "curvilinear",
        "radial",
        14.8,
    )
    assert (row.unit, row.coverage_factor, row.dof, row.lab, row.note) == (
        "D/(m/s^2)", 2.5, 12.0, "L07", "mounted on plate B",
    )  # fmt: skip
    assert row.standard_uncertainty == pytest.approx(4.2 / 2.5)


def test_bom_and_no_bom_give_the_same_rows() -> None:
    data = table(BASE, row_with(axis="Y"))
    assert parse_table(b"\xef\xbb\xbf" + data) == parse_table(data)


def test_semicolon_separator_with_decimal_comma() -> None:
    data = table(row_with(sensitivity="417,9", expanded_uncertainty="4,18"), sep=";")
    [row] = parse_table(data)
    assert (row.sensitivity, row.expanded_uncertainty) == (417.9, 4.18)


def test_semicolon_separator_with_decimal_point() -> None:
    [row] = parse_table(table(row_with(sensitivity="417.9"), sep=";"))
    assert row.sensitivity == 417.9


def test_decimal_comma_rejected_with_comma_separator() -> None:
    assert errors(table(row_with(sensitivity="417,9"))) == [
        (2, "sensitivity", "must be a number with a decimal point, got '417,9' (a decimal comma "
                           "is accepted only in semicolon-separated files)"),
    ]  # fmt: skip
    unquoted = b"device,axis,frequency_hz,bench,sensitivity,expanded_uncertainty\n" \
               b"MEMS 1,X,10,linear,417,9,4\n"  # fmt: skip
    assert errors(unquoted) == [
        (2, None, "has 7 cells but the header has 6 columns: value '4' in column 7 has no header")
    ]


def test_decimal_comma_with_thousands_separator_is_rejected() -> None:
    assert errors(table(row_with(sensitivity="1.417,9"), sep=";")) == [
        (2, "sensitivity", "must be a number without thousands separators, got '1.417,9'"),
    ]


def test_headers_are_case_insensitive_trimmed_and_in_any_order() -> None:
    data = b" Sensitivity ;DEVICE;Axis;Expanded_Uncertainty;BENCH;Frequency_Hz\r\n" \
           b"418;MEMS 2;y;1%;linear;20\r\n"  # fmt: skip
    [row] = parse_table(data)
    assert (row.device, row.axis, row.frequency_hz, row.expanded_uncertainty) == (
        "MEMS 2", "Y", 20.0, pytest.approx(4.18),
    )  # fmt: skip


def test_empty_lines_are_skipped_and_rows_keep_their_spreadsheet_number() -> None:
    data = b"\n".join(
        [b"device,axis,frequency_hz,bench,sensitivity,expanded_uncertainty",
         b"MEMS 1,X,10,linear,418,4", b"", b",,,,,", b"MEMS 1,Y,10,linear,418,-4"]
    )  # fmt: skip
    assert errors(data) == [(5, "expanded_uncertainty", "must be > 0, got -4")]


def test_unknown_columns_are_rejected_with_the_allowed_list() -> None:
    [(row, field, message)] = errors(table(row_with(colour="red", Remarks="x")))
    assert (row, field) == (1, None)
    assert message.startswith("unknown columns 'colour', 'remarks'; the allowed columns are: ")
    assert "expanded_uncertainty" in message


def test_missing_required_columns_give_one_error() -> None:
    data = b"device,axis,bench\nMEMS 1,X,linear\n"
    assert errors(data) == [
        (1, None, "missing required columns: frequency_hz, sensitivity, expanded_uncertainty"),
    ]


def test_repeated_column_is_rejected() -> None:
    data = table(BASE, header=[*BASE, "Axis"])
    assert errors(data) == [(1, "axis", "appears more than once (columns 2, 7)")]


def test_empty_file_and_header_only() -> None:
    assert errors(b"")[0][2].startswith("the table is empty; the first row must be the header")
    assert errors(b"device,axis,frequency_hz,bench,sensitivity,expanded_uncertainty\n") == [
        (None, None, "the table has no data rows"),
    ]


# --- column rules --------------------------------------------------------------------------

RULES = [
    ("device", "", "is required"),
    ("device", "   ", "is required"),
    ("axis", "W", "must be one of X, Y, Z, got 'W'"),
    ("axis", "", "is required"),
    ("frequency_hz", "0", "must be > 0, got 0"),
    ("frequency_hz", "-5", "must be > 0, got -5"),
    ("frequency_hz", "ten", "must be a number, got 'ten'"),
    ("frequency_hz", "nan", "must be a finite number, got 'nan'"),
    ("frequency_hz", "inf", "must be a finite number, got 'inf'"),
    ("frequency_hz", "1e999", "must be a finite number, got '1e999'"),
    ("bench", "rotary", "must be one of linear, curvilinear, got 'rotary'"),
    ("direction", "up", "must be one of vertical, tangential, radial, got 'up'"),
    (
        "direction",
        "radial",
        "'radial' is not allowed on the linear bench; expected one of: vertical",
    ),
    ("amplitude_m_s2", "0", "must be > 0, got 0"),
    ("amplitude_m_s2", "-10", "must be > 0, got -10"),
    ("sensitivity", "", "is required"),
    ("sensitivity", "-418", "must be > 0, got -418"),
    ("sensitivity", "Infinity", "must be a finite number, got 'Infinity'"),
    ("sensitivity", "NaN", "must be a finite number, got 'NaN'"),
    ("expanded_uncertainty", "-3", "must be > 0, got -3"),
    ("expanded_uncertainty", "0", "must be > 0, got 0"),
    ("expanded_uncertainty", "", "is required"),
    ("expanded_uncertainty", "0%", "must be > 0, got 0%"),
    ("expanded_uncertainty", "-1 %", "must be > 0, got -1 %"),
    ("expanded_uncertainty", "a%", "must be a number or a percentage, got 'a%'"),
    ("expanded_uncertainty", "nan", "must be a finite number, got 'nan'"),
    ("coverage_factor", "0", "must be > 0, got 0"),
    ("coverage_factor", "inf", "must be a finite number, got 'inf'"),
    ("dof", "0", "must be > 0, got 0"),
    ("dof", "-inf", "must be a finite number, got '-inf'"),
    ("dof", "nan", "must be a finite number, got 'nan'"),
    ("note", "x" * 501, "must be at most 500 characters, got 501"),
]


@pytest.mark.parametrize(("field", "value", "message"), RULES)
def test_column_rule(field: str, value: str, message: str) -> None:
    data = table(BASE, row_with(axis="Y"), {**row_with(axis="Z"), field: value})
    assert errors(data) == [(4, field, message)]


def test_error_text_names_row_and_column() -> None:
    with pytest.raises(ImportErrors) as caught:
        parse_table(table(BASE, BASE, BASE, BASE, BASE, row_with(expanded_uncertainty="-3")))
    lines = str(caught.value).splitlines()
    assert "row 7, column expanded_uncertainty: must be > 0, got -3" in lines
    assert caught.value.errors[-1].as_dict() == {
        "row": 7, "field": "expanded_uncertainty", "message": "must be > 0, got -3",
    }  # fmt: skip
    assert str(RowError(None, None, "the file is empty")) == "the file is empty"


def test_unknown_unit_is_rejected() -> None:
    [(row, field, message)] = errors(table(row_with(unit="V/g")))
    assert (row, field) == (2, "unit")
    assert message.startswith("unknown unit 'V/g'; allowed: D/(m/s^2), LSB/(m/s^2), ")


def test_curvilinear_bench_needs_tangential_or_radial() -> None:
    data = table(row_with(bench="curvilinear"), row_with(bench="curvilinear", direction="vertical"))
    assert errors(data) == [
        (2, "direction", "is required on the curvilinear bench: one of tangential, radial"),
        (3, "direction", "'vertical' is not allowed on the curvilinear bench; expected one of: "
                         "tangential, radial"),
    ]  # fmt: skip
    [row] = parse_table(table(row_with(bench="curvilinear", direction="TANGENTIAL")))
    assert row.direction == "tangential"


def test_infinite_dof_is_accepted() -> None:
    [row] = parse_table(table(row_with(dof="inf")))
    assert row.dof == math.inf


def test_relative_uncertainty_is_made_absolute() -> None:
    [row] = parse_table(table(row_with(expanded_uncertainty="1.5 %")))
    assert row.expanded_uncertainty == pytest.approx(418 * 0.015)


def test_every_bad_row_is_listed_at_once() -> None:
    data = table(
        row_with(axis="Q"),
        BASE,
        row_with(axis="Y", sensitivity="-1", expanded_uncertainty="x"),
        row_with(axis="Z", frequency_hz="nan"),
    )
    assert errors(data) == [
        (2, "axis", "must be one of X, Y, Z, got 'Q'"),
        (4, "sensitivity", "must be > 0, got -1"),
        (4, "expanded_uncertainty", "must be a number, got 'x'"),
        (5, "frequency_hz", "must be a finite number, got 'nan'"),
    ]


# --- lab column ---------------------------------------------------------------------------


def test_lab_column_forbidden() -> None:
    data = table(row_with(lab="L01"), row_with(axis="Y", lab=""))
    assert errors(data, lab_column="forbidden") == [
        (2, "lab", "is not allowed here: results are filed under your own laboratory; remove "
                   "the lab column"),
    ]  # fmt: skip
    assert [r.lab for r in parse_table(table(row_with(lab="")), lab_column="forbidden")] == [None]


def test_lab_column_required() -> None:
    assert errors(table(BASE), lab_column="required") == [
        (1, None, "missing required column: lab"),
    ]
    data = table(row_with(lab="L01"), row_with(lab=" "))
    assert errors(data, lab_column="required") == [(3, "lab", "is required")]


def test_same_point_from_two_labs_is_not_a_duplicate() -> None:
    rows = parse_table(table(row_with(lab="L01"), row_with(lab="L02")), lab_column="required")
    assert [r.lab for r in rows] == ["L01", "L02"]


# --- duplicates ---------------------------------------------------------------------------


def test_duplicates_name_the_earlier_row() -> None:
    data = table(BASE, row_with(axis="Y"), row_with(frequency_hz="10.0", sensitivity="420"))
    assert errors(data) == [
        (4, None, "duplicate of row 2: same lab, device, axis, frequency_hz, bench, direction "
                  "and amplitude_m_s2"),
    ]  # fmt: skip


def test_different_amplitude_is_not_a_duplicate() -> None:
    rows = parse_table(table(row_with(amplitude_m_s2="10"), row_with(amplitude_m_s2="20")))
    assert len(rows) == 2


# --- units ----------------------------------------------------------------------------------


def test_mg_per_lsb_is_converted_with_relative_uncertainty_kept() -> None:
    [row] = parse_table(table(row_with(sensitivity="0.244", unit="mg/LSB",
                                       expanded_uncertainty="1%")))  # fmt: skip
    assert row.sensitivity == pytest.approx(1 / (0.244e-3 * 9.80665))
    assert round(row.sensitivity, 1) == 417.9
    assert row.expanded_uncertainty == pytest.approx(0.01 * row.sensitivity)
    assert (row.unit, row.original_unit) == ("D/(m/s^2)", "mg/LSB")


def test_mg_per_lsb_absolute_uncertainty_keeps_its_relative_size() -> None:
    [row] = parse_table(table(row_with(sensitivity="0.244", unit="MG/lsb",
                                       expanded_uncertainty="0.00244")))  # fmt: skip
    assert row.relative_expanded_uncertainty == pytest.approx(0.01)


def test_lsb_unit_is_a_synonym() -> None:
    [row] = parse_table(table(row_with(unit="LSB/(m/s²)")))
    assert (row.unit, row.original_unit) == ("D/(m/s^2)", None)


# --- context --------------------------------------------------------------------------------

CONTEXT = TableContext(
    device_units={"MEMS 1": "D/(m/s^2)", "IEPE 1": "mV/(m/s^2)"},
    axes=("X", "Y"),
    frequencies_hz=(5.0, 10.0, 20.0),
)


def test_context_unknown_device_axis_and_frequency() -> None:
    data = table(row_with(device="MEMS 9"), row_with(axis="Z"), row_with(frequency_hz="12"))
    assert errors(data, context=CONTEXT) == [
        (2, "device", "unknown device 'MEMS 9' for this comparison; expected one of: MEMS 1, "
                      "IEPE 1"),
        (3, "axis", "'Z' is not allowed in this comparison; expected one of: X, Y"),
        (4, "frequency_hz", "12 Hz is not a frequency of this comparison; expected one of: 5, "
                            "10, 20"),
    ]  # fmt: skip


def test_context_spelling_frequency_tolerance_and_unit() -> None:
    data = table(
        row_with(device=" mems  1 ", frequency_hz="10.000000000001"),
        row_with(device="IEPE 1", sensitivity="1.02", expanded_uncertainty="0.01"),
    )
    first, second = parse_table(data, context=CONTEXT)
    assert (first.device, first.frequency_hz) == ("MEMS 1", 10.0)
    assert (second.unit, CONTEXT.unit_for_device("iepe 1")) == ("mV/(m/s^2)", "mV/(m/s^2)")


def test_context_unit_mismatch() -> None:
    assert errors(table(row_with(device="IEPE 1", unit="D/(m/s^2)")), context=CONTEXT) == [
        (2, "unit", "'D/(m/s^2)' does not fit IEPE 1, whose unit in this comparison is "
                    "mV/(m/s^2)"),
    ]  # fmt: skip


POINTS = [
    PointKey("MEMS 1", "X", 10.0, "linear", "vertical"),
    PointKey("MEMS 1", "X", 5.0, "curvilinear", "tangential"),
    PointKey("MEMS 1", "Y", 5.0, "curvilinear", "radial"),
]


def test_context_from_points_rejects_other_combinations() -> None:
    context = TableContext.from_points(POINTS)
    data = table(BASE, row_with(axis="Y"), row_with(bench="curvilinear", direction="radial",
                                                    frequency_hz="5"))  # fmt: skip
    assert errors(data, context=context) == [
        (3, None, "no measurement point MEMS 1 / Y / 10 Hz / linear / vertical in this comparison"),
        (4, None, "no measurement point MEMS 1 / X / 5 Hz / curvilinear / radial in this "
                  "comparison"),
    ]  # fmt: skip


def test_context_points_with_amplitudes() -> None:
    context = TableContext.from_points(
        [("MEMS 1", "X", 10.0, "linear", "vertical", 10.0),
         ("MEMS 1", "X", 10.0, "linear", "vertical", 20.0)]
    )  # fmt: skip
    assert errors(table(BASE), context=context) == [
        (2, "amplitude_m_s2", "is needed to tell the measurement points apart: one of 10, 20"),
    ]
    assert len(parse_table(table(row_with(amplitude_m_s2="20")), context=context)) == 1


def test_missing_points() -> None:
    context = TableContext.from_points(POINTS)
    rows = parse_table(table(row_with(bench="curvilinear", direction="tangential",
                                      frequency_hz="5")), context=context)  # fmt: skip
    assert missing_points(rows, context) == [POINTS[0], POINTS[2]]
    grid = TableContext(device_units={"M": "D/(m/s^2)"}, axes=("X",), frequencies_hz=(5.0,))
    assert missing_points([], grid) == [
        PointKey("M", "X", 5.0, "linear", "vertical"),
        PointKey("M", "X", 5.0, "curvilinear", "tangential"),
        PointKey("M", "X", 5.0, "curvilinear", "radial"),
    ]


def test_context_may_add_a_bench() -> None:
    context = TableContext(
        benches=("linear", "centrifuge"),
        directions={"linear": ("vertical",), "centrifuge": ("radial",)},
    )
    [row] = parse_table(table(row_with(bench="Centrifuge")), context=context)
    assert (row.bench, row.direction) == ("centrifuge", "radial")
    assert errors(table(row_with(bench="curvilinear")), context=context) == [
        (2, "bench", "'curvilinear' is not allowed in this comparison; expected one of: linear, "
                     "centrifuge"),
    ]  # fmt: skip


# --- safety ---------------------------------------------------------------------------------


def test_non_utf8_is_refused_with_offset_and_line() -> None:
    data = table(BASE, row_with(note="Müller")).decode().encode("latin-1")
    offset = data.index(b"\xfc")
    assert errors(data) == [
        (3, None, f"the file is not UTF-8 text: byte 0xfc at offset {offset} (line 3); save it "
                  "as 'CSV UTF-8' or as .xlsx"),
    ]  # fmt: skip


def test_too_large_file_is_refused_before_parsing() -> None:
    data = b"\xff" * int(6.2 * 2**20)
    assert errors(data) == [(None, None, "the file is 6.2 MB; the limit is 5 MB")]


def test_too_many_rows() -> None:
    data = table(BASE, row_with(axis="Y"), row_with(axis="Z"))
    assert errors(data, max_rows=2) == [
        (None, None, "the table has more than 2 data rows, the limit; split it"),
    ]
    assert len(parse_table(data, max_rows=3)) == 3


def test_xlsx_happy_path_reads_the_results_sheet() -> None:
    data = xlsx(
        [["Device", "axis", "frequency_hz", "bench", "sensitivity", "expanded_uncertainty",
          "dof", "note"],
         ["MEMS 1", "x", 10, "linear", 417.9, "1%", None, 12],
         [None],
         ["MEMS 1", "Y", 10.0, "linear", "418.5", 4.2, "inf", "'=not a formula"]],
        extra_first=True,
    )  # fmt: skip
    first, second = parse_table(data, filename="results.xlsx")
    assert (first.row, first.axis, first.sensitivity, first.note) == (2, "X", 417.9, "12")
    assert second.note == "=not a formula"
    assert first.expanded_uncertainty == pytest.approx(4.179)
    assert (second.row, second.sensitivity, second.dof) == (4, 418.5, math.inf)


def test_xlsx_errors_use_sheet_rows_and_reject_dates() -> None:
    import datetime as dt

    data = xlsx([list(BASE), ["MEMS 1", "X", dt.date(2024, 1, 5), "linear", True, -3]])
    assert errors(data) == [
        (2, "frequency_hz", "must be a number, got a date or time (2024-01-05 00:00:00)"),
        (2, "sensitivity", "must be a number, got True"),
        (2, "expanded_uncertainty", "must be > 0, got -3"),
    ]


def test_xlsx_formula_is_refused_naming_the_cell() -> None:
    data = xlsx([list(BASE), ["MEMS 1", "X", 10, "linear", 418, "=E2/100"]])
    assert errors(data) == [
        (2, "expanded_uncertainty", "cell F2 contains a formula (=E2/100); formulas are "
                                    "refused, paste the values instead"),
    ]  # fmt: skip


def test_macro_workbooks_are_refused() -> None:
    data = xlsx([list(BASE)])
    message = "macro-enabled workbooks are refused; save the file as .xlsx or CSV"
    assert errors(data, filename="results.xlsm") == [(None, None, message)]
    with_vba = io.BytesIO(data)
    with zipfile.ZipFile(with_vba, "a") as archive:
        archive.writestr("xl/vbaProject.bin", b"\x00" * 100)
    assert errors(with_vba.getvalue(), filename="results.xlsx") == [
        (None, None, "the workbook contains macros (xl/vbaProject.bin); save it as .xlsx "
                     "without macros"),
    ]  # fmt: skip


def _zip_with(member_size: int) -> bytes:
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w", compression=zipfile.ZIP_DEFLATED) as archive:
        archive.writestr("xl/worksheets/sheet1.xml", b"\x00" * member_size)
    return buffer.getvalue()


def test_zip_bomb_by_ratio_is_refused_before_openpyxl() -> None:
    [(_, _, message)] = errors(_zip_with(8 * 2**20))
    assert message.startswith("the workbook part xl/worksheets/sheet1.xml is compressed ")
    assert message.endswith(":1, the mark of a ZIP bomb; the limit is 100:1")


def test_zip_bomb_by_total_size_is_refused() -> None:
    assert errors(_zip_with(60 * 2**20)) == [
        (None, None, "the workbook unpacks to 60 MB; the limit is 50 MB"),
    ]


def test_not_a_workbook() -> None:
    assert errors(b"PK\x03\x04garbage")[0][2].startswith("the file looks like XLSX but is not")
    assert errors(b"\xd0\xcf\x11\xe0rest") == [
        (None, None, "legacy .xls workbooks are not supported; save the file as .xlsx or CSV"),
    ]
    assert errors(b"device\n", filename="a.XLSX") == [
        (None, None, "the file name ends in .xlsx but the content is not an XLSX workbook"),
    ]


def test_importer_does_not_import_django() -> None:
    code = (
        "import sys, labs.importers as m; "
        "m.parse_table(m.write_table([{'device': 'M'}], format='xlsx'), max_bytes=1) "
        "if False else m.write_table([{'device': 'M'}], format='xlsx'); "
        "assert not [n for n in sys.modules if n.split('.')[0] == 'django'], 'django imported'"
    )
    subprocess.run([sys.executable, "-c", code], check=True)


# --- JSON rows ------------------------------------------------------------------------------


def test_parse_rows_uses_the_same_rules_and_list_index() -> None:
    rows = parse_rows([
        {"Device": "MEMS 1", "axis": "x", "frequency_hz": 10, "bench": "linear",
         "sensitivity": 418.0, "expanded_uncertainty": "1%"},
    ])  # fmt: skip
    assert (rows[0].row, rows[0].axis, rows[0].expanded_uncertainty) == (1, "X", 4.18)
    with pytest.raises(ImportErrors) as caught:
        parse_rows([
            {**BASE, "sensitivity": -3},
            "not an object",
            {**BASE, "axis": "Y", "colour": "red", "dof": True},
            {**BASE, "axis": "Z", "sensitivity": "418,5", "lab": "L01"},
        ], lab_column="forbidden")  # fmt: skip
    assert [(e.row, e.field) for e in caught.value.errors] == [
        (1, "sensitivity"), (2, None), (3, "dof"), (3, "colour"), (4, "lab"), (4, "sensitivity"),
    ]  # fmt: skip
    assert caught.value.errors[0].message == "must be > 0, got -3"


def test_parse_rows_limits() -> None:
    with pytest.raises(ImportErrors, match="3 results were given; the limit is 2"):
        parse_rows([BASE, BASE, BASE], max_rows=2)
    with pytest.raises(ImportErrors, match="no data rows"):
        parse_rows([])


# --- writing --------------------------------------------------------------------------------


def test_write_table_escapes_formula_text_but_not_numbers() -> None:
    data = write_table(
        [{"device": "=HYPERLINK(1)", "note": "@SUM", "sensitivity": -3.5, "axis": "-X"}],
        columns=["device", "note", "sensitivity", "axis"],
        bom=False,
    )
    assert data.decode().splitlines()[1] == "'=HYPERLINK(1),'@SUM,-3.5,'-X"
    book = openpyxl.load_workbook(io.BytesIO(write_table(
        [{"device": "=1+1", "sensitivity": -3.5}], columns=["device", "sensitivity"],
        format="xlsx")))  # fmt: skip
    cells = next(book.active.iter_rows(min_row=2))
    assert [(c.data_type, c.value) for c in cells] == [("s", "'=1+1"), ("n", -3.5)]


def test_write_table_default_columns_and_template() -> None:
    rows = parse_table(table(row_with(note="+ok")))
    header = write_table(rows).decode("utf-8-sig").splitlines()[0]
    assert header == ("device,axis,frequency_hz,bench,direction,amplitude_m_s2,sensitivity,unit,"
                      "expanded_uncertainty,coverage_factor,dof,note")  # fmt: skip
    assert parse_table(write_table(rows, delimiter=";")) == rows
    assert write_table(rows, format="xlsx")[:4] == b"PK\x03\x04"
    with pytest.raises(ValueError, match="unknown format"):
        write_table(rows, format="ods")  # type: ignore[arg-type]


_TEXT = st.text(
    st.characters(blacklist_categories=("Cs", "Cc"), blacklist_characters="\u2028\u2029\x85"),
    max_size=30,
).map(lambda s: " ".join(s.split()))
_POSITIVE = st.floats(min_value=1e-9, max_value=1e9, allow_nan=False, allow_infinity=False)


@st.composite
def result_rows(draw: st.DrawFn) -> ResultRow:
    bench = draw(st.sampled_from(["linear", "curvilinear"]))
    return ResultRow(
        row=0,
        device=draw(_TEXT.filter(bool)),
        axis=draw(st.sampled_from(["X", "Y", "Z"])),
        frequency_hz=draw(_POSITIVE),
        bench=bench,
        direction=draw(
            st.sampled_from(["vertical"] if bench == "linear" else ["tangential", "radial"])
        ),
        amplitude_m_s2=draw(st.none() | _POSITIVE),
        sensitivity=draw(_POSITIVE),
        unit=draw(st.sampled_from(["D/(m/s^2)", "mV/(m/s^2)", "pC/(m/s^2)"])),
        expanded_uncertainty=draw(_POSITIVE),
        coverage_factor=draw(_POSITIVE),
        dof=draw(st.none() | _POSITIVE | st.just(math.inf)),
        lab=draw(st.none() | _TEXT.filter(bool)),
        note=draw(_TEXT),
    )


def _numbered(rows: list[ResultRow]) -> list[ResultRow]:
    unique = {
        (r.lab, r.device, r.axis, r.frequency_hz, r.bench, r.direction, r.amplitude_m_s2): r
        for r in rows
    }
    return [dataclasses.replace(r, row=i) for i, r in enumerate(unique.values(), start=2)]


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(result_rows(), min_size=1, max_size=8), st.sampled_from([",", ";"]))
def test_csv_round_trip(rows: list[ResultRow], delimiter: str) -> None:
    rows = _numbered(rows)
    assert parse_table(write_table(rows, delimiter=delimiter)) == rows


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(result_rows(), min_size=1, max_size=5))
def test_xlsx_round_trip(rows: list[ResultRow]) -> None:
    rows = _numbered(rows)
    parsed = parse_table(write_table(rows, format="xlsx"))
    # openpyxl writes numbers with 16 significant digits (Excel itself keeps 15).
    numeric = ("frequency_hz", "sensitivity", "expanded_uncertainty", "coverage_factor")
    for got, want in zip(parsed, rows, strict=True):
        for name in numeric:
            assert getattr(got, name) == pytest.approx(getattr(want, name), rel=1e-15)
        loose = {name: getattr(got, name) for name in numeric}
        loose["amplitude_m_s2"] = got.amplitude_m_s2
        loose["dof"] = got.dof
        assert got == dataclasses.replace(want, **loose)
        assert (got.amplitude_m_s2 is None) == (want.amplitude_m_s2 is None)
        assert got.dof == pytest.approx(want.dof, rel=1e-15) if want.dof else got.dof is None
