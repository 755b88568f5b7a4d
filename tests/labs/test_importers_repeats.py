"""The optional repeatability columns of the results table: ``repeat_sd`` and ``n_repeats``.

No database: run with ``pytest tests/labs/test_importers_repeats.py -p no:django``.
"""

from __future__ import annotations

import pytest

from labs.importers import ImportErrors, parse_rows, parse_table, write_table
from labs.importers.values import mg_per_lsb_to_canonical
from tests.labs.test_importers import BASE, errors, row_with, table, xlsx

PAIR = "the within-laboratory standard deviation and its number of repeats go together"
WHOLE = "must be a whole number from 2 to 1,000,000,000 (the repeats behind repeat_sd), got"


def test_both_columns_are_read() -> None:
    [row] = parse_table(table(row_with(repeat_sd="0.35", n_repeats="5")))
    assert (row.repeat_sd, row.n_repeats) == (0.35, 5)
    assert isinstance(row.n_repeats, int)


def test_tables_without_them_keep_their_meaning() -> None:
    [row] = parse_table(table(BASE))
    assert (row.repeat_sd, row.n_repeats) == (None, None)
    [blank] = parse_table(table(row_with(repeat_sd=" ", n_repeats="")))
    assert (blank.repeat_sd, blank.n_repeats) == (None, None)


def test_rows_may_mix_with_and_without() -> None:
    rows = parse_table(table(row_with(repeat_sd="0.3", n_repeats="4"), row_with(axis="Y")))
    assert [(r.repeat_sd, r.n_repeats) for r in rows] == [(0.3, 4), (None, None)]


def test_one_without_the_other_is_refused_naming_the_missing_column() -> None:
    data = table(BASE, row_with(axis="Y", repeat_sd="0.3"), row_with(axis="Z", n_repeats="3"))
    assert errors(data) == [
        (3, "n_repeats", f"is required when repeat_sd is given: {PAIR}"),
        (4, "repeat_sd", f"is required when n_repeats is given: {PAIR}"),
    ]


RULES = [
    ("repeat_sd", "0", "must be > 0, got 0"),
    ("repeat_sd", "-0.2", "must be > 0, got -0.2"),
    ("repeat_sd", "nan", "must be a finite number, got 'nan'"),
    ("repeat_sd", "inf", "must be a finite number, got 'inf'"),
    ("repeat_sd", "ten", "must be a number, got 'ten'"),
    ("repeat_sd", "٠٫٣", "must be a number, got '٠٫٣'"),
    ("repeat_sd", "０.３", "must be a number, got '０.３'"),
    ("repeat_sd", "0,3", "must be a number with a decimal point, got '0,3' (a decimal comma "
                         "is accepted only in semicolon-separated files)"),
    ("repeat_sd", "1e31", "must be between 1e-30 and 1e30 (the range the statistics can carry), "
                          "got 1e+31"),
    ("repeat_sd", "1e-31", "must be between 1e-30 and 1e30 (the range the statistics can carry), "
                           "got 1e-31"),
    ("repeat_sd", "0.3\x00", "contains the control character U+0000 at position 4; remove it "
                             "(NUL and other control characters cannot be stored)"),
    ("n_repeats", "1", f"{WHOLE} 1"),
    ("n_repeats", "2.5", f"{WHOLE} 2.5"),
    ("n_repeats", "1e10", f"{WHOLE} 1e10"),
    ("n_repeats", "0", "must be > 0, got 0"),
    ("n_repeats", "-3", "must be > 0, got -3"),
    ("n_repeats", "٣", "must be a number, got '٣'"),
    ("n_repeats", "three", "must be a number, got 'three'"),
    ("n_repeats", "inf", "must be a finite number, got 'inf'"),
    ("n_repeats", "3\x07", "contains the control character U+0007 at position 2; remove it "
                           "(NUL and other control characters cannot be stored)"),
]  # fmt: skip


