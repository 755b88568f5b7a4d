"""GUM conventions of analysis.core.uncertainty against hand-computed values."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from analysis.core.groups import CoreInputError
from analysis.core.uncertainty import (
    G_N,
    absolute_from_relative,
    coverage_factor,
    digits_per_ms2_to_mg_per_lsb,
    expanded_from_standard,
    mg_per_lsb_to_digits_per_ms2,
    standard_from_expanded,
    u_from_tolerance,
    welch_satterthwaite,
)

positive = st.floats(min_value=1e-6, max_value=1e6, allow_nan=False, allow_infinity=False)


def test_standard_and_expanded_are_inverse_by_hand() -> None:
    # 430 ± 11 (k = 2): u = 11 / 2 = 5.5 ; back: 2 · 5.5 = 11
    assert float(standard_from_expanded(11.0, 2.0)) == 5.5
    assert float(expanded_from_standard(5.5)) == 11.0
    np.testing.assert_allclose(standard_from_expanded([6.0, 9.0], [2.0, 3.0]), [3.0, 3.0])


@pytest.mark.parametrize("U", [0.0, -1.0, np.nan, np.inf])
def test_standard_from_expanded_rejects_bad_u(U: float) -> None:
    with pytest.raises(CoreInputError, match=r"U\[0\]"):
        standard_from_expanded(U, 2.0)


@pytest.mark.parametrize("k", [0.0, -2.0, np.nan, np.inf])
def test_bad_coverage_factor_is_rejected(k: float) -> None:
    with pytest.raises(CoreInputError, match=r"k\[0\]"):
        standard_from_expanded(1.0, k)
    with pytest.raises(CoreInputError, match=r"k\[0\]"):
        expanded_from_standard(1.0, k)


def test_error_names_the_bad_index() -> None:
    with pytest.raises(CoreInputError, match=r"U\[2\].*2 bad"):
        standard_from_expanded([1.0, 2.0, -1.0, 0.0], 2.0)


def test_absolute_from_relative() -> None:
    # 1 % of 418 = 4.18; the sign of the value does not matter
    assert float(absolute_from_relative(418.0, 1.0)) == pytest.approx(4.18, rel=1e-15)
    assert float(absolute_from_relative(-200.0, 0.5)) == pytest.approx(1.0, rel=1e-15)
    with pytest.raises(CoreInputError, match=r"value\[0\] is 0"):
        absolute_from_relative(0.0, 1.0)
    with pytest.raises(CoreInputError, match="U_percent"):
        absolute_from_relative(418.0, 0.0)


def test_rectangular_tolerance_reference_fact() -> None:
    # domain spec §3: 418 ± 1 % rectangular, u = 4.18/√3 = 2.413324..., U(k=2) = 4.826648...
    u = u_from_tolerance(absolute_from_relative(418.0, 1.0))
    assert float(u) == pytest.approx(4.18 / math.sqrt(3.0), rel=1e-14)
    assert round(float(u), 3) == 2.413
    assert float(expanded_from_standard(u)) == pytest.approx(4.8266482504, rel=1e-10)
    assert round(float(expanded_from_standard(u)), 3) == 4.827


@pytest.mark.parametrize(
    ("distribution", "k", "expected"),
    [
        ("rectangular", 2.0, 6.0 / math.sqrt(3.0)),
        ("triangular", 2.0, 6.0 / math.sqrt(6.0)),
        ("u-shaped", 2.0, 6.0 / math.sqrt(2.0)),
        ("normal", 2.0, 3.0),  # ±6 is an expanded uncertainty with k = 2
        ("normal", 3.0, 2.0),
    ],
)
def test_u_from_tolerance_distributions(distribution: str, k: float, expected: float) -> None:
    assert float(u_from_tolerance(6.0, distribution, k)) == pytest.approx(expected, rel=1e-15)  # type: ignore[arg-type]


def test_u_from_tolerance_bad_input() -> None:
    with pytest.raises(CoreInputError, match="unknown distribution"):
        u_from_tolerance(1.0, "gaussian")  # type: ignore[arg-type]
    with pytest.raises(CoreInputError, match="half_width"):
        u_from_tolerance(-1.0)
    with pytest.raises(CoreInputError, match="k"):
        u_from_tolerance(1.0, "normal", 0.0)


def test_coverage_factor_student_table() -> None:
    # printed t tables (two-sided 95 %): ν=1 12.706, ν=10 2.228, ν=∞ 1.960
    k = coverage_factor([1.0, 10.0, np.inf])
    np.testing.assert_allclose(k, [12.7062047, 2.2281389, 1.9599640], atol=1e-6)
    # 95.45 % with ν = ∞ is the GUM's k = 2
    assert float(coverage_factor(np.inf, p=0.9545)) == pytest.approx(2.0, abs=1e-3)
    assert float(coverage_factor(2.5)) > float(coverage_factor(3.0))  # non-integer ν works


@pytest.mark.parametrize("dof", [0.0, -1.0, np.nan])
def test_coverage_factor_bad_dof(dof: float) -> None:
    with pytest.raises(CoreInputError, match=r"dof\[0\]"):
        coverage_factor(dof)


@pytest.mark.parametrize("p", [0.0, 1.0, 1.5])
def test_coverage_factor_bad_p(p: float) -> None:
    with pytest.raises(CoreInputError, match="coverage probability"):
        coverage_factor(10.0, p)


def test_welch_satterthwaite_by_hand() -> None:
    # u = (1, 1), ν = (10, ∞): u_c⁴ = 4, Σu⁴/ν = 1/10 → ν_eff = 40
    # u = (1, 1), ν = (4, 4):  4 / (1/4 + 1/4) = 8
    # u = (1, 0), ν = (4, 5):  1 / (1/4) = 4
    got = welch_satterthwaite([[1, 1], [1, 1], [1, 0]], np.array([[10, np.inf], [4, 4], [4, 5]]))
    np.testing.assert_allclose(got, [40.0, 8.0, 4.0], rtol=1e-15)
    one = welch_satterthwaite([3.0, 4.0], [5.0, 5.0])  # 625 / (81/5 + 256/5) = 3125/337
    assert one.shape == ()
    assert float(one) == pytest.approx(3125 / 337, rel=1e-14)
    assert float(welch_satterthwaite([1.0, 2.0], np.inf)) == np.inf


def test_welch_satterthwaite_single_component_keeps_its_dof() -> None:
    assert float(welch_satterthwaite([0.7], [12.0])) == pytest.approx(12.0, rel=1e-14)


def test_welch_satterthwaite_bad_input() -> None:
    with pytest.raises(CoreInputError, match=r"u_components\[1\]"):
        welch_satterthwaite([1.0, -1.0], [3.0, 3.0])
    with pytest.raises(CoreInputError, match="quantity 1"):
        welch_satterthwaite([[1.0, 1.0], [0.0, 0.0]], 5.0)
    with pytest.raises(CoreInputError, match=r"dof\[1\]"):
        welch_satterthwaite([1.0, 1.0], [3.0, 0.0])
    with pytest.raises(CoreInputError, match="does not match"):
        welch_satterthwaite([1.0, 1.0], [3.0, 3.0, 3.0])
    with pytest.raises(CoreInputError, match="non-empty"):
        welch_satterthwaite(np.zeros((2, 2, 2)), 3.0)


def test_mg_per_lsb_reference_fact() -> None:
    # 1 / (0.244e-3 · 9.80665) = 1 / 0.0023928226 = 417.9165 D/(m/s²)
    s, big_u = mg_per_lsb_to_digits_per_ms2(0.244, 0.00244)  # 1 % relative
    assert G_N == 9.80665
    assert float(s) == pytest.approx(417.91648, rel=1e-7)
    assert float(big_u) == pytest.approx(0.01 * float(s), rel=1e-14)
    back, back_u = digits_per_ms2_to_mg_per_lsb(s, big_u)
    assert float(back) == pytest.approx(0.244, rel=1e-14)
    assert float(back_u) == pytest.approx(0.00244, rel=1e-14)
    with pytest.raises(CoreInputError, match=r"value\[0\]"):
        mg_per_lsb_to_digits_per_ms2(0.0, 0.1)


@given(positive, positive)
def test_conversion_keeps_relative_uncertainty(value: float, rel: float) -> None:
    s, big_u = mg_per_lsb_to_digits_per_ms2(value, value * rel)
    assert float(big_u / s) == pytest.approx(rel, rel=1e-12)


@given(positive, positive)
def test_expanded_standard_round_trip(U: float, k: float) -> None:
    assert float(expanded_from_standard(standard_from_expanded(U, k), k)) == pytest.approx(
        U, rel=1e-14
    )
