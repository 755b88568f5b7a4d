"""Aggregation rule of docs/domain.md §3: x̄, u(x̄) = √(ū² + s²), U = k·u(x̄)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from analysis.core.aggregate import aggregate, check_coverage_factor
from analysis.core.groups import CoreInputError, Groups


def test_single_result_keeps_its_own_uncertainty() -> None:
    # n = 1: x̄ = 420, s = 0 by definition (no NaN), ū = 2.5, u = √(2.5² + 0) = 2.5, U = 5.0
    agg = aggregate([420.0], [2.5], Groups.from_index([0]))
    assert agg.mean.tolist() == [420.0]
    assert agg.s.tolist() == [0.0]
    assert agg.u_mean.tolist() == [2.5]
    assert agg.standard_uncertainty.tolist() == [2.5]
    assert agg.expanded_uncertainty.tolist() == [5.0]
    assert agg.n.tolist() == [1]
    assert agg.coverage_factor == 2.0


def test_three_results_worked_by_hand() -> None:
    # x = 419, 421, 426 → x̄ = 1266/3 = 422
    # deviations −3, −1, +4 → Σd² = 9 + 1 + 16 = 26, s² = 26/2 = 13, s = 3.605551
    # u = 2, 3, 4 → ū = 3;  u(x̄) = √(3² + 13) = √22 = 4.690416;  U(k=2) = 9.380832
    agg = aggregate([419.0, 421.0, 426.0], [2.0, 3.0, 4.0], Groups.from_index([0, 0, 0]))
    assert agg.mean[0] == pytest.approx(422.0, abs=1e-12)
    assert agg.s[0] == pytest.approx(math.sqrt(13.0), rel=1e-14)
    assert agg.u_mean[0] == pytest.approx(3.0, rel=1e-14)
    assert agg.standard_uncertainty[0] == pytest.approx(math.sqrt(22.0), rel=1e-14)
    assert agg.expanded_uncertainty[0] == pytest.approx(2 * math.sqrt(22.0), rel=1e-14)


def test_groups_are_independent_and_k_is_applied() -> None:
    # group 0: the n = 3 case above; group 1: n = 1; group 2: two equal values → s = 0
    x = [419.0, 500.0, 421.0, 10.0, 426.0, 10.0]
    u = [2.0, 1.0, 3.0, 0.5, 4.0, 1.5]
    agg = aggregate(x, u, Groups.from_index([0, 1, 0, 2, 0, 2]), k=3.0)
    assert agg.mean == pytest.approx([422.0, 500.0, 10.0])
    assert agg.n.tolist() == [3, 1, 2]
    assert agg.s == pytest.approx([math.sqrt(13.0), 0.0, 0.0])
    assert agg.standard_uncertainty == pytest.approx([math.sqrt(22.0), 1.0, 1.0])
    assert agg.expanded_uncertainty == pytest.approx([3 * math.sqrt(22.0), 3.0, 3.0])


def test_small_spread_on_a_large_level_loses_no_digits() -> None:
    # two-pass sum: values 420 ± 1e-6 must give s = 1e-6 (ddof=1 of ±1e-6 about the mean · √2)
    agg = aggregate([420.0 - 1e-6, 420.0 + 1e-6], [1.0, 1.0], Groups.from_index([0, 0]))
    assert agg.s[0] == pytest.approx(math.sqrt(2) * 1e-6, rel=1e-6)


group_sizes = st.lists(st.integers(min_value=1, max_value=6), min_size=1, max_size=8)


@st.composite
def grouped_results(draw: st.DrawFn) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    sizes = draw(group_sizes)
    index = np.repeat(np.arange(len(sizes)), sizes)
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    rng.shuffle(index)
    x = rng.normal(420.0, 3.0, index.size)
    u = rng.uniform(1.0, 6.0, index.size)
    return x, u, index


@settings(max_examples=60, deadline=None)
@given(grouped_results())
def test_vectorised_equals_per_group(data: tuple[np.ndarray, np.ndarray, np.ndarray]) -> None:
    x, u, index = data
    agg = aggregate(x, u, Groups.from_index(index))
    for g in range(int(index.max()) + 1):
        xs, us = x[index == g], u[index == g]
        s = float(np.std(xs, ddof=1)) if xs.size > 1 else 0.0
        assert agg.mean[g] == pytest.approx(xs.mean(), rel=1e-13)
        assert agg.s[g] == pytest.approx(s, rel=1e-9, abs=1e-12)
        assert agg.standard_uncertainty[g] == pytest.approx(math.hypot(us.mean(), s), rel=1e-12)


@settings(max_examples=40, deadline=None)
@given(grouped_results(), st.floats(min_value=1e-3, max_value=1e3))
def test_scaling_units_scales_everything(
    data: tuple[np.ndarray, np.ndarray, np.ndarray], c: float
) -> None:
    x, u, index = data
    groups = Groups.from_index(index)
    a, b = aggregate(x, u, groups), aggregate(c * x, c * u, groups)
    np.testing.assert_allclose(b.mean, c * a.mean, rtol=1e-12)
    np.testing.assert_allclose(b.standard_uncertainty, c * a.standard_uncertainty, rtol=1e-9)


@settings(max_examples=40, deadline=None)
@given(grouped_results(), st.integers(0, 2**32 - 1))
def test_order_of_results_does_not_matter(
    data: tuple[np.ndarray, np.ndarray, np.ndarray], seed: int
) -> None:
    x, u, index = data
    perm = np.random.default_rng(seed).permutation(x.size)
    a = aggregate(x, u, Groups.from_index(index))
    b = aggregate(x[perm], u[perm], Groups.from_index(index[perm]))
    np.testing.assert_allclose(b.mean, a.mean, rtol=1e-13)
    np.testing.assert_allclose(b.standard_uncertainty, a.standard_uncertainty, rtol=1e-9)


@pytest.mark.parametrize(
    ("x", "u", "index", "message"),
    [
        ([420.0, np.nan], [1.0, 1.0], [0, 0], r"x\[1\] must be finite"),
        ([420.0, np.inf], [1.0, 1.0], [0, 0], r"x\[1\] must be finite"),
        ([420.0, 421.0], [1.0, 0.0], [0, 0], r"u\[1\] must be finite and > 0"),
        ([420.0, 421.0], [-1.0, 1.0], [0, 0], r"u\[0\] must be finite and > 0"),
        ([420.0, 421.0], [1.0, np.nan], [0, 0], r"u\[1\]"),
        ([], [], [], "empty"),
        ([420.0, 421.0], [1.0], [0, 0], "same length"),
        ([420.0, 421.0], [1.0, 1.0], [0], "same length"),
    ],
)
def test_bad_input_is_refused(x: list, u: list, index: list, message: str) -> None:
    with pytest.raises(CoreInputError, match=message):
        aggregate(x, u, Groups.from_index(index))


def test_empty_group_is_refused() -> None:
    with pytest.raises(CoreInputError, match="group 1 has no results"):
        aggregate([420.0, 421.0], [1.0, 1.0], Groups.from_index([0, 2]))


@pytest.mark.parametrize("k", [0.0, -2.0, math.nan, math.inf, "2"])
def test_bad_coverage_factor_is_refused(k: object) -> None:
    with pytest.raises(CoreInputError, match="coverage factor"):
        aggregate([420.0], [1.0], Groups.from_index([0]), k=k)  # type: ignore[arg-type]


def test_coverage_factor_accepts_numpy_numbers() -> None:
    assert check_coverage_factor(np.float32(2.0)) == 2.0
    assert check_coverage_factor(np.int64(3)) == 3.0
