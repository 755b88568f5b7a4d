"""analysis.core.graphs against independent references: ISO 5725-2 Table 6, hand-computed
h and k, numpy's eigh, a simulated bivariate normal, scipy's gaussian_kde and the scores."""

import math

import numpy as np
import pytest
from scipy import stats

from analysis.core import graphs
from analysis.core.groups import CoreInputError, Groups
from analysis.core.scores import compute_scores

# --------------------------------------------------------------------------- Mandel

# ISO 5725-2 Table 6, indicators at 1 % and 5 %: h for p = 5, 6, 8, 9 and k for n = 2 at
# p = 5 (the entries of p = 3 and 10 are checked in test_consistency.py).
H_TABLE = {5: (1.72, 1.57), 6: (1.87, 1.66), 8: (2.06, 1.75), 9: (2.13, 1.78)}
K_TABLE_N2 = {5: (2.05, 1.81)}


@pytest.mark.parametrize("p", sorted(H_TABLE))
def test_h_indicators_match_iso_5725_2_table_6(p):
    means = np.arange(p, dtype=float) ** 1.5  # any spread: the indicators depend on p only
    res = graphs.mandel_statistics(means)
    assert round(float(res.h_critical_1[0]), 2) == H_TABLE[p][0]
    assert round(float(res.h_critical_5[0]), 2) == H_TABLE[p][1]


@pytest.mark.parametrize("p", sorted(K_TABLE_N2))
def test_k_indicators_match_iso_5725_2_table_6(p):
    means = np.arange(p, dtype=float)
    sds = 0.1 + np.arange(p) / 10
    res = graphs.mandel_statistics(means, sds, 2)
    assert round(float(res.k_critical_1[0]), 2) == K_TABLE_N2[p][0]
    assert round(float(res.k_critical_5[0]), 2) == K_TABLE_N2[p][1]


def test_indicators_follow_the_t_and_f_formulas():
    p, n = 7, 4
    res = graphs.mandel_statistics(np.arange(p, dtype=float), np.ones(p) + np.arange(p), n)
    for alpha, h_crit, k_crit in ((0.01, res.h_critical_1, res.k_critical_1),
                                  (0.05, res.h_critical_5, res.k_critical_5)):  # fmt: skip
        t = stats.t.ppf(1 - alpha / 2, p - 2)
        f = stats.f.ppf(1 - alpha, n - 1, (p - 1) * (n - 1))
        assert h_crit[0] == pytest.approx((p - 1) * t / math.sqrt(p * (t * t + p - 2)), rel=1e-10)
        assert k_crit[0] == pytest.approx(math.sqrt(p / (1 + (p - 1) / f)), rel=1e-10)


def test_h_and_k_by_hand():
    # three labs, two replicates: means 10, 11, 13 (grand mean 34/3), sds 1, 2, 2
    r = math.sqrt(0.5)
    replicates = np.array([[10 - r, 10 + r], [11 - math.sqrt(2), 11 + math.sqrt(2)],
                           [13 - math.sqrt(2), 13 + math.sqrt(2)]])  # fmt: skip
    res = graphs.mandel_from_replicates(replicates)
    dev = np.array([10, 11, 13]) - 34 / 3
    s_means = math.sqrt((dev**2).sum() / 2)  # = sqrt(7/3)
    np.testing.assert_allclose(res.h[:, 0], dev / s_means, rtol=1e-12)
    np.testing.assert_allclose(res.k[:, 0], np.array([1, 2, 2]) * math.sqrt(3 / 9), rtol=1e-12)
    assert res.p.tolist() == [3] and res.n.tolist() == [2]
    assert res.h_reason == (None,) and res.k_reason == (None,)


