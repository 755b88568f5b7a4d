"""Homogeneity of proficiency-test items, ISO 13528:2022 Annex B.2 and B.3.

An accelerometer comparison usually circulates one artefact per device, so this
check applies when the provider prepares several items of a kind (a batch of
MEMS boards, say) and measures each of g items m times before sending them out.
Every function works on many measurement points at once: ``x`` has the shape
(points, g, m) — a balanced design per point.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike
from scipy import stats

from analysis.core.groups import BoolArray, CoreInputError, FloatArray


@dataclass(frozen=True)
class Homogeneity:
    """Per measurement point: general mean, s_x (B.7), s_w (B.8), s_s (B.10), the
    criterion 0.3 σ_pt (B.2.2), the expanded criterion sqrt(F1 (0.3 σ_pt)² + F2 s_w²)
    (B.2.3) and whether s_s meets each; and the ANOVA F test of B.2.4 a) (NaN where
    s_w = 0, when the test is undefined)."""

    mean: FloatArray
    s_x: FloatArray
    s_w: FloatArray
    s_s: FloatArray
    criterion: FloatArray
    sufficient: BoolArray
    expanded_criterion: FloatArray
    sufficient_expanded: BoolArray
    f_statistic: FloatArray
    f_critical: float


def expanded_criterion_factors(g: int, m: int = 2) -> tuple[float, float]:
    """F1 = χ²_0.95(g − 1)/(g − 1) and F2 = (F_0.95(g − 1, g(m − 1)) − 1)/m, ISO 13528:2022
    B.2.3 (Table B.1 prints them for duplicates, g = 7 to 20; the formulae are general)."""
    if g < 2 or m < 2:
        raise CoreInputError("homogeneity needs at least 2 items measured at least twice")
    f1 = stats.chi2.ppf(0.95, g - 1) / (g - 1)
    f2 = (stats.f.ppf(0.95, g - 1, g * (m - 1)) - 1.0) / m
    return float(f1), float(f2)


def homogeneity(x: ArrayLike, sigma_pt: ArrayLike, *, alpha: float = 0.05) -> Homogeneity:
    """Homogeneity check of ISO 13528:2022 B.3 (Formulae B.4 to B.10) for every point.

    ``x``: shape (points, g, m), or (g, m) for one point; ``sigma_pt``: one per point
    (or one for all).  s_s = sqrt(max(0, s_x² − s_w²/m)); sufficient when s_s ≤ 0.3 σ_pt."""
    arr = np.asarray(x, dtype=np.float64)
    arr = arr[None] if arr.ndim == 2 else arr
    if arr.ndim != 3 or arr.shape[1] < 2 or arr.shape[2] < 2:
        raise CoreInputError(
            "homogeneity data must be g items x m replicates (g >= 2, m >= 2) per point"
        )
    bad = np.argwhere(~np.isfinite(arr))
    if bad.size:
        p, item, rep = (int(v) for v in bad[0])
        raise CoreInputError(f"point {p}, item {item + 1}, replicate {rep + 1}: not finite")
    sig = np.broadcast_to(np.asarray(sigma_pt, dtype=np.float64), arr.shape[:1])
    if not np.all(np.isfinite(sig) & (sig > 0)):
        raise CoreInputError("sigma_pt must be finite and > 0 for every point")
    if not 0 < alpha < 1:
        raise CoreInputError("alpha must lie between 0 and 1")
    g, m = arr.shape[1], arr.shape[2]
    item_mean = arr.mean(axis=2)
    s_x2 = item_mean.var(axis=1, ddof=1)
    s_w2 = arr.var(axis=2, ddof=1).mean(axis=1)
    s_s = np.sqrt(np.maximum(0.0, s_x2 - s_w2 / m))
    crit = 0.3 * sig
    f1, f2 = expanded_criterion_factors(g, m)
    expanded = np.sqrt(f1 * crit**2 + f2 * s_w2)
    with np.errstate(divide="ignore", invalid="ignore"):
        f_stat = np.where(s_w2 > 0, m * s_x2 / np.where(s_w2 > 0, s_w2, 1.0), np.nan)
    return Homogeneity(
        mean=item_mean.mean(axis=1),
        s_x=np.sqrt(s_x2),
        s_w=np.sqrt(s_w2),
        s_s=s_s,
        criterion=crit,
        sufficient=s_s <= crit,
        expanded_criterion=expanded,
        sufficient_expanded=s_s <= expanded,
        f_statistic=f_stat,
        f_critical=float(stats.f.ppf(1 - alpha, g - 1, g * (m - 1))),
    )
