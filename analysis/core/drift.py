"""Drift of a travelling artefact from the pilot's repeated measurements (docs/domain.md §13).

For every series (one kit's device at one measurement point) the pilot measures at times
t_j (days) values y_j.  Two models are fitted by weighted least squares, all series at
once (``np.bincount`` sums, no loop over series):

* constant: y = a;
* linear: y = a + b·(t − t̄), with t̄ the weighted mean time, so that a and b are
  uncorrelated and a is the value at t̄.

Weights: 1/u_j² when the pilot gives the uncertainty relevant to a change over time (its
reproducibility, not its whole calibration uncertainty: the components common to all its
repeats cancel in a drift); the covariance is then scaled by the Birge ratio squared when
χ²/ν > 1 (the data scatter more than the stated u).  Without u, equal weights and the
covariance from the residuals (s²·(AᵀA)⁻¹, as ``numpy.polyfit(..., cov=True)``).

The linear model is chosen when the slope differs from zero: |b|/u(b) above the
two-sided Student-t quantile at level ``alpha`` with n − 2 degrees of freedom (n ≥ 3).
A round then either corrects for the drift — the reference value at a participant's
date t is a + b·(t − t̄) with u² = u²(a) + (t − t̄)²·u²(b) — or keeps the constant value
and adds u_stab(t) = |b·(t − t̄)|/√3 to that participant's u(x_pt): the drift at its date
taken as a rectangular half-width, as the before/after rule of §7 does with |Δ|.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike
from scipy import stats

from analysis.core.groups import BoolArray, CoreInputError, FloatArray, Groups, IntArray

CONSTANT = "constant"
LINEAR = "linear"
ALPHA = 0.05


@dataclass(frozen=True)
class DriftFit:
    """Per series: both models' parameters and the choice.  ``t_mean`` is t̄; ``value``
    and ``u_value`` the constant model's weighted mean and its standard uncertainty;
    ``intercept``/``slope`` (per day) with ``u_intercept``/``u_slope`` the linear model's
    (a at t̄, so cov(a, b) = 0); ``t_statistic`` = b/u(b), ``p_value`` its two-sided
    Student-t probability; ``linear`` where the slope is significant."""

    n: IntArray
    t_mean: FloatArray
    value: FloatArray
    u_value: FloatArray
    intercept: FloatArray
    slope: FloatArray
    u_intercept: FloatArray
    u_slope: FloatArray
    t_statistic: FloatArray
    p_value: FloatArray
    linear: BoolArray
    alpha: float

    @property
    def model(self) -> list[str]:
        return [LINEAR if lin else CONSTANT for lin in self.linear]

    def reference(self, series: ArrayLike, t: ArrayLike) -> tuple[FloatArray, FloatArray]:
        """The drift-corrected reference value and its standard uncertainty at times ``t``
        of the given ``series`` (one entry each): the linear fit where the series drifts,
        the constant value elsewhere."""
        s, dt = self._at(series, t)
        lin = self.linear[s]
        value = np.where(lin, self.intercept[s] + self.slope[s] * dt, self.value[s])
        u2 = np.where(
            lin, self.u_intercept[s] ** 2 + (dt * self.u_slope[s]) ** 2, self.u_value[s] ** 2
        )
        return value, np.sqrt(u2)

    def u_stab(self, series: ArrayLike, t: ArrayLike) -> FloatArray:
        """u_stab at times ``t`` when the drift is not corrected: |b·(t − t̄)|/√3 where the
        series drifts, 0 where it does not."""
        s, dt = self._at(series, t)
        return np.where(self.linear[s], np.abs(self.slope[s] * dt) / np.sqrt(3.0), 0.0)

    def at_date(
        self, series: ArrayLike, t: ArrayLike, u_t: ArrayLike | None = None, *, correct: bool
    ) -> tuple[FloatArray, FloatArray]:
        """What the drift does to an observation of each given series at date ``t`` (days)
        with that date's own standard uncertainty ``u_t`` (none: 0): the value added and
        the standard uncertainty added.  Where the series drifts, corrected (``correct``):
        −b·(t − t̄) and √((t − t̄)²·u²(b) + b²·u_t²); kept: 0 and √(u_stab(t)² + b²·u_t²),
        the date's uncertainty counted in either (docs/domain.md §13).  Where it does not
        drift: 0 and 0.  The one rule of the analysis run and of the kits page's preview."""
        s, dt = self._at(series, t)
        shift, u_add = np.zeros(s.size), np.zeros(s.size)
        on = self.linear[s]
        dt, b = dt[on], self.slope[s[on]]
        # hypot(x, b·0) is |x| exactly: no date uncertainty changes nothing
        b_u_t = b * (0.0 if u_t is None else np.asarray(u_t, dtype=np.float64)[on])
        if correct:
            shift[on] = -b * dt
            u_add[on] = np.hypot(dt * self.u_slope[s[on]], b_u_t)
        else:
            u_add[on] = np.hypot(np.abs(b * dt) / np.sqrt(3.0), b_u_t)  # u_stab(t), b·u_t
        return shift, u_add

    def _at(self, series: ArrayLike, t: ArrayLike) -> tuple[IntArray, FloatArray]:
        s = np.asarray(series, dtype=np.intp)
        tt = np.asarray(t, dtype=np.float64)
        if s.shape != tt.shape or (s.size and (s.min() < 0 or s.max() >= self.n.size)):
            raise CoreInputError("one existing series per date is needed")
        if not np.isfinite(tt).all():
            raise CoreInputError("measurement dates must be finite")
        return s, tt - self.t_mean[s]