def test_several_points_and_a_missing_lab():
    means = np.array([[1.0, 5.0], [2.0, np.nan], [4.0, 6.0], [3.0, 9.0]])
    res = graphs.mandel_statistics(means)
    assert res.p.tolist() == [4, 3]
    col = np.array([5.0, 6.0, 9.0])
    np.testing.assert_allclose(res.h[[0, 2, 3], 1], (col - col.mean()) / col.std(ddof=1))
    assert math.isnan(res.h[1, 1])
    assert res.h_critical_1[0] == pytest.approx(1.485, abs=5e-4)  # p = 4
    assert res.h_critical_1[1] == pytest.approx(1.155, abs=5e-4)  # p = 3


def test_too_few_labs_and_no_replicates_say_why():
    res = graphs.mandel_statistics([[1.0], [2.0]])
    assert np.isnan(res.h).all() and np.isnan(res.h_critical_5).all()
    assert res.h_reason[0] is not None and "at least 3 laboratories" in res.h_reason[0]
    assert np.isnan(res.k).all() and res.k_reason[0] is not None
    assert "repeat" in res.k_reason[0]


def test_unequal_repeats_give_no_k():
    res = graphs.mandel_statistics([1.0, 2.0, 4.0], [0.1, 0.2, 0.3], [2, 3, 3])
    assert np.isnan(res.k).all() and res.k_reason == ("unequal numbers of repeats",)
    assert np.isfinite(res.h).all()


# --------------------------------------------------------------------------- Youden

COV = np.array([[4.0, 1.7], [1.7, 1.5]])
CENTRE = np.array([10.0, -3.0])


def test_every_vertex_lies_on_the_chi2_contour():
    e = graphs.confidence_ellipse(CENTRE, COV, level=0.95, n_vertices=100)
    assert e.vertices.shape == (100, 2)
    dv = e.vertices - CENTRE
    m2 = np.einsum("ni,ij,nj->n", dv, np.linalg.inv(COV), dv)
    np.testing.assert_allclose(m2, stats.chi2.ppf(0.95, 2), atol=1e-9, rtol=0)


def test_semi_axes_and_angle_from_eigh():
    e = graphs.confidence_ellipse(CENTRE, COV, level=0.9)
    lam, vec = np.linalg.eigh(COV)
    q = stats.chi2.ppf(0.9, 2)
    np.testing.assert_allclose(e.semi_axes, np.sqrt(lam[::-1] * q), rtol=1e-12)
    major = np.array([math.cos(e.angle), math.sin(e.angle)])
    assert abs(major @ vec[:, 1]) == pytest.approx(1.0, abs=1e-12)


def test_ellipse_holds_95_percent_of_simulated_points():
    rng = np.random.default_rng(20240513)
    pts = rng.multivariate_normal(CENTRE, COV, size=200_000)
    e = graphs.confidence_ellipse(CENTRE, COV)
    # inside the polygon of the vertices (ray casting, vectorised over the points)
    vx, vy = e.vertices[:, 0], e.vertices[:, 1]
    wx, wy = np.roll(vx, -1), np.roll(vy, -1)
    px, py = pts[:, :1], pts[:, 1:]
    crosses = ((vy > py) != (wy > py)) & (px < (wx - vx) * (py - vy) / (wy - vy) + vx)
    inside = crosses.sum(axis=1) % 2 == 1
    assert inside.mean() == pytest.approx(0.95, abs=0.005)


def test_youden_classical_uses_mean_and_sample_covariance():
    rng = np.random.default_rng(1)
    xy = rng.multivariate_normal(CENTRE, COV, size=30)
    yd = graphs.youden_data(xy[:, 0], xy[:, 1], 10.0, -3.0, method="classical")
    np.testing.assert_allclose(yd.ellipse.centre, xy.mean(axis=0))
    np.testing.assert_allclose(yd.ellipse.covariance, np.cov(xy.T), rtol=1e-12)
    assert yd.assigned.tolist() == [10.0, -3.0]


