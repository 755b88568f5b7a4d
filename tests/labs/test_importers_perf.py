"""The importer's fast column-wise path agrees with the precise per-row path, and scales.

No database: run with ``pytest tests/labs/test_importers_perf.py -p no:django``.
"""

from __future__ import annotations

import csv
import datetime as dt
import io
import math

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from labs.importers import ImportErrors, PointKey, ResultRow, TableContext, parse_table
from labs.importers.columns import validate_records_fast
from labs.importers.matching import FrequencyIndex
from labs.importers.readers import read_sheet
from labs.importers.schema import LabColumn
from labs.importers.validate import cells_to_record, check_header, validate_records

NUMBER_TEXTS = [
    "418", "417.9", "4,18", "1.417,9", "1,2,3", "1_0", " 12 ", "nan", "NaN", "inf", "+inf",
    "-inf", "Infinity", "1e999", "0", "-0", "-3", "'=1", "'-3", "١٢", "1.", ".5", "+.5e-3",
    "5e", "1%", "1,5 %", "-1 %", "a%", "0%", "", "  ", "ten", "\u20035", "5\x00",
]  # fmt: skip
NUMBERS = st.one_of(
    st.sampled_from(NUMBER_TEXTS),
    st.floats(allow_nan=True, allow_infinity=True),
    st.integers(min_value=-5, max_value=10**400),
    st.sampled_from([None, True, False, dt.date(2024, 1, 5), 10, 5.0, 20.0, -0.0]),
)
FREQUENCIES = st.one_of(
    st.sampled_from(["10", "10.0", "10.000000000001", "5", "5,0", "20", "12", "0", "x"]),
    NUMBERS,
)
FIELDS = {
    "device": st.sampled_from(["MEMS 1", " mems  1 ", "IEPE 1", "MEMS 9", "", None, 12, "'=x"]),
    "axis": st.sampled_from(["X", "y", "Z", "W", "", None, 1.0]),
    "frequency_hz": FREQUENCIES,
    "bench": st.sampled_from(["linear", "Curvilinear", "rotary", "centrifuge", "", None]),
    "direction": st.sampled_from(["", "vertical", "radial", "TANGENTIAL", "up", None]),
    "amplitude_m_s2": st.one_of(st.sampled_from(["", "10", "20", "10,0"]), NUMBERS),
    "sensitivity": NUMBERS,
    "unit": st.sampled_from(
        ["", "D/(m/s^2)", "mg/LSB", "MG/lsb", "mV/(m/s^2)", "V/g", "LSB/(m/s²)"]
    ),
    "expanded_uncertainty": NUMBERS,
    "coverage_factor": NUMBERS,
    "dof": NUMBERS,
    "repeat_sd": st.one_of(st.sampled_from(["", "0.3", "0,3", "1e-31"]), NUMBERS),
    "n_repeats": st.one_of(st.sampled_from(["", "3", "2.0", "1", "2.5", "1e10"]), NUMBERS),
    "lab": st.sampled_from(["", "L01", "L02", None, " "]),
    "note": st.sampled_from(["", "ok", "x" * 501, "'=x", " mounted "]),
}  # fmt: skip
VALID = {
    "device": st.sampled_from(["MEMS 1", "mems 1"]),
    "axis": st.sampled_from(["X", "Y"]),
    "frequency_hz": st.sampled_from(["5", "10", "20", 10.0]),
    "bench": st.just("linear"),
    "sensitivity": st.floats(min_value=1e-3, max_value=1e6) | st.sampled_from(["418", "0.244"]),
    "expanded_uncertainty": st.sampled_from(["4.2", "1%", 0.5, "2,5"]),
    "unit": st.sampled_from(["", "mg/LSB", "D/(m/s^2)"]),
}
CONTEXTS = [
    None,
    TableContext(
        device_units={"MEMS 1": "D/(m/s^2)", "IEPE 1": "mV/(m/s^2)"},
        axes=("X", "Y"),
        frequencies_hz=(5.0, 10.0, 20.0),
    ),
    TableContext.from_points(
        [
            ("MEMS 1", "X", 10.0, "linear", "vertical", 10.0),
            ("MEMS 1", "X", 10.0, "linear", "vertical", 20.0),
            ("MEMS 1", "Y", 10.0, "linear", "vertical"),
            ("MEMS 1", "Y", 5.0, "curvilinear", "radial"),
            ("IEPE 1", "Z", 20.0, "linear", "vertical"),
        ],
        device_units={"IEPE 1": "mV/(m/s^2)"},
    ),
    TableContext(
        benches=("linear", "centrifuge"),
        directions={"linear": ("vertical",), "centrifuge": ("radial",)},
    ),
]
RECORD = st.fixed_dictionaries({}, optional=FIELDS)
REPEATS = {
    "repeat_sd": st.sampled_from(["0.3", 0.02, "1e-29"]),
    "n_repeats": st.sampled_from(["3", 5]),
}
VALID_RECORD = st.fixed_dictionaries(VALID, optional={"lab": FIELDS["lab"], **REPEATS})
OPTIONS = st.fixed_dictionaries(
    {
        "decimal_comma": st.booleans(),
        "lab_column": st.sampled_from(["optional", "forbidden", "required"]),
        "context": st.sampled_from(CONTEXTS),
    }
)