@pytest.mark.parametrize(("field", "value", "message"), RULES)
def test_column_rule(field: str, value: str, message: str) -> None:
    pair = {"repeat_sd": "0.3", "n_repeats": "3"} | {field: value}
    data = table(BASE, row_with(axis="Y"), {**row_with(axis="Z"), **pair})
    assert errors(data) == [(4, field, message)]


def test_whole_numbers_written_as_decimals_are_accepted() -> None:
    [row] = parse_table(table(row_with(repeat_sd="0.3", n_repeats="3.0")))
    assert row.n_repeats == 3


def test_semicolon_table_with_decimal_comma() -> None:
    data = table(row_with(sensitivity="418,5", repeat_sd="0,25", n_repeats="6"), sep=";")
    [row] = parse_table(data)
    assert (row.sensitivity, row.repeat_sd, row.n_repeats) == (418.5, 0.25, 6)


def test_mg_per_lsb_keeps_the_relative_size_of_repeat_sd() -> None:
    [row] = parse_table(
        table(row_with(sensitivity="0.244", expanded_uncertainty="0.00244", unit="mg/LSB",
                       repeat_sd="0.000488", n_repeats="10"))
    )  # fmt: skip
    converted = mg_per_lsb_to_canonical(0.244)
    assert row.sensitivity == converted
    assert row.repeat_sd == pytest.approx(converted * 0.002, rel=1e-14)
    assert row.original_unit == "mg/LSB"


def test_xlsx_numeric_cells() -> None:
    header: list[object] = [*BASE, "repeat_sd", "n_repeats"]
    data = xlsx([header, ["MEMS 1", "X", 10, "linear", 418, 4.2, 0.31, 4],
                 ["MEMS 1", "Y", 10, "linear", 418, 4.2, 0.29, 4.0],
                 ["MEMS 1", "Z", 10, "linear", 418, 4.2, 0.29, 4.5]])  # fmt: skip
    with pytest.raises(ImportErrors) as caught:
        parse_table(data)
    assert [(e.row, e.field, e.message) for e in caught.value.errors] == [
        (4, "n_repeats", f"{WHOLE} 4.5")
    ]
    rows = parse_table(xlsx([header, ["MEMS 1", "X", 10, "linear", 418, 4.2, 0.31, 4]]))
    assert (rows[0].repeat_sd, rows[0].n_repeats) == (0.31, 4)


def test_json_rows_take_numbers_and_strings() -> None:
    rows = parse_rows(
        [{**BASE, "repeat_sd": 0.3, "n_repeats": 3}, {**BASE, "axis": "Y", "REPEAT_SD": "0.4",
                                                     "n_repeats": "5"}]
    )  # fmt: skip
    assert [(r.repeat_sd, r.n_repeats) for r in rows] == [(0.3, 3), (0.4, 5)]
    with pytest.raises(ImportErrors) as caught:
        parse_rows([{**BASE, "repeat_sd": 0.3, "n_repeats": True}, {**BASE, "n_repeats": 3}])
    assert [(e.row, e.field, e.message) for e in caught.value.errors] == [
        (1, "n_repeats", "must be a number, got True"),
        (2, "repeat_sd", f"is required when n_repeats is given: {PAIR}"),
    ]


def test_written_and_read_back() -> None:
    rows = parse_table(table(row_with(repeat_sd="0.123456789012345", n_repeats="7"),
                             row_with(axis="Y")))  # fmt: skip
    text = write_table(rows).decode("utf-8-sig")
    assert text.splitlines()[0].endswith(",dof,repeat_sd,n_repeats,note")
    assert parse_table(write_table(rows)) == rows
    assert parse_table(write_table(rows, format="xlsx")) == rows


def test_downloads_without_repeat_data_keep_the_old_columns() -> None:
    rows = parse_table(table(BASE))
    assert "repeat_sd" not in write_table(rows).decode("utf-8-sig").splitlines()[0]
