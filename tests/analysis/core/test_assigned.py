"""Assigned-value methods: hand-computed cases, brute-force references, properties."""

from __future__ import annotations

import math
from fractions import Fraction
from itertools import combinations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from analysis.core.assigned import (
    dersimonian_laird,
    largest_consistent_subset,
    nominal_value,
    reference_value,
    sigma_pt_given,
    sigma_pt_prescribed,
    weighted_mean,
)
from analysis.core.groups import CoreInputError, Groups
from analysis.core.types import AssignedValues

CHI2_95_2DOF = 5.991464547  # printed χ² table, ν = 2, 95 %

values = st.lists(
    st.tuples(
        st.floats(min_value=-10.0, max_value=10.0, allow_nan=False),
        st.floats(min_value=0.1, max_value=5.0, allow_nan=False),
    ),
    min_size=1,
    max_size=8,
)


def g0(n: int) -> Groups:
    return Groups.from_index(np.zeros(n, dtype=int))


def brute_force_lcs(x: list[float], u: list[float], alpha: float = 0.05) -> tuple[int, ...]:
    """Cox 2007 by plain enumeration, independent of the module (scipy only for χ²)."""
    from scipy.stats import chi2

    for size in range(len(x), 0, -1):
        best: tuple[float, tuple[int, ...]] | None = None
        for subset in combinations(range(len(x)), size):
            w = [1 / u[i] ** 2 for i in subset]
            y = sum(wi * x[i] for wi, i in zip(w, subset, strict=True)) / sum(w)
            c2 = sum(wi * (x[i] - y) ** 2 for wi, i in zip(w, subset, strict=True))
            if (size == 1 or c2 <= chi2.ppf(1 - alpha, size - 1)) and (
                best is None or c2 < best[0]
            ):
                best = (c2, subset)
        if best is not None:
            return best[1]
    raise AssertionError("unreachable")


# --- reference laboratory -------------------------------------------------------------


def test_reference_value() -> None:
    groups = Groups.from_index([0, 0, 1, 1, 1])
    a = reference_value(
        [10.0, 11.0, 20.0, 21.0, 22.0], [0.1, 0.2, 0.3, 0.4, 0.5], groups,
        np.array([False, True, False, False, True]),
    )  # fmt: skip
    np.testing.assert_array_equal(a.value, [11.0, 22.0])
    np.testing.assert_array_equal(a.standard_uncertainty, [0.2, 0.5])
    np.testing.assert_array_equal(a.diagnostics["reference_index"], [1, 4])
    np.testing.assert_array_equal(a.included, [False, True, False, False, True])
    assert a.method == "reference" and a.n_groups == 2


@pytest.mark.parametrize(
    ("is_ref", "match"),
    [
        ([True, False, False], "group 1 has no reference result"),
        ([True, True, True], "group 0 has 2 reference results"),
    ],
)
def test_reference_value_errors_name_the_group(is_ref: list[bool], match: str) -> None:
    with pytest.raises(CoreInputError, match=match):
        reference_value([1.0, 2.0, 3.0], [1.0] * 3, Groups.from_index([0, 0, 1]), np.array(is_ref))


# --- nominal value --------------------------------------------------------------------


def test_nominal_value_reference_fact() -> None:
    # 418 ± 1 % rectangular: u = 4.18/√3 = 2.413324; also given absolutely as ± 4.18
    groups = Groups.from_index([0, 0, 1])
    rel = nominal_value(418.0, 1.0, groups, relative=True)
    ab = nominal_value([418.0, 418.0], 4.18, groups)
    np.testing.assert_allclose(rel.standard_uncertainty, [4.18 / math.sqrt(3)] * 2, rtol=1e-14)
    np.testing.assert_allclose(ab.standard_uncertainty, rel.standard_uncertainty, rtol=1e-14)
    assert round(float(rel.standard_uncertainty[0]), 3) == 2.413
    assert not rel.included.any() and rel.included.shape == (3,)
    normal = nominal_value(418.0, 4.0, groups, distribution="normal", k=2.0)
    np.testing.assert_array_equal(normal.standard_uncertainty, [2.0, 2.0])
    with pytest.raises(CoreInputError, match="tolerance"):
        nominal_value(418.0, 0.0, groups)
    with pytest.raises(CoreInputError, match="one value per group"):
        nominal_value([418.0, 1.0, 2.0], 1.0, groups)