def drift_fit(
    t: ArrayLike,
    y: ArrayLike,
    groups: Groups,
    u: ArrayLike | None = None,
    *,
    alpha: float = ALPHA,
) -> DriftFit:
    """Fit both drift models to every series of ``groups`` (see the module docstring).

    ``t``: time of each pilot measurement in days (any origin); ``y``: its value;
    ``u``: its standard uncertainty for a change over time, or None (equal weights,
    covariance from the residuals).  Every series needs at least two measurements at two
    different times; the slope test needs three."""
    tt, yy = (np.asarray(a, dtype=np.float64) for a in (t, y))
    if not (tt.shape == yy.shape == groups.index.shape):
        raise CoreInputError("one time and one value per pilot measurement are needed")
    if not (np.isfinite(tt).all() and np.isfinite(yy).all()):
        bad = int(np.flatnonzero(~(np.isfinite(tt) & np.isfinite(yy)))[0])
        raise CoreInputError(f"pilot measurement {bad}: time and value must be finite")
    if not 0 < alpha < 1:
        raise CoreInputError("alpha must be in (0, 1)")
    known = u is not None
    if known:
        uu = np.asarray(u, dtype=np.float64)
        if uu.shape != tt.shape or not (np.isfinite(uu).all() and (uu > 0).all()):
            raise CoreInputError("pilot uncertainties must be finite and > 0, one each")
        w = 1.0 / uu**2
    else:
        w = np.ones_like(tt)

    def total(v: FloatArray) -> FloatArray:
        return np.bincount(groups.index, weights=v, minlength=groups.n_groups).astype(np.float64)

    n = np.bincount(groups.index, minlength=groups.n_groups)
    sw = total(w)
    if (n < 2).any():
        bad = int(np.flatnonzero(n < 2)[0])
        raise CoreInputError(f"series {bad}: a drift needs at least two pilot measurements")
    t_mean = total(w * tt) / sw
    dt = tt - t_mean[groups.index]
    sxx = total(w * dt * dt)
    if (sxx <= 0).any():
        bad = int(np.flatnonzero(sxx <= 0)[0])
        raise CoreInputError(f"series {bad}: the pilot measured it at one time only")
    value = total(w * yy) / sw
    slope = total(w * dt * yy) / sxx
    intercept = value  # a at t̄ equals the weighted mean
    r_const = yy - value[groups.index]
    r_lin = r_const - slope[groups.index] * dt
    chi2_const, chi2_lin = total(w * r_const**2), total(w * r_lin**2)
    nu_const, nu_lin = n - 1, n - 2
    with np.errstate(invalid="ignore", divide="ignore"):
        if known:  # stated u, inflated where the scatter exceeds it (Birge ratio > 1)
            scale_const = np.maximum(1.0, chi2_const / nu_const)
            scale_lin = np.where(nu_lin > 0, np.maximum(1.0, chi2_lin / nu_lin), 1.0)
        else:  # the residual variance estimates the unknown u² (polyfit's cov=True)
            scale_const = chi2_const / nu_const
            scale_lin = np.where(nu_lin > 0, chi2_lin / nu_lin, np.nan)
        u_value = np.sqrt(scale_const / sw)
        u_slope = np.sqrt(scale_lin / sxx)
        u_intercept = np.sqrt(scale_lin / sw)
        # a line through every point (no residual) drifts for certain: t = ±∞, p = 0
        t_stat = np.where(u_slope > 0, slope / u_slope, np.where(slope == 0, 0.0, np.inf))
    testable = nu_lin > 0
    p = np.where(testable, 2 * stats.t.sf(np.abs(t_stat), np.maximum(nu_lin, 1)), np.nan)
    linear = testable & (p < alpha)
    return DriftFit(
        n=n.astype(np.intp), t_mean=t_mean, value=value, u_value=u_value,
        intercept=intercept, slope=slope, u_intercept=u_intercept, u_slope=u_slope,
        t_statistic=np.where(testable, t_stat, np.nan), p_value=p, linear=linear, alpha=alpha,
    )  # fmt: skip
