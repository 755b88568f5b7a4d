"""The ``quantity`` column of the results table (docs/interfaces.md §1, docs/domain.md §12):
no database, no Django.  Both readers of the importer (the column-wise one of files and the
per-record one) give the same rows and the same errors."""

from __future__ import annotations

import math
import re
from fractions import Fraction

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from analysis.core.phase import wrap
from common import quantities
from labs.importers import ImportErrors, PointKey, TableContext, parse_rows, parse_table
from labs.importers.validate import validate_records

from .test_importers import BASE, errors, row_with, table


def both(*records: dict[str, str], **kwargs: object) -> list:
    """The rows of a CSV of ``records`` and of the same records one by one (must agree)."""
    from_file = parse_table(table(*records), **kwargs)  # type: ignore[arg-type]
    one_by_one = validate_records(enumerate(records, start=2), **kwargs)  # type: ignore[arg-type]
    assert from_file == one_by_one
    return from_file


def test_registry_is_the_one_table():
    assert quantities.NAMES == ("magnitude", "phase", "angular_rate")
    assert quantities.parse("") == quantities.parse(None) == "magnitude"
    assert quantities.parse(" Phase ") == "phase"
    with pytest.raises(ValueError, match="must be one of magnitude, phase, angular_rate, got 'x'"):
        quantities.parse("x")
    assert set(quantities.CIRCULAR) == {"phase"}
    angles = [-540.0, -180.0, -179.5, 0.0, 179.5, 180.0, 190.0, 540.0, 1e6 + 0.25]
    assert [quantities.wrap_degrees(a) for a in angles] == wrap(angles).tolist()
    assert quantities.own_unit("angular_rate", "digits/(rad/s)") == ("D/(deg/s)", math.pi / 180)
    assert quantities.own_unit("magnitude", "mV/(m/s^2)") is None


def test_a_table_without_the_column_is_a_table_of_magnitudes():
    rows = both(row_with(), row_with(axis="Y"))
    assert [r.quantity for r in rows] == ["magnitude", "magnitude"]
    blank = both(row_with(quantity=""), row_with(axis="Y", quantity=""))
    assert blank == rows
    assert rows[0].point == PointKey("MEMS 1", "X", 10.0, "linear", "vertical", None)


def test_phases_are_stored_wrapped_and_any_finite_value_is_accepted():
    records = [
        row_with(quantity="phase", sensitivity=s, expanded_uncertainty="0.5", axis=a, unit=u)
        for s, a, u in (("-179.5", "X", ""), ("540", "Y", "deg"), ("-0", "Z", "°"))
    ]
    magnitude = row_with(frequency_hz="20")
    rows = both(*records, magnitude)
    assert [r.sensitivity for r in rows] == [-179.5, 180.0, 0.0, 418.0]
    assert [r.unit for r in rows] == ["deg", "deg", "deg", "D/(m/s^2)"]
    assert [r.quantity for r in rows] == ["phase"] * 3 + ["magnitude"]
    assert rows[0].point.quantity == "phase" and rows[0].expanded_uncertainty == 0.5


def test_angular_rate_per_rad_s_is_made_per_degree_keeping_the_relative_u():
    (row,) = both(
        row_with(quantity="angular_rate", sensitivity="57.2958", expanded_uncertainty="1%",
                 unit="LSB/(rad/s)")
    )  # fmt: skip
    assert row.unit == "D/(deg/s)"
    assert row.sensitivity == pytest.approx(57.2958 * math.pi / 180, rel=1e-15)
    assert row.expanded_uncertainty / row.sensitivity == pytest.approx(0.01, rel=1e-12)


def test_a_magnitude_and_a_phase_of_one_point_are_not_duplicates():
    rows = both(row_with(), row_with(quantity="phase", sensitivity="-3", unit=""))
    assert len(rows) == 2
    twice = table(row_with(quantity="phase", sensitivity="1"),
                  row_with(quantity="PHASE", sensitivity="2"))  # fmt: skip
    assert errors(twice)[0][:2] == (3, None)


@pytest.mark.parametrize(
    ("changes", "expected"),
    [
        ({"quantity": "foo"},
         ("quantity", "must be one of magnitude, phase, angular_rate, got 'foo'")),
        ({"quantity": "phase", "expanded_uncertainty": "1%"},
         ("expanded_uncertainty", "a phase's U is given in deg, not as a percentage, got '1%'")),
        ({"quantity": "phase", "unit": "mV/(m/s^2)"},
         ("unit", "a sensitivity phase is in deg, °, degree, degrees; got 'mV/(m/s^2)'")),
        ({"quantity": "phase", "sensitivity": "nan"}, ("sensitivity", None)),
        ({"quantity": "phase", "expanded_uncertainty": "-1"},
         ("expanded_uncertainty", "must be > 0, got -1")),
        ({"quantity": "magnitude", "sensitivity": "-3"}, ("sensitivity", "must be > 0, got -3")),
        ({"quantity": "angular_rate", "sensitivity": "-3"},
         ("sensitivity", "must be > 0, got -3")),
        ({"quantity": "ph\x00ase"}, ("quantity", None)),
    ],
)  # fmt: skip
def test_bad_cells_are_named_by_row_and_column(changes, expected):
    data = table(row_with(axis="Y"), row_with(**changes))
    found = errors(data)
    with pytest.raises(ImportErrors) as caught:
        validate_records([(2, row_with(axis="Y")), (3, row_with(**changes))])
    assert [(e.row, e.field, e.message) for e in caught.value.errors] == found
    (row, field, message), *_ = found
    assert (row, field) == (3, expected[0])
    if expected[1] is not None:
        assert message == expected[1]
    if "\x00" in changes.get("quantity", ""):
        assert "control character" in message