# --- weighted mean --------------------------------------------------------------------


def test_weighted_mean_by_hand() -> None:
    # x = (10, 11, 12), u = (1, 1, 2): w = (1, 1, 0.25), Σw = 2.25
    # y = (10 + 11 + 0.25·12)/2.25 = 24/2.25 = 10.666667 ; u(y) = 2.25^(-1/2) = 0.666667
    # χ² = 0.666667²·1 + 0.333333²·1 + 1.333333²·0.25 = 0.444444 + 0.111111 + 0.444444 = 1
    # ν = 2: p = exp(−χ²/2) = 0.606531 ; R_B = √(1/2) = 0.707107
    a = weighted_mean([10.0, 11.0, 12.0], [1.0, 1.0, 2.0], g0(3))
    d = a.diagnostics
    assert a.value[0] == pytest.approx(24 / 2.25, rel=1e-15)
    assert a.standard_uncertainty[0] == pytest.approx(2 / 3, rel=1e-15)
    assert d["chi2_obs"][0] == pytest.approx(1.0, rel=1e-13)
    assert d["dof"][0] == 2 and d["n"][0] == 3
    assert d["chi2_crit"][0] == pytest.approx(CHI2_95_2DOF, rel=1e-9)
    assert d["p_value"][0] == pytest.approx(math.exp(-0.5), rel=1e-12)
    assert d["birge_ratio"][0] == pytest.approx(math.sqrt(0.5), rel=1e-13)
    assert d["consistent"][0]
    assert a.included.all() and a.method == "weighted_mean"


def test_weighted_mean_alpha_changes_critical_value() -> None:
    # χ²_0.99(2) = 9.210340 from printed tables
    a = weighted_mean([10.0, 11.0, 12.0], [1.0, 1.0, 2.0], g0(3), alpha=0.01)
    assert a.diagnostics["chi2_crit"][0] == pytest.approx(9.210340372, rel=1e-9)


def test_weighted_mean_inconsistent() -> None:
    # x = (0, 5), u = 1: y = 2.5, χ² = 12.5 > 3.841459 (ν = 1)
    d = weighted_mean([0.0, 5.0], [1.0, 1.0], g0(2)).diagnostics
    assert d["chi2_obs"][0] == 12.5 and not d["consistent"][0]
    assert d["birge_ratio"][0] == pytest.approx(math.sqrt(12.5))


def test_weighted_mean_single_result_is_documented() -> None:
    a = weighted_mean([418.0], [2.0], g0(1))
    d = a.diagnostics
    assert a.value[0] == 418.0 and a.standard_uncertainty[0] == 2.0
    assert (d["n"][0], d["dof"][0], d["chi2_obs"][0], d["chi2_crit"][0]) == (1, 0, 0.0, 0.0)
    assert d["consistent"][0] and d["birge_ratio"][0] == 0.0 and d["p_value"][0] == 1.0


@given(st.floats(min_value=-1e6, max_value=1e6, allow_nan=False), values)
def test_weighted_mean_of_identical_values_is_that_value(v: float, data: list) -> None:
    u = [t[1] for t in data]
    a = weighted_mean([v] * len(u), u, g0(len(u)))
    assert a.value[0] == v
    assert a.diagnostics["chi2_obs"][0] == 0.0 and a.diagnostics["consistent"][0]


@settings(deadline=None)
@given(values, st.floats(min_value=0.01, max_value=100.0, allow_nan=False))
def test_adding_the_weighted_mean_keeps_a_consistent_set_consistent(
    data: list, u_new: float
) -> None:
    x, u = [t[0] for t in data], [t[1] for t in data]
    a = weighted_mean(x, u, g0(len(x)))
    if not a.diagnostics["consistent"][0]:
        return
    b = weighted_mean([*x, float(a.value[0])], [*u, u_new], g0(len(x) + 1))
    assert b.diagnostics["consistent"][0]
    assert b.value[0] == pytest.approx(a.value[0], rel=1e-12, abs=1e-12)


# --- largest consistent subset --------------------------------------------------------


