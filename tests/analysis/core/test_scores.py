"""ISO 13528:2022 §9 scores: hand-computed cases, the pt13528 oracle, properties."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from pt13528 import scores as oracle

from analysis.core.groups import CoreInputError, Groups
from analysis.core.scores import (
    FLAG_ACTION,
    FLAG_LABELS,
    FLAG_NOT_SCORED,
    FLAG_SATISFACTORY,
    FLAG_WARNING,
    Scores,
    compute_scores,
    flag_en,
    flag_z,
    rlp,
    rsz,
)
from analysis.core.uncertainty import u_from_tolerance

U_NOMINAL = 4.18 / math.sqrt(3.0)  # 418 ± 1 % rectangular

value = st.floats(min_value=1.0, max_value=1e3, allow_nan=False)
offset = st.floats(min_value=-50.0, max_value=50.0, allow_nan=False)
unc = st.floats(min_value=1e-2, max_value=50.0, allow_nan=False)


def one(x: float, u: float, x_pt: float, u_pt: float, **kw: Any) -> Scores:
    """Score one result against one assigned value (U = 2u on both sides unless given)."""
    return compute_scores([x], [u], [2 * u], Groups.from_index([0]), x_pt, u_pt, **kw)


def test_flag_labels() -> None:
    assert FLAG_LABELS[FLAG_SATISFACTORY] == "satisfactory"
    assert FLAG_LABELS[FLAG_WARNING] == "warning"
    assert FLAG_LABELS[FLAG_ACTION] == "action"
    assert FLAG_LABELS[FLAG_NOT_SCORED] == "not scored"


def test_reference_fact_nominal_en() -> None:
    # MEMS 3, Y, curvilinear: 430 ± 11 (k=2) vs 418 ± 1 % rectangular (U = 4.826648)
    # En = 12 / √(11² + 4.826648²) = 12 / √144.296533 = 12 / 12.012349 = 0.998972
    s = compute_scores(
        [430.0], [5.5], [11.0], Groups.from_index([0]), 418.0, u_from_tolerance(4.18)
    )
    assert s.en[0] == pytest.approx(12 / math.sqrt(121 + (2 * U_NOMINAL) ** 2), rel=1e-14)
    assert round(float(s.en[0]), 4) == 0.9990
    assert s.en_flag[0] == FLAG_SATISFACTORY
    assert s.d[0] == 12.0
    assert s.d_percent[0] == pytest.approx(100 * 12 / 418, rel=1e-14)


def test_hand_computed_two_groups() -> None:
    # group 0: x_pt = 100, u_pt = 0.5, σ_pt = 2 (u_pt ≤ 0.6 → z used)
    #   x = 104, u = 1.5, U = 3: D = 4, D% = 4, z = 2, z' = 4/√4.25 = 1.940285,
    #   ζ = 4/√(2.25+0.25) = 2.529822 (warning), En = 4/√(9+1) = 1.264911 (action)
    # group 1: x_pt = 50, u_pt = 1, σ_pt = 1 (u_pt > 0.3 → z' used)
    #   x = 47, u = 1, U = 2: D = -3, D% = -6, z = -3 (action), z' = -3/√2 = -2.121320,
    #   ζ = -2.121320 (warning), En = -3/√8 = -1.060660 (action)
    s = compute_scores(
        [104.0, 47.0], [1.5, 1.0], [3.0, 2.0], Groups.from_index([0, 1]),
        [100.0, 50.0], [0.5, 1.0], sigma_pt=[2.0, 1.0],
    )  # fmt: skip
    np.testing.assert_allclose(s.d, [4.0, -3.0])
    np.testing.assert_allclose(s.d_percent, [4.0, -6.0])
    np.testing.assert_allclose(s.z, [2.0, -3.0])
    np.testing.assert_allclose(s.z_prime, [1.940285, -2.121320], atol=1e-6)
    np.testing.assert_allclose(s.zeta, [2.529822, -2.121320], atol=1e-6)
    np.testing.assert_allclose(s.en, [1.264911, -1.060660], atol=1e-6)
    np.testing.assert_array_equal(s.use_z_prime, [False, True])
    np.testing.assert_allclose(s.performance, [2.0, -2.121320], atol=1e-6)
    np.testing.assert_array_equal(s.z_flag, [FLAG_SATISFACTORY, FLAG_ACTION])
    np.testing.assert_array_equal(s.zeta_flag, [FLAG_WARNING, FLAG_WARNING])
    np.testing.assert_array_equal(s.en_flag, [FLAG_ACTION, FLAG_ACTION])
    np.testing.assert_array_equal(s.performance_flag, [FLAG_SATISFACTORY, FLAG_WARNING])
    np.testing.assert_array_equal(s.d_flag, [FLAG_NOT_SCORED, FLAG_NOT_SCORED])
    np.testing.assert_allclose(s.u_d, [math.sqrt(2.5), math.sqrt(2.0)])
    np.testing.assert_allclose(s.U_d, [math.sqrt(10.0), math.sqrt(8.0)])
    assert not s.correlation_applied.any()


def test_flag_boundaries() -> None:
    np.testing.assert_array_equal(
        flag_z([0.0, 2.0, -2.0, 2.0001, 2.9999, 3.0, -3.0, np.nan]), [0, 0, 0, 1, 1, 2, 2, 3]
    )
    np.testing.assert_array_equal(flag_en([1.0, -1.0, 1.0000001, 0.5]), [0, 0, 2, 0])
    np.testing.assert_array_equal(flag_en([1.2], limit=1.5), [0])


def test_d_flag_with_delta_e() -> None:
    # δ_E = 5: |D| = 4 satisfactory, |D| = 5 action (|D| < δ_E is the rule)
    s = compute_scores(
        [104.0, 95.0], [1.0, 1.0], [2.0, 2.0], Groups.from_index([0, 0]), 100.0, 0.5,
        delta_e=5.0,
    )  # fmt: skip
    np.testing.assert_array_equal(s.d_flag, [FLAG_SATISFACTORY, FLAG_ACTION])


def test_unknown_sigma_gives_nan_z_only() -> None:
    s = compute_scores(
        [104.0, 47.0], [1.5, 1.0], [3.0, 2.0], Groups.from_index([0, 1]),
        [100.0, 50.0], [0.5, 1.0], sigma_pt=[np.nan, 1.0],
    )  # fmt: skip
    assert np.isnan(s.z[0]) and np.isnan(s.z_prime[0]) and np.isnan(s.performance[0])
    assert s.z_flag[0] == s.z_prime_flag[0] == s.performance_flag[0] == FLAG_NOT_SCORED
    assert not s.use_z_prime[0]
    for arr in (s.d, s.d_percent, s.zeta, s.en, s.u_d, s.U_d, s.z[1:], s.z_prime[1:]):
        assert np.isfinite(arr).all()
    none = compute_scores([1.0], [1.0], [2.0], Groups.from_index([0]), 2.0, 0.1)
    assert np.isnan(none.z).all() and np.isfinite(none.en).all()


def test_cox_correction_for_weighted_mean() -> None:
    # x = (10, 11, 12), u = (1, 1, 2): w = (1, 1, 0.25), Σw = 2.25,
    # y = (10 + 11 + 3)/2.25 = 10.666667, u²(y) = 1/2.25 = 0.444444
    # result 0: u²(d) = 1 − 0.444444 = 0.555556, u(d) = 0.745356,
    #   ζ = −0.666667/0.745356 = −0.894427; U²(d) = 4 − 4·0.444444 → U(d) = 1.490712,
    #   En = −0.447214
    y, u_y = 24 / 2.25, math.sqrt(1 / 2.25)
    s = compute_scores(
        [10.0, 11.0, 12.0], [1.0, 1.0, 2.0], [2.0, 2.0, 4.0], Groups.from_index([0, 0, 0]),
        y, u_y, contributes=np.array([True, True, False]),
    )  # fmt: skip
    np.testing.assert_array_equal(s.correlation_applied, [True, True, False])
    assert not s.correlation_failed.any()
    assert s.u_d[0] == pytest.approx(math.sqrt(1 - 1 / 2.25), rel=1e-12)
    assert s.zeta[0] == pytest.approx(-0.894427191, rel=1e-9)
    assert s.en[0] == pytest.approx(-0.4472135955, rel=1e-9)
    assert s.u_d[2] == pytest.approx(math.sqrt(4 + 1 / 2.25), rel=1e-12)  # uncorrected


def test_cox_correction_that_is_not_positive_is_flagged_not_raised() -> None:
    # the reference lab itself: u²(x) − u²(x_pt) = 0 → uncorrected sum, flagged; D = 0
    s = compute_scores(
        [418.0, 420.0], [1.0, 2.0], [2.0, 4.0], Groups.from_index([0, 0]), 418.0, 1.0,
        contributes=np.array([True, False]),
    )  # fmt: skip
    np.testing.assert_array_equal(s.correlation_failed, [True, False])
    np.testing.assert_array_equal(s.correlation_applied, [False, False])
    assert s.en[0] == 0.0 and s.u_d[0] == pytest.approx(math.sqrt(2.0))


@settings(max_examples=200, deadline=None)
@given(value, offset, unc, unc, unc)
def test_against_pt13528(x_pt: float, dx: float, u: float, u_pt: float, sigma: float) -> None:
    x = x_pt + dx
    s = one(x, u, x_pt, u_pt, sigma_pt=sigma)
    assert s.d[0] == pytest.approx(oracle.difference(x, x_pt), rel=1e-12, abs=1e-12)
    assert s.d_percent[0] == pytest.approx(oracle.percent_difference(x, x_pt), rel=1e-9, abs=1e-12)
    assert s.z[0] == pytest.approx(oracle.z_score(x, x_pt, sigma), rel=1e-12, abs=1e-12)
    zp = oracle.z_prime_score(x, x_pt, sigma, u_pt)
    assert s.z_prime[0] == pytest.approx(zp, rel=1e-12, abs=1e-12)
    zeta = oracle.zeta_score(x, x_pt, u, u_pt)
    assert s.zeta[0] == pytest.approx(zeta, rel=1e-12, abs=1e-12)
    en = oracle.en_score(x, x_pt, 2 * u, 2 * u_pt)
    assert s.en[0] == pytest.approx(en, rel=1e-12, abs=1e-12)
    # pt13528's rule is strict (u < 0.3σ); the service uses u ≤ 0.3σ: equal away from equality
    assume(u_pt != 0.3 * sigma)
    assert s.use_z_prime[0] == (not oracle.uncertainty_negligible(u_pt, sigma_pt=sigma))
    labels = {"acceptable": "satisfactory", "warning": "warning", "action": "action"}
    assert FLAG_LABELS[s.z_flag[0]] == labels[oracle.classify_z(float(s.z[0]))]


def test_negligible_rule_boundary_uses_z() -> None:
    # domain spec §4: z when u(x_pt) ≤ 0.3 σ_pt, so exactly 0.3 σ_pt still uses z
    s = one(10.0, 1.0, 8.0, 0.75, sigma_pt=2.5)
    assert 0.75 == 0.3 * 2.5
    assert not s.use_z_prime[0]


scale = st.floats(min_value=1e-3, max_value=1e3, allow_nan=False)


@given(value, offset, unc, unc, unc, scale)
def test_scores_invariant_to_unit_scaling(
    x_pt: float, dx: float, u: float, u_pt: float, sigma: float, c: float
) -> None:
    a = one(x_pt + dx, u, x_pt, u_pt, sigma_pt=sigma)
    b = one(c * (x_pt + dx), c * u, c * x_pt, c * u_pt, sigma_pt=c * sigma)
    for name in ("z", "z_prime", "zeta", "en", "d_percent"):
        assert getattr(b, name)[0] == pytest.approx(getattr(a, name)[0], rel=1e-9, abs=1e-9)
    assert a.use_z_prime[0] == b.use_z_prime[0] or math.isclose(u_pt, 0.3 * sigma, rel_tol=1e-9)


@given(value, offset, unc, unc)
def test_en_symmetric_in_swapping_roles(
    x_pt: float, dx: float, big_u: float, big_u_pt: float
) -> None:
    g = Groups.from_index([0])
    x = x_pt + dx
    ab = compute_scores([x], [big_u / 2], [big_u], g, x_pt, big_u_pt / 2, U_pt=big_u_pt)
    ba = compute_scores([x_pt], [big_u_pt / 2], [big_u_pt], g, x, big_u / 2, U_pt=big_u)
    assert ab.en[0] == pytest.approx(-ba.en[0], rel=1e-12, abs=1e-15)
    assert ab.zeta[0] == pytest.approx(-ba.zeta[0], rel=1e-12, abs=1e-15)


def test_many_groups_at_once_equals_one_at_a_time() -> None:
    rng = np.random.default_rng(7)
    n_groups, n = 40, 400
    index = rng.integers(0, n_groups, n)
    x = rng.normal(418, 5, n)
    u = rng.uniform(0.5, 5, n)
    x_pt = rng.normal(418, 1, n_groups)
    u_pt = rng.uniform(0.05, 0.2, n_groups)
    sigma = rng.uniform(0.3, 5, n_groups)
    sigma[::7] = np.nan
    de = rng.uniform(1, 10, n_groups)
    contributes = rng.random(n) < 0.5
    all_at_once = compute_scores(
        x, u, 2 * u, Groups.from_index(index, n_groups), x_pt, u_pt,
        sigma_pt=sigma, contributes=contributes, delta_e=de,
    )  # fmt: skip
    for g in range(n_groups):
        m = index == g
        single = compute_scores(
            x[m], u[m], 2 * u[m], Groups.from_index(np.zeros(m.sum(), int), 1), x_pt[g], u_pt[g],
            sigma_pt=sigma[g], contributes=contributes[m], delta_e=de[g],
        )  # fmt: skip
        for name in ("d", "d_percent", "z", "z_prime", "zeta", "en", "u_d", "U_d",
                     "performance", "d_flag", "z_flag", "z_prime_flag", "zeta_flag",
                     "en_flag", "performance_flag", "correlation_applied"):  # fmt: skip
            np.testing.assert_array_equal(getattr(all_at_once, name)[m], getattr(single, name))
        assert all_at_once.use_z_prime[g] == single.use_z_prime[0]


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"x": [np.nan]}, r"x\[0\]"),
        ({"u": [np.inf]}, r"u\(x\)\[0\]"),
        ({"u": [0.0]}, r"u\(x\)\[0\]"),
        ({"U": [-2.0]}, r"U\(x\)\[0\]"),
        ({"x_pt": 0.0}, "group 0 is 0"),
        ({"x_pt": np.nan}, r"x_pt\[0\]"),
        ({"u_pt": -1.0}, "u\\(x_pt\\) of group 0"),
        ({"k_pt": 0.0}, "k_pt"),
        ({"sigma_pt": 0.0}, "sigma_pt of group 0"),
        ({"sigma_pt": np.inf}, "sigma_pt of group 0"),
        ({"delta_e": -1.0}, "delta_e of group 0"),
        ({"en_limit": 0.0}, "en_limit"),
        ({"contributes": [1]}, "contributes"),
        ({"x_pt": [1.0, 2.0]}, "one value per group"),
        ({"x": [1.0, 2.0]}, "one entry per result"),
    ],
)
def test_bad_input_raises(kwargs: dict[str, object], match: str) -> None:
    args: dict[str, object] = {
        "x": [1.0], "u": [1.0], "U": [2.0], "groups": Groups.from_index([0]),
        "x_pt": 1.5, "u_pt": 0.1,
    }  # fmt: skip
    args.update(kwargs)
    with pytest.raises(CoreInputError, match=match):
        compute_scores(**args)  # type: ignore[arg-type]


def test_all_labs_identical_to_assigned_value() -> None:
    s = compute_scores([5.0] * 3, [1.0] * 3, [2.0] * 3, Groups.from_index([0] * 3), 5.0, 0.2,
                       sigma_pt=1.0)  # fmt: skip
    for arr in (s.d, s.z, s.z_prime, s.zeta, s.en):
        np.testing.assert_array_equal(arr, 0.0)


def test_rsz_and_rlp_by_hand() -> None:
    # row 0: z = (1, 2, missing): RSZ = 3/√2 = 2.121320 (warning), RLP = √(5/2) = 1.581139
    # row 1: z = (3, 3, 3):       RSZ = 9/√3 = 5.196152 (action),  RLP = 3
    # row 2: z = (0.5, −0.5, ·):  RSZ = 0, RLP = 0.5
    z = [[1.0, 2.0, np.nan], [3.0, 3.0, 3.0], [0.5, -0.5, np.nan]]
    r = rsz(z)
    np.testing.assert_allclose(r.value, [3 / math.sqrt(2), 9 / math.sqrt(3), 0.0], atol=1e-15)
    np.testing.assert_array_equal(r.n_rounds, [2, 3, 2])
    np.testing.assert_array_equal(r.flag, [FLAG_WARNING, FLAG_ACTION, FLAG_SATISFACTORY])
    p = rlp(z)
    np.testing.assert_allclose(p.value, [math.sqrt(2.5), 3.0, 0.5])
    np.testing.assert_array_equal(p.flag, [FLAG_ACTION, FLAG_ACTION, FLAG_SATISFACTORY])
    np.testing.assert_allclose(rsz([1.0, 1.0, 1.0, 1.0]).value, [2.0])  # 1-D is one participant


def test_rsz_bad_input() -> None:
    with pytest.raises(CoreInputError, match="participant row 1 has no z"):
        rsz([[1.0, 2.0], [np.nan, np.nan]])
    with pytest.raises(CoreInputError, match="row 0, round 1 is infinite"):
        rlp([[1.0, np.inf]])
    with pytest.raises(CoreInputError, match="2-D"):
        rsz(np.zeros((2, 2, 2)))
