"""Linking kits and loops by least squares (docs/domain.md §14): the single-kit round gives
today's scores exactly (compute_scores with a reference laboratory or the weighted
mean), a two-loop round equals its hand linking, and random loop structures equal a
dense weighted least-squares solve of the constraint eliminated by substitution."""

from __future__ import annotations

import numpy as np
import pytest

from analysis.core.assigned import weighted_mean
from analysis.core.groups import CoreInputError, Groups
from analysis.core.linking import factored_covariance, link
from analysis.core.scores import compute_scores

Y = np.array([418.2, 419.1, 417.6, 418.9, 420.3])
U = np.array([0.3, 0.5, 0.4, 0.6, 0.8])


def test_one_kit_with_the_pilot_as_reference_is_todays_reference_laboratory_round():
    linked = link(Y, U, kit=[0] * 5, lab=range(5), reference="pilot", pilot=0)
    g = Groups.from_index([0] * 5)
    today = compute_scores(Y, U, 2 * U, g, x_pt=[Y[0]], u_pt=[U[0]])
    assert linked.doe.tolist() == pytest.approx(today.d.tolist(), abs=1e-12)
    assert linked.u_doe[1:].tolist() == pytest.approx(today.u_d[1:].tolist(), rel=1e-12)
    assert linked.kit_value[0] == pytest.approx(Y[0])
    # two laboratories share the pilot's u²: their DoEs are correlated by it
    assert linked.doe_covariance[1, 2] == pytest.approx(U[0] ** 2)
    assert linked.u_link[1:].tolist() == pytest.approx([U[0]] * 4)


def test_one_kit_against_the_weighted_mean_is_todays_weighted_mean_round():
    linked = link(Y, U, kit=[0] * 5, lab=range(5), reference="weighted_mean")
    g = Groups.from_index([0] * 5)
    av = weighted_mean(Y, U, g)
    today = compute_scores(Y, U, 2 * U, g, av.value, av.standard_uncertainty,
                           contributes=np.ones(5, dtype=bool))  # fmt: skip
    assert linked.kit_value[0] == pytest.approx(av.value[0], rel=1e-14)
    assert linked.u_kit_value[0] == pytest.approx(av.standard_uncertainty[0], rel=1e-12)
    assert linked.doe.tolist() == pytest.approx(today.d.tolist(), abs=1e-10)
    # u²(d) = u² − u²(x_pt): the Cox 2002 correction of today's En
    assert linked.u_doe.tolist() == pytest.approx(today.u_d.tolist(), rel=1e-10)
    # one bias per laboratory and one result each: nothing left over to test
    assert linked.dof == 0 and linked.chi2 == pytest.approx(0.0, abs=1e-12)


def test_two_loops_linked_through_the_pilot_by_hand():
    """Pilot (lab 0) measures kit A and kit B; lab 1 measures A, lab 2 measures B."""
    y = [418.0, 421.0, 418.6, 420.5]
    u = [0.2, 0.3, 0.4, 0.5]
    linked = link(y, u, kit=[0, 1, 0, 1], lab=[0, 0, 1, 2], reference="pilot")
    assert linked.kit_value.tolist() == pytest.approx([418.0, 421.0])
    assert linked.doe.tolist() == pytest.approx([0.0, 0.6, -0.5])
    assert linked.u_doe.tolist() == pytest.approx([0.0, np.hypot(0.4, 0.2), np.hypot(0.5, 0.3)])
    assert linked.doe_covariance[1, 2] == pytest.approx(0.0)  # different pilot results
    assert linked.u_link.tolist() == pytest.approx([0.0, 0.2, 0.3])
    assert linked.dof == 0