def test_lcs_tie_broken_by_smallest_chi2() -> None:
    # x = (0, 2.5, 5.2), u = 1: full χ² = 13.5 > 5.99.  Pairs: χ² = Δ²/2:
    # {0, 2.5} 3.125 ✓, {2.5, 5.2} 3.645 ✓, {0, 5.2} 13.52 ✗ → keep {0, 2.5}
    a = largest_consistent_subset([0.0, 2.5, 5.2], [1.0] * 3, g0(3))
    np.testing.assert_array_equal(a.included, [True, True, False])
    assert a.value[0] == pytest.approx(1.25)
    assert a.diagnostics["chi2_obs"][0] == pytest.approx(3.125)
    assert a.diagnostics["n_excluded"][0] == 1 and not a.diagnostics["consistent_all"][0]


def test_lcs_exhaustive_beats_sequential() -> None:
    # x = (3.7, 4.0, −2.1, 0.7, −1.3), u = 1; full set: y = 1, χ² = 31.28 > 9.49.
    # Exhaustive: {−2.1, 0.7, −1.3}: y = −0.9, χ² = 1.44 + 2.56 + 0.16 = 4.16 ≤ 5.99 (3 kept).
    # Sequential drops −2.1, −1.3, 0.7 in turn and ends with {3.7, 4.0} (2 kept).
    x = [3.7, 4.0, -2.1, 0.7, -1.3]
    a = largest_consistent_subset(x, [1.0] * 5, g0(5))
    np.testing.assert_array_equal(a.included, [False, False, True, True, True])
    assert a.value[0] == pytest.approx(-0.9)
    assert a.diagnostics["chi2_obs"][0] == pytest.approx(4.16)
    assert a.diagnostics["exhaustive"][0]
    swept = largest_consistent_subset(x, [1.0] * 5, g0(5), exhaustive_max=0)
    np.testing.assert_array_equal(swept.included, a.included)
    assert swept.diagnostics["exhaustive"][0]
    b = largest_consistent_subset(x, [1.0] * 5, g0(5), exhaustive_max=4, exact_max=4)
    np.testing.assert_array_equal(b.included, [True, True, False, False, False])
    assert not b.diagnostics["exhaustive"][0] and b.diagnostics["consistent"][0]


@settings(max_examples=150, deadline=None)
@given(values)
def test_lcs_matches_brute_force(data: list) -> None:
    x, u = [t[0] for t in data], [t[1] for t in data]
    a = largest_consistent_subset(x, u, g0(len(x)))
    expected = brute_force_lcs(x, u)
    assert int(a.included.sum()) == len(expected)
    assert a.diagnostics["consistent"][0]
    # same subset unless two subsets tie in χ² to rounding
    w = np.array([1 / ui**2 for ui in u])
    xs = np.array(x)
    m = np.zeros(len(x), bool)
    m[list(expected)] = True
    y = np.sum(w[m] * xs[m]) / np.sum(w[m])
    assert a.diagnostics["chi2_obs"][0] == pytest.approx(np.sum(w[m] * (xs[m] - y) ** 2), abs=1e-9)


def test_lcs_consistent_set_unchanged_and_single_result() -> None:
    a = largest_consistent_subset([10.0, 11.0, 12.0], [1.0, 1.0, 2.0], g0(3))
    b = weighted_mean([10.0, 11.0, 12.0], [1.0, 1.0, 2.0], g0(3))
    assert a.included.all() and a.value[0] == b.value[0]
    assert a.diagnostics["n_excluded"][0] == 0
    one = largest_consistent_subset([5.0], [1.0], g0(1))
    assert one.value[0] == 5.0 and one.included.all()


def test_lcs_beyond_the_exact_limit_is_sequential_and_says_so() -> None:
    rng = np.random.default_rng(3)
    x = np.concatenate([rng.normal(0, 1, 30), [8.0, -9.0, 12.0]])
    a = largest_consistent_subset(x, np.ones(x.size), g0(x.size), exact_max=32)
    assert not a.diagnostics["exhaustive"][0]
    assert a.diagnostics["consistent"][0]
    assert not a.included[-3:].any()
    exact = largest_consistent_subset(x, np.ones(x.size), g0(x.size))
    assert exact.diagnostics["exhaustive"][0] and exact.diagnostics["consistent"][0]
    assert exact.included.sum() >= a.included.sum()


