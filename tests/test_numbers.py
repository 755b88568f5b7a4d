"""One rounding rule for the numbers people read (common.numbers, docs/domain.md §3.1)."""

import math
from decimal import Decimal

import pytest
from hypothesis import given
from hypothesis import strategies as st

from common.numbers import (
    column_places,
    fixed,
    percent_fraction,
    plain,
    round_to_uncertainty,
    significant,
    uncertainty,
    uncertainty_exponent,
    value_with_uncertainty,
)


@pytest.mark.parametrize(
    ("x", "u", "expected"),
    [
        # GUM 7.2.2: m_s = 100.021 47 g with u = 0.35 mg (in grams)
        (100.02147, 0.00035, ("100.02147", "0.00035")),
        (419.4712, 0.1349, ("419.47", "0.13")),
        # the coordinator's review page planted 3.4160160000000004 with U = 0.0123
        (3.4160160000000004, 0.0123, ("3.416", "0.012")),
        # the version page's U = 12.751038232238182 beside a sensitivity of 637.55
        (637.5519116119091, 12.751038232238182, ("638", "13")),
        # a carry to a new leading digit keeps two significant digits: 9.96 -> 10, not 10.0
        (123.456, 9.96, ("123", "10")),
        (0.123456, 0.0996, ("0.12", "0.10")),
        # large numbers never use an exponent
        (1234567.0, 12345.0, ("1235000", "12000")),
        # small numbers neither
        (4.19e-7, 1.3e-9, ("0.0000004190", "0.0000000013")),
        # a value smaller than its uncertainty's last place; no negative zero
        (-0.001, 0.5, ("0.00", "0.50")),
        (-41.93, 0.27, ("-41.93", "0.27")),
        # ties to even on the exact binary value, as format() and the PDF: 0.125 -> 0.12
        (1.0, 0.125, ("1.00", "0.12")),
        (1.0, 0.135, ("1.00", "0.14")),  # 0.135 is stored as 0.13500000000000000888
        (2.675, 0.11, ("2.67", "0.11")),  # 2.675 is stored as 2.674999999999999822...
    ],
)
def test_value_with_uncertainty_worked_examples(x, u, expected):
    assert value_with_uncertainty(x, u) == expected


@pytest.mark.parametrize(
    ("x", "u", "expected"),
    [
        (3.4160160000000004, None, ("3.416016", "")),
        (3.4160160000000004, 0.0, ("3.416016", "0")),
        (419.0, float("nan"), ("419", "NaN")),
        (419.0, float("inf"), ("419", "∞")),
        (float("nan"), 0.2, ("NaN", "0.20")),
        (float("-inf"), 0.2, ("−∞", "0.20")),
        (None, 0.2, ("", "0.20")),
        (None, None, ("", "")),
        (419.47, -0.13, ("419.47", "0.13")),  # an uncertainty is shown by its size
    ],
)
def test_value_without_a_usable_uncertainty(x, u, expected):
    assert value_with_uncertainty(x, u) == expected


def test_round_to_uncertainty_is_the_value_column():
    assert round_to_uncertainty(419.4712, 0.1349) == "419.47"
    assert round_to_uncertainty(5.0, 0.0123) == "5.000"  # trailing zeros kept: they count
    assert round_to_uncertainty(None, 0.1) == ""


def test_plain_drops_binary_noise_and_exponents():
    assert plain(3.4160160000000004) == "3.416016"
    assert plain(0.1 + 0.2) == "0.3"
    assert plain(420.0) == "420"
    assert plain(4.19e2) == "419"
    assert plain(1e-7) == "0.0000001"
    assert plain(1.5e20) == "150000000000000000000"
    assert plain(-0.0) == "0"
    assert plain(None) == ""


def test_scores_as_the_pdf_writes_them():
    assert fixed(0.125, 2) == format(0.125, ".2f") == "0.12"
    assert fixed(-1.005, 2) == "-1.00"  # -1.005 is stored as -1.00499999...
    assert fixed(None, 2) == ""
    assert fixed(float("nan"), 2) == "NaN"
    assert significant(0.0123456, 4, sign=True) == "+0.01235"
    assert significant(-12.3456, 4, sign=True) == "-12.35"
    assert significant(0.00001234, 4, sign=True) == "+0.00001234"  # .4g: 1.234e-05
    assert significant(1234.5, 4) == "1234"  # ties to even, as format(1234.5, ".4g")
    assert significant(0.0, 4, sign=True) == "0"