def test_a_laboratory_in_both_loops_adds_a_second_link_by_hand():
    """Lab 3 measures both kits. Labs 1 and 2 have one result each, so they fit exactly
    (b = y − K) and lab 3's free bias leaves it one datum, its B − A difference 2.8 with
    u² = 2·0.25². The kit difference Δ = K_B − K_A is then the weighted mean of the pilot's
    (3.0, u² = 0.2² + 0.3²) and lab 3's, and the pilot's two values move apart by
    Δ − 3.0 in proportion to their variances."""
    y = [418.0, 421.0, 418.6, 420.5, 418.3, 421.1]
    u = [0.2, 0.3, 0.4, 0.5, 0.25, 0.25]
    kit, lab = [0, 1, 0, 1, 0, 1], [0, 0, 1, 2, 3, 3]
    linked = link(y, u, kit, lab, reference="pilot")
    var_p, var_3 = 0.2**2 + 0.3**2, 2 * 0.25**2
    delta = (3.0 / var_p + 2.8 / var_3) / (1 / var_p + 1 / var_3)
    k_a = 418.0 - 0.2**2 / var_p * (delta - 3.0)
    k_b = 421.0 + 0.3**2 / var_p * (delta - 3.0)
    assert linked.kit_value.tolist() == pytest.approx([k_a, k_b], rel=1e-13)
    assert linked.doe[:3].tolist() == pytest.approx([0.0, 418.6 - k_a, 420.5 - k_b], abs=1e-10)
    assert linked.doe[0] == 0.0 and linked.dof == 1
    # lab 2 (on kit B only) is linked better than through the pilot alone
    alone = link(y[:4], u[:4], kit[:4], lab[:4], reference="pilot")
    assert linked.u_doe[2] < alone.u_doe[2]


def _dense(y, u, kit, lab, reference, pilot=0):
    """Weighted least squares with the constraint substituted: the pilot's column removed,
    or the last laboratory's bias written as −Σ w_j b_j / w_last; solved by lstsq."""
    y, u, kit, lab = map(np.asarray, (y, u, kit, lab))
    n_k, n_l = kit.max() + 1, lab.max() + 1
    a = np.zeros((y.size, n_k + n_l))
    a[np.arange(y.size), kit] = 1
    a[np.arange(y.size), n_k + lab] = 1
    m = n_k + n_l
    if reference == "pilot":
        keep = [c for c in range(m) if c != n_k + pilot]
        t = np.eye(m)[:, keep]
    else:
        w = 1 / (np.bincount(lab, weights=u**2) / np.bincount(lab))
        t = np.eye(m)[:, : m - 1].copy()
        t[m - 1, n_k : m - 1] = -w[:-1] / w[-1]
    sw = 1 / u
    ar = (a @ t) * sw[:, None]
    beta = np.linalg.lstsq(ar, y * sw, rcond=None)[0]
    cov_r = np.linalg.inv(ar.T @ ar)
    return t @ beta, t @ cov_r @ t.T, n_k


@pytest.mark.parametrize("reference", ["pilot", "weighted_mean"])
@pytest.mark.parametrize("seed", range(5))
def test_random_loop_structures_equal_a_dense_solve(reference, seed):
    rng = np.random.default_rng(seed)
    n_kits, n_labs = int(rng.integers(2, 5)), int(rng.integers(6, 40))
    kits = rng.integers(0, n_kits, n_labs)
    kits[1 : n_kits + 1] = np.arange(n_kits)  # every kit has a laboratory
    obs_kit = list(range(n_kits)) * 2 + kits[1:].tolist()  # the pilot twice on every kit
    obs_lab = [0] * (2 * n_kits) + list(range(1, n_labs))
    linkers = rng.choice(np.arange(1, n_labs), 2, replace=False)  # two labs in two loops
    for j in linkers:
        obs_kit.append(int((kits[j] + 1) % n_kits))
        obs_lab.append(int(j))
    truth_k, truth_b = rng.normal(418, 2, n_kits), rng.normal(0, 0.5, n_labs)
    truth_b[0] = 0
    u = rng.uniform(0.1, 0.8, len(obs_kit))
    y = truth_k[obs_kit] + truth_b[obs_lab] + rng.normal(0, u)
    linked = link(y, u, obs_kit, obs_lab, reference=reference)
    theta, cov, n_k = _dense(y, u, obs_kit, obs_lab, reference)
    assert linked.kit_value == pytest.approx(theta[:n_k], rel=1e-10)
    assert linked.doe == pytest.approx(theta[n_k:], abs=1e-9)
    assert linked.doe_covariance == pytest.approx(cov[n_k:, n_k:], abs=1e-12)
    # the factored form a run stores gives the same covariance, and its diagonal beyond the
    # laboratory's own part is u_link²
    factored = factored_covariance(linked.doe_own, linked.doe_factor, linked.doe_core)
    scale = np.abs(cov[n_k:, n_k:]).max()
    np.testing.assert_allclose(factored, cov[n_k:, n_k:], rtol=1e-10, atol=1e-10 * scale)
    assert linked.doe_factor.shape == (n_labs, n_kits + 1) and linked.doe_core.shape == (
        n_kits + 1, n_kits + 1)  # fmt: skip
    link_part = np.diag(factored) - linked.doe_own
    assert np.sqrt(np.maximum(link_part, 0)) == pytest.approx(linked.u_link, abs=1e-9)
    # a subset of laboratories: the subset of the rows
    some = np.array([1, *linkers])
    sub = factored_covariance(linked.doe_own[some], linked.doe_factor[some], linked.doe_core)
    np.testing.assert_allclose(sub, factored[np.ix_(some, some)], rtol=1e-12, atol=1e-14 * scale)