# A PT round of 21 results in two clusters, made to defeat the sequential approach: one
# result of the smaller cluster has a tiny uncertainty, so the weighted mean of all sits
# on it and the sequential approach drops the larger cluster one by one, ending on 8
# results, while the 12 results of the larger cluster are consistent (the only consistent
# subset of that size: the enumeration of all 2^21 subsets below says so).
TWO_CLUSTERS_X = [
    0.0441, 0.0452, 0.0437, 0.0449, 0.0458, 0.0440, 0.0446, 0.0433, 0.0455, 0.0444, 0.0450,
    0.0439, 0.01397, 0.0152, 0.0131, 0.0146, 0.0128, 0.0155, 0.0137, 0.0143, 0.0298,
]  # fmt: skip
TWO_CLUSTERS_U = [
    0.0038, 0.0041, 0.0035, 0.0040, 0.0044, 0.0036, 0.0039, 0.0042, 0.0037, 0.0040, 0.0043,
    0.0038, 0.00008, 0.0030, 0.0028, 0.0032, 0.0027, 0.0031, 0.0029, 0.0030, 0.0020,
]  # fmt: skip


def test_lcs_two_clusters_where_the_sequential_path_fails() -> None:
    x, u, g = TWO_CLUSTERS_X, TWO_CLUSTERS_U, g0(21)
    greedy = largest_consistent_subset(x, u, g, exhaustive_max=0, exact_max=0)
    assert greedy.included.sum() == 8 and greedy.value[0] == pytest.approx(0.013971, abs=1e-6)
    assert not greedy.diagnostics["exhaustive"][0]
    enumerated = largest_consistent_subset(x, u, g, exhaustive_max=21)  # all 2^21 subsets
    swept = largest_consistent_subset(x, u, g)  # 21 > EXHAUSTIVE_MAX: the sweep
    for a in (enumerated, swept):
        np.testing.assert_array_equal(a.included, [True] * 12 + [False] * 9)
        assert a.diagnostics["exhaustive"][0] and a.diagnostics["n_excluded"][0] == 9
        # by hand: weighted mean of the first 12 and (Σ 1/u²)^(-1/2)
        w = 1 / np.array(u[:12]) ** 2
        assert a.value[0] == pytest.approx(np.sum(w * x[:12]) / np.sum(w), rel=1e-12)
        assert a.standard_uncertainty[0] == pytest.approx(np.sum(w) ** -0.5, rel=1e-12)
    assert swept.value[0] == pytest.approx(0.044491, abs=1e-6)
    assert swept.standard_uncertainty[0] == pytest.approx(0.001130, abs=1e-6)


@settings(max_examples=300, deadline=None)
@given(
    st.lists(
        st.tuples(
            # a coarse grid makes ties and identical results common
            st.integers(-40, 40).map(lambda v: v / 4),
            st.sampled_from([0.25, 0.5, 1.0, 1.7, 3.0]),
        ),
        min_size=1,
        max_size=11,
    )
)
def test_lcs_sweep_matches_brute_force_with_ties(data: list) -> None:
    """The sweep (enumeration switched off) against plain enumeration; brute force is an
    oracle up to about 11 results here (2^11 subsets in pure Python per example)."""
    x, u = [t[0] for t in data], [t[1] for t in data]
    a = largest_consistent_subset(x, u, g0(len(x)), exhaustive_max=0)
    expected = brute_force_lcs(x, u)
    assert int(a.included.sum()) == len(expected)
    assert a.diagnostics["consistent"][0] and a.diagnostics["exhaustive"][0]
    w, xs = 1 / np.array(u) ** 2, np.array(x)
    m = np.zeros(len(x), bool)
    m[list(expected)] = True
    y = np.sum(w[m] * xs[m]) / np.sum(w[m])
    assert a.diagnostics["chi2_obs"][0] == pytest.approx(np.sum(w[m] * (xs[m] - y) ** 2), abs=1e-9)


