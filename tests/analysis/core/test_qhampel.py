"""Q/Hampel (ISO 13528:2022 C.5.2.2, C.5.3.3, C.5.4), checked against the independent
package pt13528 on random groups, by hand, and for its vectorised and degenerate cases.

Tolerances: s* agrees with pt13528 to 1e-12 relative (both take the same order
statistics of the differences and one interpolation); x* to 1e-9 s* plus 4 ulp of x*
(pt13528 rounds the zeros of its Hampel sum to 12 decimals in units of s*)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from pt13528 import robust as oracle
from scipy import stats

from analysis.core import robust
from analysis.core.groups import CoreInputError, Groups
from analysis.core.qhampel import hampel_location


def _flat(datasets: list[list[float]]) -> tuple[np.ndarray, Groups]:
    x = np.concatenate([np.asarray(d, dtype=float) for d in datasets])
    idx = np.repeat(np.arange(len(datasets)), [len(d) for d in datasets])
    return x, Groups.from_index(idx)


def _psi(q: np.ndarray) -> np.ndarray:
    """Formula (C.30), written out independently of the core."""
    a = np.abs(q)
    return np.sign(q) * np.where(
        a <= 1.5, a, np.where(a <= 3.0, 1.5, np.where(a <= 4.5, 4.5 - a, 0.0))
    )


def _solves(d: list[float], scale: float, x: float) -> bool:
    """x solves the Hampel equation sum psi((x_i - x) / s*) = 0 (C.5.3)."""
    return abs(float(_psi((np.asarray(d) - x) / scale).sum())) < 1e-9 * len(d)


def _closer_zero(d: list[float], scale: float, found: float, ref: float) -> bool:
    """``found`` solves the Hampel equation and pt13528's ``ref`` does not, or is farther
    from the median: pt13528 missed the closest zero.  It does so where the sum vanishes
    on a whole interval around the median (its finite-step search lists the interval's
    end nodes only), and where a result is ~1e12 s* away (its tolerances grow with the
    largest |x_i - median| / s*, and it falls back to the median)."""
    med = float(np.median(d))
    closer = abs(found - med) < abs(ref - med)
    return _solves(d, scale, found) and (closer or not _solves(d, scale, ref))


def _node_hit(d: list[float]) -> float | None:
    """s* where the target 0.25 + 0.75 H1(0) of the Q method falls exactly on a node of G1,
    counted in integers over all pairs (p^2, for small groups), else None.  pt13528 sums
    H1 and G1 in floating point, which can then land it in the adjacent segment."""
    a = np.sort(np.asarray(d, dtype=float))
    i, j = np.triu_indices(a.size, 1)
    diffs = np.sort(a[j] - a[i])
    tol = 4 * np.finfo(float).eps * np.abs(a).max()
    big_n, c0 = diffs.size, int(np.sum(diffs <= tol))
    k = c0
    while k < big_n:  # discontinuities: an anchor and the differences within tol above it
        end = int(np.searchsorted(diffs, diffs[k] + tol, side="right"))
        if 2 * (k + end) == big_n + 3 * c0:
            return float(diffs[k] / (math.sqrt(2) * stats.norm.ppf(0.625 + 0.375 * c0 / big_n)))
        k = end
    return None


finite = st.floats(-1e6, 1e6, allow_nan=False, allow_infinity=False)
group = st.one_of(
    st.lists(finite, min_size=2, max_size=40),
    # ties: results rounded to one decimal around a level (H1(0) > 0, decimal differences)
    st.lists(st.integers(-5, 5), min_size=2, max_size=30).map(lambda v: [100 + 0.1 * i for i in v]),
    # three-decimal results as in Table E.4, with a few gross outliers
    st.tuples(
        st.lists(st.integers(200, 300), min_size=2, max_size=40),
        st.lists(st.sampled_from([-50_000, -900, 900, 4000, 60_000]), max_size=4),
    ).map(lambda t: [v / 1000 for v in t[0] + t[1]]),
    # many identical results
    st.tuples(st.integers(2, 25), st.lists(finite, max_size=3)).map(lambda t: [7.5] * t[0] + t[1]),
)
datasets = st.lists(group, min_size=1, max_size=8)


def _check_against_oracle(data: list[list[float]]) -> None:
    x, groups = _flat(data)
    av = robust.q_hampel(x, groups)
    s_star = av.diagnostics["s_star"]
    for g, d in enumerate(data):
        if min(d) == max(d):  # pt13528 returns NaN for identical zeros: no comparison
            assert s_star[g] == 0 and av.value[g] == d[0] and av.diagnostics["degenerate"][g]
            continue
        ref = oracle.q_hampel(d)
        if s_star[g] != pytest.approx(ref.scale, rel=1e-12, abs=0):
            hit = _node_hit(d)
            assert hit is not None and s_star[g] == pytest.approx(hit, rel=1e-14)
            assert ref.scale == pytest.approx(hit, rel=1e-6)
            continue
        assert av.diagnostics["degenerate"][g] == (ref.scale == 0)
        tol = 1e-9 * ref.scale + 4 * np.spacing(abs(ref.location))
        if abs(av.value[g] - ref.location) > tol:
            assert _closer_zero(d, ref.scale, av.value[g], ref.location)
        assert av.standard_uncertainty[g] == pytest.approx(1.25 * s_star[g] / math.sqrt(len(d)))


@settings(max_examples=200, deadline=None)
@given(datasets)
def test_q_hampel_matches_pt13528(data: list[list[float]]) -> None:
    _check_against_oracle(data)


def test_q_hampel_matches_pt13528_on_large_groups() -> None:
    """Groups large enough for the bisection of the Q method to work (the window of
    candidate differences is much smaller than the p(p-1)/2 pairs)."""
    rng = np.random.default_rng(11)
    data = [
        list(np.round(rng.normal(418.0, 2.0, size=1500), 2)),  # many tied differences
        [*rng.normal(0.0, 1.0, size=900), 40.0, -60.0, 1e4],
        list(rng.standard_cauchy(size=700)),
    ]
    _check_against_oracle(data)


@settings(max_examples=100, deadline=None)
@given(
    st.lists(
        st.tuples(
            st.lists(st.floats(-5, 5, allow_nan=False), min_size=1, max_size=30),
            st.floats(0.05, 20.0),
        ),
        min_size=1,
        max_size=6,
    )
)
def test_hampel_with_any_scale_matches_pt13528(data: list[tuple[list[float], float]]) -> None:
    """The Hampel estimator alone, for scales other than the Q method's (many local zeros
    when s* is small)."""
    x, groups = _flat([d for d, _ in data])
    s = robust._sorted_groups("x", x, groups)
    scale = np.array([sc for _, sc in data])
    loc, _ = hampel_location(s.rows, s.n, robust._row_median(s), scale)
    for g, (d, sc) in enumerate(data):
        ref = oracle.hampel(d, sc)
        if abs(loc[g] - ref) > 1e-9 * sc + 4 * np.spacing(abs(ref)):
            assert _closer_zero(d, sc, loc[g], ref)


def test_hand_computed_q_method_and_hampel() -> None:
    # Two results: one difference d; H1 jumps to 1 at d, G1(d) = 1/2, G1^-1(1/4) = d/2
    av = robust.q_hampel([1.0, 4.0], Groups.from_index([0, 0]))
    s2 = 1.5 / (math.sqrt(2) * stats.norm.ppf(0.625))
    assert av.diagnostics["s_star"][0] == pytest.approx(s2, rel=1e-14)
    assert av.value[0] == 2.5  # both results in the linear part of psi: the mean
    # 1, 1, 2: differences 0, 1, 1; H1(0) = 1/3, G1(1) = (1/3 + 1)/2 = 2/3, target
    # 0.25 + 0.75/3 = 1/2 -> G1^-1 = 3/4; denominator sqrt(2) Phi^-1(0.625 + 0.125)
    av = robust.q_hampel([1.0, 1.0, 2.0], Groups.from_index([0, 0, 0]))
    s3 = 0.75 / (math.sqrt(2) * stats.norm.ppf(0.75))
    assert av.diagnostics["s_star"][0] == pytest.approx(s3, rel=1e-14)
    # Hampel: psi((1-x)/s) * 2 + psi((2-x)/s) = 0 with all three in the linear part
    assert av.value[0] == pytest.approx(4.0 / 3.0, rel=1e-14)


def test_decimal_ties_are_one_discontinuity() -> None:
    """0.3 - 0.1 and 0.4 - 0.2 differ in binary; merged, the result does not depend on
    which decimals the laboratories reported, only on the decimal values."""
    a = [0.1, 0.2, 0.3, 0.4, 0.6, 0.7, 1.0]
    b = [v + 1000.0 for v in a]  # other binary rounding of the same differences
    av = robust.q_hampel(a + b, Groups.from_index([0] * 7 + [1] * 7))
    s = av.diagnostics["s_star"]
    assert s[0] == pytest.approx(s[1], rel=1e-9)
    assert av.value[1] - 1000.0 == pytest.approx(av.value[0], abs=1e-9)


def test_degenerate_and_small_groups() -> None:
    x, groups = _flat([[7.0], [5.0, 5.0, 5.0], [2.0, 2.0, 2.0, 2.0, 9.0], [1.0, 3.0]])
    av = robust.q_hampel(x, groups)
    s = av.diagnostics["s_star"]
    assert list(av.value[:2]) == [7.0, 5.0] and list(s[:2]) == [0.0, 0.0]
    assert list(av.diagnostics["degenerate"]) == [True, True, False, False]
    assert list(av.diagnostics["median_fallback"][:2]) == [True, True]
    assert s[2] > 0  # ties are allowed for in H1(0): s* > 0 unless all results are tied
    assert av.value[3] == 2.0 and list(av.diagnostics["n"]) == [1, 3, 5, 2]
    assert av.included.all()


def test_symmetric_clusters_give_the_median() -> None:
    """Two clusters far apart in units of s*: the Hampel sum vanishes between them, at the
    median too, which is then the closest zero (pt13528: two nodes equally close, also
    the median)."""
    data = [0.0, 0.0, 0.1, 0.1, 10.0, 10.0, 10.1, 10.1]
    loc, fallback = hampel_location(
        np.array([data]), np.array([8]), np.array([5.05]), np.array([0.5])
    )
    assert loc[0] == 5.05 == oracle.hampel(data, 0.5) and not fallback[0]


def test_vectorised_equals_one_group_at_a_time() -> None:
    rng = np.random.default_rng(5)
    sizes = rng.integers(1, 80, size=60)
    data = [list(np.round(rng.normal(418, 2, size=k), int(rng.integers(1, 4)))) for k in sizes]
    x, groups = _flat(data)
    whole = robust.q_hampel(x, groups)
    perm = rng.permutation(x.size)
    shuffled = robust.q_hampel(x[perm], Groups.from_index(groups.index[perm], groups.n_groups))
    np.testing.assert_array_equal(whole.value, shuffled.value)
    for g, d in enumerate(data):
        one = robust.q_hampel(d, Groups.from_index([0] * len(d)))
        assert one.value[0] == whole.value[g]
        assert one.diagnostics["s_star"][0] == whole.diagnostics["s_star"][g]


@settings(max_examples=60, deadline=None)
@given(
    st.lists(
        st.lists(st.integers(-(10**6), 10**6).map(lambda i: i / 64), min_size=2, max_size=30),
        min_size=1,
        max_size=6,
    ),
    st.integers(-1000, 1000).map(lambda i: i / 8),
    st.sampled_from([1e-3, 0.5, 7.0, -2.0, 1e4]),
)
def test_location_scale_equivariance(data: list[list[float]], a: float, b: float) -> None:
    x, groups = _flat(data)
    base, moved = robust.q_hampel(x, groups), robust.q_hampel(a + b * x, groups)
    s0, s1 = base.diagnostics["s_star"], moved.diagnostics["s_star"]
    tol = 1e-9 * abs(b) * s0 + 1e-12 * (abs(a) + abs(b) * np.abs(base.value))
    np.testing.assert_array_less(np.abs(s1 - abs(b) * s0), tol + 1e-300)
    np.testing.assert_array_less(np.abs(moved.value - (a + b * base.value)), tol + 1e-300)


def test_bad_input_rejected() -> None:
    with pytest.raises(CoreInputError, match=r"x\[1\] must be finite"):
        robust.q_hampel([1.0, np.nan], Groups.from_index([0, 0]))
    with pytest.raises(CoreInputError, match=r"group\(s\) \[1\] have no results"):
        robust.q_hampel([1.0, 2.0], Groups.from_index([0, 2]))


def test_sigma_pt_robust_takes_the_q_method_s_star_where_asked() -> None:
    rng = np.random.default_rng(2)
    data = [[*rng.normal(10, 1, size=k), 30.0] for k in (8, 15, 40)]
    x, groups = _flat(data)
    sigma = robust.sigma_pt_robust(x, groups, estimator=["q_method", "algorithm_a", "q_method"])
    q = robust.q_hampel(x, groups).diagnostics["s_star"]
    a = robust.algorithm_a(x, groups).diagnostics["s_star"]
    np.testing.assert_array_equal(sigma, [q[0], a[1], q[2]])
    np.testing.assert_array_equal(robust.sigma_pt_robust(x, groups), a)
    with pytest.raises(CoreInputError, match=r"unknown robust estimator\(s\) \['qn'\]"):
        robust.sigma_pt_robust(x, groups, estimator="qn")
    x2, g2 = _flat([[1.0, 2.0, 4.0], [3.0, 3.0, 3.0]])
    with pytest.raises(CoreInputError, match=r"group\(s\) \[1\].*all of them for the Q method"):
        robust.sigma_pt_robust(x2, g2, estimator="q_method")