def outcome(
    validate, *args, **kwargs
) -> list[ResultRow] | list[tuple[int | None, str | None, str]]:
    """The rows, or the errors as tuples (ImportErrors is compared by its list)."""
    try:
        return validate(*args, **kwargs)
    except ImportErrors as caught:
        return [(e.row, e.field, e.message) for e in caught.errors]


def same(a: object, b: object) -> bool:
    """Equality that takes NaN == NaN (a NaN never reaches a row, but be exact about it)."""
    return a == b or repr(a) == repr(b)


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(st.one_of(RECORD, VALID_RECORD), max_size=12), OPTIONS)
def test_fast_and_precise_validation_agree(records: list[dict], options: dict) -> None:
    numbered = [(n, record) for n, record in enumerate(records, start=2)]
    precise = outcome(validate_records, numbered, **options)
    fast = outcome(validate_records_fast, numbered, **options)
    assert same(fast, precise)


def precise_parse(
    data: bytes, *, lab_column: LabColumn, context: TableContext | None
) -> list[ResultRow]:
    """The importer before the fast path: per row, record by record."""
    sheet = read_sheet(data, filename=None, content_type=None, max_rows=10**6)
    names = check_header(sheet.header, lab_column=lab_column, row=sheet.header_row)
    columns = [name for name in names if name]  # a sheet's rows hold the named cells only
    errors, records = list(sheet.errors), []
    for number, cells in sheet.rows:
        record, cell_errors = cells_to_record(columns, cells, number)
        errors.extend(cell_errors)
        records.append((number, record))
    return validate_records(
        records,
        decimal_comma=sheet.decimal_comma,
        errors=errors,
        lab_column=lab_column,
        context=context,
    )


def text(value: object) -> str:
    return "" if value is None else str(value)


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    st.lists(st.one_of(RECORD, VALID_RECORD), min_size=1, max_size=10),
    st.sampled_from([",", ";"]),
    st.lists(st.sampled_from(["", "stray", " "]), max_size=2),
    st.sampled_from(["optional", "forbidden"]),
    st.sampled_from(CONTEXTS),
)
def test_fast_and_precise_tables_agree(
    records: list[dict], sep: str, extra: list[str], lab_column: str, context: TableContext
) -> None:
    names = ["device", "axis", "frequency_hz", "bench", "sensitivity", "expanded_uncertainty"]
    names += [n for n in dict.fromkeys(k for r in records for k in r) if n not in names]
    buffer = io.StringIO()
    writer = csv.writer(buffer, delimiter=sep, lineterminator="\n")
    writer.writerow([*names, *([""] if extra else [])])  # a column with no header
    for i, record in enumerate(records):
        cells = [text(record.get(n)) for n in names]
        writer.writerow(cells + extra if i % 2 else cells[: len(cells) - i % 3])  # ragged rows
    data = buffer.getvalue().encode()
    options = {"lab_column": lab_column, "context": context}
    assert same(outcome(parse_table, data, **options), outcome(precise_parse, data, **options))


@settings(max_examples=60, deadline=None)
@given(
    st.lists(
        st.one_of(
            st.floats(min_value=-1e6, max_value=1e6), st.sampled_from([10.0, 10.0 + 1e-9, 0.0])
        ),
        max_size=20,
    ),
    st.one_of(st.floats(allow_nan=True), st.sampled_from([10.0, 10.00000001, -0.0])),
    st.sampled_from([0.0, 1e-12, 1e-9, 1e-3, 0.3, 0.7]),
)
def test_frequency_index_finds_what_a_scan_finds(
    keys: list[float], frequency: float, tol: float
) -> None:
    index = FrequencyIndex(((f, i) for i, f in enumerate(keys)), tol)
    scan = [i for i, f in enumerate(keys) if math.isclose(f, frequency, rel_tol=tol, abs_tol=0)]
    assert index.find(frequency) == scan


def big_csv(n_rows: int) -> tuple[bytes, list[PointKey]]:
    points = [
        PointKey(f"MEMS {d}", axis, 1.0 + 0.5 * i, "linear", "vertical")
        for d in range(1, 26)
        for axis in "XYZ"
        for i in range(1334)
    ][:n_rows]
    lines = ["device,axis,frequency_hz,bench,sensitivity,expanded_uncertainty"]
    lines += [
        f"{p.device},{p.axis},{p.frequency_hz:g},linear,{418 + i % 97 / 10:.4f},4.18%"
        for i, p in enumerate(points)
    ]
    return ("\n".join(lines) + "\n").encode(), points


def test_100k_row_csv_parses_to_100k_rows() -> None:
    """Size, not time: the limit table of docs/interfaces.md §1 is read whole (≈1 s on 2 cores)."""
    data, points = big_csv(100_000)
    assert len(data) < 5 * 2**20
    rows = parse_table(data, lab_column="forbidden", context=TableContext.from_points(points))
    assert len(rows) == 100_000
    assert (rows[-1].row, rows[-1].point) == (100_001, points[-1])
    assert rows[5].expanded_uncertainty == pytest.approx(rows[5].sensitivity * 0.0418)