def test_lcs_sweep_matches_the_enumeration_up_to_21_results() -> None:
    """Random rounds of 13–21 results with 1–6 outliers and spread uncertainties: the
    sweep and the vectorised enumeration of every subset agree (subset and χ²)."""
    rng = np.random.default_rng(2026)
    for _ in range(60):
        n = int(rng.integers(13, 22))
        k = int(rng.integers(1, 7))
        x = np.concatenate([rng.normal(0, 1, n - k), rng.normal(0, 1, k) + rng.choice([-6, 5], k)])
        u = rng.uniform(0.3, 2.0, n) * rng.choice([1.0, 0.05], n, p=[0.9, 0.1])
        enumerated = largest_consistent_subset(x, u, g0(n), exhaustive_max=21)
        swept = largest_consistent_subset(x, u, g0(n), exhaustive_max=0)
        assert swept.included.sum() == enumerated.included.sum()
        assert swept.diagnostics["chi2_obs"][0] == pytest.approx(
            enumerated.diagnostics["chi2_obs"][0], rel=1e-9, abs=1e-12
        )


def test_lcs_200_results_with_10_outliers_is_exact() -> None:
    rng = np.random.default_rng(7)
    x = np.concatenate([rng.normal(0, 1, 190), rng.normal(9, 1, 10)])
    u = rng.uniform(0.5, 1.5, 200)
    a = largest_consistent_subset(x, u, g0(200))
    assert a.diagnostics["exhaustive"][0] and a.diagnostics["consistent"][0]
    assert not a.included[190:].any()  # every planted outlier is out
    greedy = largest_consistent_subset(x, u, g0(200), exact_max=0)
    assert a.included.sum() >= greedy.included.sum()


# --- DerSimonian–Laird ----------------------------------------------------------------


def test_dersimonian_laird_by_hand() -> None:
    # x = (0, 2), u = 1: w = 1, y = 1, Q = 2, N − 1 = 1, S1 = 2, S2 = 2
    # τ² = (2 − 1)/(2 − 2/2) = 1 ; w* = 1/2 each ; μ = 1 ; u(μ) = (1/2 + 1/2)^(−1/2) = 1
    a = dersimonian_laird([0.0, 2.0], [1.0, 1.0], g0(2))
    assert a.value[0] == 1.0
    assert a.standard_uncertainty[0] == pytest.approx(1.0, rel=1e-15)
    assert a.diagnostics["tau"][0] == pytest.approx(1.0, rel=1e-15)
    assert a.diagnostics["q"][0] == 2.0


def dl_reference(x: list[float], u: list[float]) -> tuple[float, float, float]:
    """Plain-Python DerSimonian–Laird (1986) for comparison."""
    w = [1 / v**2 for v in u]
    yw = sum(a * b for a, b in zip(w, x, strict=True)) / sum(w)
    q = sum(a * (b - yw) ** 2 for a, b in zip(w, x, strict=True))
    s1, s2 = sum(w), sum(a * a for a in w)
    tau2 = max(0.0, (q - (len(x) - 1)) / (s1 - s2 / s1)) if len(x) > 1 else 0.0
    ws = [1 / (v**2 + tau2) for v in u]
    return sum(a * b for a, b in zip(ws, x, strict=True)) / sum(ws), sum(ws) ** -0.5, tau2**0.5


@given(values)
def test_dersimonian_laird_matches_reference(data: list) -> None:
    x, u = [t[0] for t in data], [t[1] for t in data]
    a = dersimonian_laird(x, u, g0(len(x)))
    mu, u_mu, tau = dl_reference(x, u)
    assert a.value[0] == pytest.approx(mu, rel=1e-10, abs=1e-10)
    assert a.standard_uncertainty[0] == pytest.approx(u_mu, rel=1e-10)
    assert a.diagnostics["tau"][0] == pytest.approx(tau, rel=1e-7, abs=1e-7)


def _dl_exact(x: list[float], u: list[float]) -> tuple[float, float]:
    """τ² and μ of DerSimonian–Laird in exact rational arithmetic (the same formulas)."""
    xs, w = [Fraction(v) for v in x], [1 / Fraction(v) ** 2 for v in u]
    s1, s2 = sum(w), sum(a * a for a in w)
    y = sum(a * b for a, b in zip(w, xs, strict=True)) / s1
    q = sum(a * (b - y) ** 2 for a, b in zip(w, xs, strict=True))
    tau2 = max(Fraction(0), (q - (len(x) - 1)) / (s1 - s2 / s1))
    ws = [1 / (Fraction(v) ** 2 + tau2) for v in u]
    return float(tau2), float(sum(a * b for a, b in zip(ws, xs, strict=True)) / sum(ws))


