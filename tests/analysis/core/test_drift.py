"""Drift of a kit from the pilot's repeats (docs/domain.md §13) against numpy.polyfit and
scipy.stats.linregress on constructed series, several series at once."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from analysis.core.drift import drift_fit
from analysis.core.groups import CoreInputError, Groups


def _series(rng, n, slope, noise, t_end=180.0):
    t = np.sort(rng.uniform(0, t_end, n))
    return t, 418.0 + slope * t + rng.normal(0, noise, n)


def test_three_series_at_once_equal_polyfit_with_stated_uncertainties():
    rng = np.random.default_rng(11)
    parts = [_series(rng, 6, 0.0, 0.05), _series(rng, 8, 0.01, 0.05), _series(rng, 5, -0.004, 0.02)]
    u_of = [0.05, 0.05, 0.02]
    t = np.concatenate([p[0] for p in parts])
    y = np.concatenate([p[1] for p in parts])
    u = np.concatenate([np.full(p[0].size, ui) for p, ui in zip(parts, u_of, strict=True)])
    groups = Groups.from_index(np.repeat([0, 1, 2], [p[0].size for p in parts]))
    fit = drift_fit(t, y, groups, u)
    for g, ((tg, yg), ug) in enumerate(zip(parts, u_of, strict=True)):
        centre = tg.mean()  # equal u within a series: t̄ is the plain mean
        coef, cov = np.polyfit(tg - centre, yg, 1, w=np.full(tg.size, 1 / ug), cov="unscaled")
        chi2 = float(np.sum(((yg - np.polyval(coef, tg - centre)) / ug) ** 2))
        scale = max(1.0, chi2 / (tg.size - 2))
        assert fit.t_mean[g] == pytest.approx(centre)
        assert fit.slope[g] == pytest.approx(coef[0], rel=1e-10)
        assert fit.intercept[g] == pytest.approx(coef[1], rel=1e-12)
        assert fit.u_slope[g] == pytest.approx(np.sqrt(cov[0, 0] * scale), rel=1e-10)
        assert fit.u_intercept[g] == pytest.approx(np.sqrt(cov[1, 1] * scale), rel=1e-10)
        assert fit.value[g] == pytest.approx(yg.mean(), rel=1e-12)
    # the constructed drift (0.01 /day over 180 days at u = 0.05) is found; no drift is not
    assert fit.model[1] == "linear" and fit.p_value[1] < 1e-6
    assert fit.model[0] == "constant" and fit.p_value[0] > 0.05


def test_without_uncertainties_the_fit_is_linregress():
    rng = np.random.default_rng(5)
    t, y = _series(rng, 10, 0.003, 0.1)
    fit = drift_fit(t, y, Groups.from_index(np.zeros(10, dtype=int)))
    ref = stats.linregress(t, y)
    assert fit.slope[0] == pytest.approx(ref.slope, rel=1e-10)
    assert fit.u_slope[0] == pytest.approx(ref.stderr, rel=1e-10)
    assert fit.p_value[0] == pytest.approx(ref.pvalue, rel=1e-8)
    assert fit.intercept[0] == pytest.approx(ref.intercept + ref.slope * t.mean(), rel=1e-12)
    _, cov = np.polyfit(t - t.mean(), y, 1, cov=True)
    assert fit.u_intercept[0] == pytest.approx(np.sqrt(cov[1, 1]), rel=1e-10)


def test_reference_and_u_stab_at_a_participants_date():
    """A kit drifting by exactly 0.02 per day, measured at days 0, 30, 60, 90 (t̄ = 45)."""
    t = np.array([0.0, 30.0, 60.0, 90.0])
    y = 418.0 + 0.02 * t
    fit = drift_fit(t, y, Groups.from_index([0, 0, 0, 0]), u=[0.01] * 4)
    assert fit.linear[0] and fit.slope[0] == pytest.approx(0.02)
    value, u = fit.reference([0, 0], [45.0, 75.0])
    assert value.tolist() == pytest.approx([418.9, 419.5])
    # u² = u²(a) + (t − t̄)² u²(b): u(a) = 0.01/2, u(b) = 0.01/√4500
    assert u[1] == pytest.approx(np.hypot(0.005, 30 * 0.01 / np.sqrt(4500)))
    assert fit.u_stab([0, 0], [45.0, 105.0]).tolist() == pytest.approx([0.0, 1.2 / np.sqrt(3)])


def test_a_stable_kit_keeps_its_constant_value_and_no_u_stab():
    t = np.array([0.0, 40.0, 80.0, 120.0, 160.0])
    y = 418.0 + np.array([0.01, -0.02, 0.015, -0.01, 0.005])
    fit = drift_fit(t, y, Groups.from_index([0] * 5), u=[0.02] * 5)
    assert not fit.linear[0]
    value, u = fit.reference([0], [300.0])
    assert value[0] == pytest.approx(y.mean()) and u[0] == pytest.approx(0.02 / np.sqrt(5))
    assert fit.u_stab([0], [300.0])[0] == 0.0


def test_two_measurements_fit_a_line_but_cannot_test_it():
    fit = drift_fit([0.0, 100.0], [418.0, 419.0], Groups.from_index([0, 0]), u=[0.1, 0.1])
    assert fit.slope[0] == pytest.approx(0.01) and not fit.linear[0]
    assert np.isnan(fit.p_value[0])


def test_exactly_linear_data_without_uncertainties_drifts_for_certain():
    t = np.array([0.0, 10.0, 20.0])
    fit = drift_fit(t, 1.0 + 0.5 * t, Groups.from_index([0, 0, 0]))
    assert fit.linear[0] and fit.p_value[0] == 0.0


@pytest.mark.parametrize(
    ("t", "y", "u", "message"),
    [([0.0], [1.0], None, "at least two"), ([5.0, 5.0], [1.0, 2.0], None, "one time only"),
     ([0.0, np.nan], [1.0, 2.0], None, "finite"), ([0.0, 1.0], [1.0, 2.0], [0.1, 0.0], "> 0")],
)  # fmt: skip
def test_bad_series_say_what_is_wrong(t, y, u, message):
    with pytest.raises(CoreInputError, match=message):
        drift_fit(t, y, Groups.from_index([0] * len(t)), u)