def test_uncertainty_alone():
    assert uncertainty(12.751038232238182) == "13"
    assert uncertainty(0.00035) == "0.00035"
    assert uncertainty(0.0) == "0"
    assert uncertainty(None) == ""
    assert uncertainty_exponent(0.1349) == -2
    assert uncertainty_exponent(9.96) == 0


def test_percent_fraction_from_the_decimal_text():
    assert percent_fraction(1.2) == 0.012
    assert percent_fraction(0.7) == 0.007 != 0.7 / 100
    assert 4.195 * percent_fraction(1.2) == 4.195 * 0.012 != 4.195 * 1.2 / 100


finite = st.floats(min_value=-1e12, max_value=1e12, allow_nan=False, allow_infinity=False)
positive = st.floats(min_value=1e-12, max_value=1e9, allow_nan=False, allow_infinity=False)


def _places(text: str) -> int:
    return len(text.split(".")[1]) if "." in text else 0


@given(finite, positive)
def test_rounded_value_is_within_half_a_unit_of_its_last_digit(x, u):
    x_text, u_text = value_with_uncertainty(x, u)
    exponent = uncertainty_exponent(u)
    half = Decimal(1).scaleb(exponent) / 2
    assert abs(Decimal(x_text) - Decimal(x)) <= half
    assert abs(Decimal(u_text) - Decimal(u)) <= half
    assert "e" not in x_text.lower() and "e" not in u_text.lower()
    # value and uncertainty end at the same decimal place
    assert _places(x_text) == _places(u_text) == max(0, -exponent)


@given(finite, positive)
def test_uncertainty_has_exactly_two_significant_digits(x, u):
    _, u_text = value_with_uncertainty(x, u)
    digits = Decimal(u_text).as_tuple().digits
    exponent = uncertainty_exponent(u)
    # the digits from the leading one down to the last place written: two
    assert Decimal(u_text).adjusted() - exponent + 1 == 2
    assert digits[0] != 0
    if exponent <= 0:  # every digit written is significant
        assert len(u_text.replace(".", "").lstrip("0")) == 2


@given(finite, positive)
def test_rounding_agrees_with_format_as_the_pdf(x, u):
    exponent = uncertainty_exponent(u)
    if exponent < 0:
        expected = format(x, f".{-exponent}f")
        if float(expected) == 0:
            expected = expected.lstrip("-")
        assert round_to_uncertainty(x, u) == expected


@given(st.floats(min_value=-1e300, max_value=1e300, allow_nan=False))
def test_plain_gives_the_number_back_to_fifteen_digits(x):
    text = plain(x)
    assert "e" not in text.lower()
    assert math.isclose(float(text), x, rel_tol=1e-14, abs_tol=0.0) or x == 0


def test_signed_value_to_its_uncertainty_and_column_places():
    assert round_to_uncertainty(4.0, 0.011, sign=True) == "+4.000"
    assert round_to_uncertainty(1.4684, 0.013, sign=True) == "+1.468"
    assert round_to_uncertainty(-2.0, 0.013, sign=True) == "-2.000"
    assert round_to_uncertainty(0.0001, 0.013, sign=True) == "0.000"  # no sign on a zero
    assert column_places([422.0, 419.468]) == 3  # six significant digits of 422
    assert column_places([0.00123, None, math.nan]) == 8
    assert column_places([123456789.0]) == 0 and column_places([]) == 0


def test_a_value_far_above_its_uncertainty_is_written_as_it_is_not_to_600_digits():
    from common.numbers import plain, round_to_uncertainty, value_with_uncertainty

    # 1e308 ± 1e-300 would need ~600 digits (decimal.InvalidOperation before)
    assert value_with_uncertainty(1e308, 1e-300)[0] == plain(1e308)
    assert round_to_uncertainty(1e308, 1e-300, sign=True) == "+" + plain(1e308)
    assert round_to_uncertainty(419.4712, 0.1349) == "419.47"  # the rule holds below