@pytest.mark.parametrize(
    ("x", "u"),
    [([0.0, 2.0, 1.0], [1.0, 1.0, 5e-30]), ([16.0, -16.0, 16.0], [0.25, 0.25, 5e-30]),
     ([1e28, 0.99e28, 1.01e28], [5e27, 1e26, 1e-30 * 1e28])],
)  # fmt: skip
def test_dersimonian_laird_with_one_weight_dwarfing_the_rest(x, u) -> None:
    """S1 − S2/S1 cancelled to 0 when one u was 1e-29 of the others (values the results
    table accepts): τ² was infinite and the consensus NaN, and the run failed."""
    a = dersimonian_laird(x, u, g0(3))
    tau2, mu = _dl_exact(x, u)
    assert a.diagnostics["tau2"][0] == pytest.approx(tau2, rel=1e-9)
    assert a.value[0] == pytest.approx(mu, rel=1e-9, abs=1e-300)
    assert np.isfinite(a.standard_uncertainty[0])


@given(values)
def test_dersimonian_laird_without_excess_scatter_is_the_weighted_mean(data: list) -> None:
    x, u = [t[0] for t in data], [t[1] for t in data]
    a = dersimonian_laird(x, u, g0(len(x)))
    if a.diagnostics["q"][0] > len(x) - 1:
        return
    b = weighted_mean(x, u, g0(len(x)))
    assert a.diagnostics["tau"][0] == 0.0
    assert a.value[0] == b.value[0] and a.standard_uncertainty[0] == b.standard_uncertainty[0]


# --- σ_pt -----------------------------------------------------------------------------


def test_sigma_pt_prescribed_and_given() -> None:
    np.testing.assert_array_equal(sigma_pt_prescribed(5.0, 2), [5.0, 5.0])
    # 1 % of 418 = 4.18 ; 0.5 % of 200 = 1
    np.testing.assert_allclose(
        sigma_pt_prescribed([1.0, 0.5], 2, x_pt=[418.0, -200.0], relative=True), [4.18, 1.0]
    )
    np.testing.assert_array_equal(sigma_pt_given([1.0, 2.0], 2), [1.0, 2.0])
    with pytest.raises(CoreInputError, match="needs x_pt"):
        sigma_pt_prescribed(1.0, 2, relative=True)
    with pytest.raises(CoreInputError, match=r"sigma_pt\[1\]"):
        sigma_pt_given([1.0, 0.0], 2)


# --- vectorisation and bad input ------------------------------------------------------


def _fields_equal(a: AssignedValues, b: AssignedValues, g: int, mask: np.ndarray) -> None:
    assert a.value[g] == b.value[0]
    assert a.standard_uncertainty[g] == b.standard_uncertainty[0]
    np.testing.assert_array_equal(a.included[mask], b.included)
    for key, arr in a.diagnostics.items():
        assert arr[g] == b.diagnostics[key][0], key


@pytest.mark.parametrize("method", [weighted_mean, largest_consistent_subset, dersimonian_laird])
def test_many_groups_at_once_equals_one_at_a_time(method: object) -> None:
    rng = np.random.default_rng(11)
    n_groups = 25
    index = np.repeat(np.arange(n_groups), rng.integers(1, 9, n_groups))
    rng.shuffle(index)
    x = rng.normal(418, 2, index.size) + rng.normal(0, 6, index.size) * (
        rng.random(index.size) < 0.2
    )
    u = rng.uniform(0.5, 2.0, index.size)
    together = method(x, u, Groups.from_index(index))  # type: ignore[operator]
    for g in range(n_groups):
        m = index == g
        _fields_equal(together, method(x[m], u[m], g0(int(m.sum()))), g, m)  # type: ignore[operator]
    if method is largest_consistent_subset:
        assert together.diagnostics["n_excluded"].sum() > 0  # the search was exercised