def test_an_unlinked_laboratory_is_named():
    with pytest.raises(CoreInputError, match=r"laboratories \[2\] are not linked"):
        link([1.0, 2.0, 3.0], [0.1, 0.1, 0.1], kit=[0, 0, 1], lab=[0, 1, 2])


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [(dict(y=[1.0], u=[0.0], kit=[0], lab=[0]), "> 0"),
     (dict(y=[1.0, 2.0], u=[0.1, 0.1], kit=[0, 2], lab=[0, 1]), "kit 1 has no observation"),
     (dict(y=[1.0], u=[0.1], kit=[0], lab=[0], reference="median"), "unknown reference"),
     (dict(y=[1.0], u=[0.1], kit=[0], lab=[0], pilot=3), "pilot 3")],
)  # fmt: skip
def test_bad_input_says_what(kwargs, message):
    with pytest.raises(CoreInputError, match=message):
        link(**kwargs)


def test_a_transfer_series_left_out_of_the_weighted_mean_equals_a_dense_solve():
    """The pilot's repeats of two kits as their own series (lab 4, a free offset, out of the
    mean): Σ w_j b_j = 0 over labs 0–3 only. Dense check: lab 3's bias substituted as
    −Σ_{j<3} w_j b_j / w_3, lab 4's column free, solved by lstsq."""
    y = np.array([418.2, 419.1, 421.4, 420.9, 419.0, 419.1, 421.9, 422.0])
    u = np.array([0.3, 0.5, 0.4, 0.6, 0.05, 0.05, 0.05, 0.05])
    kit, lab = np.array([0, 0, 1, 1, 0, 0, 1, 1]), np.array([0, 1, 2, 3, 4, 4, 4, 4])
    in_mean = np.array([True, True, True, True, False])
    linked = link(y, u, kit, lab, reference="weighted_mean", in_mean=in_mean)
    n_k, m = 2, 7
    a = np.zeros((y.size, m))
    a[np.arange(y.size), kit] = 1
    a[np.arange(y.size), n_k + lab] = 1
    w = 1 / u[:4] ** 2
    t = np.delete(np.eye(m), n_k + 3, axis=1)
    t[n_k + 3, n_k : n_k + 3] = -w[:3] / w[3]
    ar = (a @ t) / u[:, None]
    theta = t @ np.linalg.lstsq(ar, y / u, rcond=None)[0]
    cov = t @ np.linalg.inv(ar.T @ ar) @ t.T
    assert linked.doe[:4] == pytest.approx(theta[n_k : n_k + 4], abs=1e-10)
    assert linked.doe_covariance[:4, :4] == pytest.approx(cov[n_k : n_k + 4, n_k : n_k + 4],
                                                          abs=1e-12)  # fmt: skip
    assert float(np.sum(w * linked.doe[:4])) == pytest.approx(0.0, abs=1e-9)
    # the kits differ by the transfer's 2.9, not by the labs' 2.5
    assert linked.kit_value[1] - linked.kit_value[0] == pytest.approx(2.9, abs=0.05)