def test_youden_robust_centre_and_scale_ignore_an_outlier():
    rng = np.random.default_rng(2)
    xy = rng.multivariate_normal(CENTRE, COV, size=200)
    xy[0] = [1e4, 1e4]
    yd = graphs.youden_data(xy[:, 0], xy[:, 1], 10.0, -3.0)
    np.testing.assert_allclose(yd.ellipse.centre, np.median(xy, axis=0))
    made = 1.483 * np.median(np.abs(xy - np.median(xy, axis=0)), axis=0)
    np.testing.assert_allclose(np.sqrt(np.diag(yd.ellipse.covariance)), made)
    r = yd.ellipse.covariance[0, 1] / np.prod(made)
    assert r == pytest.approx(1.7 / math.sqrt(6.0), abs=0.12)  # the true correlation 0.69


def test_youden_refuses_too_few_or_collinear_pairs():
    with pytest.raises(CoreInputError, match="at least 3"):
        graphs.youden_data([1.0, 2.0], [1.0, 2.0], 0, 0)
    with pytest.raises(CoreInputError, match="singular"):
        graphs.youden_data([1.0, 2.0, 3.0], [2.0, 4.0, 6.0], 0, 0, method="classical")


# --------------------------------------------------------------------------- density

X = np.array([9.8, 10.1, 10.0, 10.4, 9.6, 10.2, 11.5, 9.9, 10.05, 10.3])


def test_density_equals_scipy_gaussian_kde():
    d = graphs.kernel_density(X)
    kde = stats.gaussian_kde(X, bw_method=d.bandwidth / X.std(ddof=1))
    np.testing.assert_allclose(d.density, kde(d.grid), rtol=1e-12)


def test_bandwidth_is_robust_silverman():
    h, sigma = graphs.kde_bandwidth(X)
    made = 1.483 * np.median(np.abs(X - np.median(X)))
    niqr = 0.7413 * np.subtract(*np.quantile(X, [0.75, 0.25]))
    assert sigma == pytest.approx(min(made, niqr), rel=1e-14)
    assert h == pytest.approx(0.9 * sigma * 10 ** (-0.2), rel=1e-14)


def test_density_integrates_to_one_on_a_wide_grid():
    grid = np.linspace(0, 20, 200_001)
    d = graphs.kernel_density(X, bandwidth=0.3, grid=grid)
    assert np.trapezoid(d.density, grid) == pytest.approx(1.0, abs=1e-6)


def test_density_of_identical_results_is_an_error():
    with pytest.raises(CoreInputError, match="identical"):
        graphs.kernel_density([1.0, 1.0, 1.0])


# --------------------------------------------------------------------------- DoE


def test_doe_by_hand_and_with_the_correlation():
    d = graphs.doe_data(["A", "B"], [10.3, 9.9], [0.2, 0.3], 10.0, 0.1, in_assigned=[True, False])
    np.testing.assert_allclose(d.d, [0.3, -0.1])
    np.testing.assert_allclose(d.u_d, [math.sqrt(0.04 - 0.01), math.sqrt(0.09 + 0.01)])
    np.testing.assert_allclose(d.U_d, 2 * d.u_d)
    assert d.corrected.tolist() == [True, False]


def test_doe_agrees_with_the_scores_en_denominator():
    rng = np.random.default_rng(3)
    x, u = 10 + rng.normal(size=12), 0.2 + rng.random(12)
    inside = rng.random(12) < 0.5
    d = graphs.doe_data([f"L{i}" for i in range(12)], x, u, 10.1, 0.05, in_assigned=inside)
    s = compute_scores(x, u, 2 * u, Groups.from_index(np.zeros(12, int)), [10.1], [0.05],
                       contributes=inside)  # fmt: skip
    np.testing.assert_allclose(d.d, s.d)
    np.testing.assert_allclose(d.u_d, s.u_d, rtol=1e-14)
    np.testing.assert_allclose(d.U_d, s.U_d, rtol=1e-14)


# --------------------------------------------------------------------------- sorted


def test_sorted_scores_keep_codes_and_leave_out_nan():
    s = graphs.sorted_scores(["A", "B", "C", "D"], [1.5, -2.5, float("nan"), 1.5])
    assert s.labels == ("B", "A", "D")
    assert s.values.tolist() == [-2.5, 1.5, 1.5]
    assert s.not_scored == ("C",)