@pytest.mark.parametrize("method", [weighted_mean, largest_consistent_subset, dersimonian_laird])
def test_bad_input(method: object) -> None:
    with pytest.raises(CoreInputError, match=r"x\[1\]"):
        method([1.0, np.nan], [1.0, 1.0], g0(2))  # type: ignore[operator]
    with pytest.raises(CoreInputError, match=r"u\[0\]"):
        method([1.0, 2.0], [0.0, 1.0], g0(2))  # type: ignore[operator]
    with pytest.raises(CoreInputError, match=r"u\[1\]"):
        method([1.0, 2.0], [1.0, np.inf], g0(2))  # type: ignore[operator]
    with pytest.raises(CoreInputError, match=r"group\(s\) \[1\] have no results"):
        method([1.0, 2.0], [1.0, 1.0], Groups.from_index([0, 2]))  # type: ignore[operator]
    with pytest.raises(CoreInputError, match="one entry per result"):
        method([1.0, 2.0], [1.0], g0(2))  # type: ignore[operator]


def test_bad_alpha() -> None:
    with pytest.raises(CoreInputError, match="alpha"):
        weighted_mean([1.0], [1.0], g0(1), alpha=0.0)
    with pytest.raises(CoreInputError, match="alpha"):
        largest_consistent_subset([1.0], [1.0], g0(1), alpha=1.0)


def test_all_labs_identical() -> None:
    x, u = [418.0] * 4, [1.0, 2.0, 0.5, 3.0]
    for method in (weighted_mean, largest_consistent_subset, dersimonian_laird):
        a = method(x, u, g0(4))
        assert a.value[0] == 418.0 and a.included.all()
    assert dersimonian_laird(x, u, g0(4)).diagnostics["tau"][0] == 0.0


def test_lcs_keeps_small_results_beside_a_huge_one() -> None:
    """A result 1e30 beside two of about 420: shifted by the huge one, the others rounded
    to it and the subset's mean came out as 0 (found by the extreme-value sweep)."""
    a = largest_consistent_subset([1e30, 420.5, 421.0], [4.0] * 3, g0(3))
    np.testing.assert_array_equal(a.included, [False, True, True])
    assert a.value[0] == 420.75
    assert a.diagnostics["chi2_obs"][0] == pytest.approx(0.25**2 / 16 * 2, rel=1e-12)
    b = largest_consistent_subset([1e-30, 420.5, 421.0], [4.0] * 3, g0(3))
    assert b.value[0] == 420.75


def test_a_consistent_group_above_the_budget_is_exact_as_it_stands() -> None:
    """No search is needed when the whole group passes: it is its own largest subset, so
    ``exhaustive`` is true whatever the budget; only a searched group can be approximate."""
    x = [10.0, 10.1, 9.9, 10.05, 9.95, 10.0, 30.0]
    g = Groups.from_index([0] * 6 + [1])  # group 1 is the single 30.0
    a = largest_consistent_subset(x, [1.0] * 7, g, exhaustive_max=2, exact_max=2)
    assert a.diagnostics["consistent_all"].tolist() == [True, True]
    assert a.diagnostics["exhaustive"].tolist() == [True, True]
    both = Groups.from_index([0] * 7)
    b = largest_consistent_subset(x, [1.0] * 7, both, exhaustive_max=2, exact_max=2)
    assert not b.diagnostics["consistent_all"][0] and not b.diagnostics["exhaustive"][0]


def test_lcs_sweep_on_a_triple_crossing_keeps_the_ranking_it_scored() -> None:
    """Found by hypothesis: at y = −1 the contributions of results 1, 3 and 4 are equal (a
    triple crossing, and an evaluation point of the sweep). The size-4 subset scored there
    was {0, 1, 2, 4} (χ² = 4.65, consistent); re-sorting at the same y ranked the tied
    results otherwise, gave {0, 1, 2, 3} (inconsistent) and the search failed."""
    x, u = [0.0, 0.25, -0.25, -2.25, 6.5], [0.5, 0.5, 1.7, 0.5, 3.0]
    assert brute_force_lcs(x, u) == (0, 1, 2, 4)
    a = largest_consistent_subset(x, u, g0(5), exhaustive_max=0)
    np.testing.assert_array_equal(a.included, [True, True, True, False, True])
    assert a.diagnostics["chi2_obs"][0] == pytest.approx(4.649702232122562, rel=1e-12)