def test_error_text_as_the_interface_writes_it():
    with pytest.raises(ImportErrors) as caught:
        parse_table(table(*[row_with(axis=a) for a in "XYZ"], row_with(quantity="foo")))
    assert str(caught.value.errors[0]) == (
        "row 5, column quantity: must be one of magnitude, phase, angular_rate, got 'foo'"
    )


def test_api_rows_carry_the_quantity_too():
    rows = parse_rows([{**BASE, "quantity": "phase", "sensitivity": -90.25}, BASE])
    assert [(r.quantity, r.sensitivity) for r in rows] == [("phase", -90.25), ("magnitude", 418.0)]


def test_a_comparison_context_matches_the_row_of_its_kind_only():
    magnitude = PointKey("MEMS 1", "X", 10.0, "linear", "vertical")
    phase = magnitude._replace(quantity="phase")
    context = TableContext.from_points([magnitude, phase], device_units={"MEMS 1": "D/(m/s^2)"})
    rows = both(row_with(), row_with(quantity="phase", sensitivity="12"), context=context)
    assert [r.point for r in rows] == [magnitude, phase]
    only_magnitude = TableContext.from_points([magnitude])
    found = errors(table(row_with(quantity="phase", sensitivity="1")), context=only_magnitude)
    assert found == [
        (2, None, "no measurement point MEMS 1 / X / 10 Hz / linear / vertical / phase "
         "in this comparison")
    ]  # fmt: skip
    scoped = context.with_scope([magnitude], "magnitudes only")
    found = errors(table(row_with(quantity="phase", sensitivity="1")), context=scoped)
    assert found == [
        (2, None, "MEMS 1, X, 10 Hz, linear vertical, sensitivity phase is not in your scope "
         "(magnitudes only)")
    ]  # fmt: skip


def test_wrapping_a_huge_phase_is_exact():
    (row,) = both(row_with(quantity="phase", sensitivity="3600000000.5"))
    assert row.sensitivity == 0.5
    assert np.isfinite(row.sensitivity)


def _exact_wrap(value: float) -> float:
    r = Fraction(value) % 360
    return float(r - 360 if r > 180 else r)


#: phases the table takes: 0, or of a size the statistics carry (docs/interfaces.md §1)
PHASES = st.floats(min_value=-1e30, max_value=1e30).filter(lambda x: x == 0 or abs(x) >= 1e-30)


@settings(max_examples=200, deadline=None)
@given(PHASES, st.sampled_from(["{!r}", "{:.17g}", "{:+.17e}", "{:.17E}"]))
def test_any_phase_cell_is_stored_as_its_exact_wrap(value, spelling):
    """Positive generation: every way a program writes a phase in range is read, and
    stored as φ − 360°·n exactly (docs/domain.md §12), by both readers alike."""
    cell = spelling.format(value)
    (row,) = both(row_with(quantity="phase", sensitivity=cell, unit=""))
    assert row.sensitivity == _exact_wrap(float(cell))
    assert -180.0 < row.sensitivity <= 180.0
    assert row.sensitivity != 0.0 or math.copysign(1.0, row.sensitivity) == 1.0  # −0 is 0


NUMBER = re.compile(r"[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?", re.ASCII)
HOSTILE_NUMBERS = st.one_of(
    st.floats().filter(lambda x: not math.isfinite(x) or 0 < abs(x) < 1e-30 or abs(x) > 1e30)
    .map(repr),
    st.text(alphabet=st.characters(codec="utf-8"), min_size=1, max_size=12).filter(
        lambda t: not NUMBER.fullmatch(t.strip())
    ),
)  # fmt: skip


@settings(max_examples=300, deadline=None)
@given(HOSTILE_NUMBERS)
def test_a_phase_cell_out_of_range_or_no_number_is_named_and_nothing_is_read(cell):
    """Negative generation: not finite, out of range, or text that is no plain ASCII number
    (other scripts' digits, ``1_0``, control characters): one error on that row's
    sensitivity, the same from both readers, and no row."""
    record = row_with(quantity="phase", sensitivity=cell, unit="")
    with pytest.raises(ImportErrors) as caught:
        validate_records([(2, record)])
    found = [(e.row, e.field) for e in caught.value.errors]
    assert found == [(2, "sensitivity")], (cell, caught.value.errors)
    if "\r" not in cell:  # unquoted by csv.writer, a lone CR ends a CSV line
        assert [(r, f) for r, f, _ in errors(table(record))] == found  # the file reader agrees
