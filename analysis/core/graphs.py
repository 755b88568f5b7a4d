"""Data of the standard graphs of ISO 13528:2022 Clause 10 (docs/domain.md §11), pure numpy.

Each function turns results into the numbers a chart draws: Mandel's h and k per
laboratory and point with their indicator lines, a Youden plot with its confidence
ellipse, a kernel density, degrees of equivalence with U(d_i), and scores sorted for a
bar chart.  The statistics that already exist elsewhere in the core are called, not
written again: Mandel's h and k and their critical values come from
``analysis.core.consistency`` (docs/domain.md §6), the degrees of equivalence from
``analysis.core.compatibility``.  Drawing is ``analysis.charts``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike

from analysis.core.compatibility import degrees_of_equivalence
from analysis.core.consistency import cells_from_summaries, mandel_cells
from analysis.core.groups import BoolArray, CoreInputError, FloatArray, Groups, IntArray
from analysis.core.robust import MADE_FACTOR, NIQR_FACTOR

# --------------------------------------------------------------------------- Mandel


@dataclass(frozen=True)
class MandelGraph:
    """Mandel's h and k for a labs × points table (docs/domain.md §6, §11.1).

    ``h`` and ``k`` are (labs, points), NaN where the laboratory has no result at the
    point or where the statistic is not defined there; the per-point arrays give the
    indicator lines (NaN where not defined) and ``h_reason`` / ``k_reason`` say why a
    point has none (``None`` where it has them).  ``p`` counts the laboratories with a
    mean at each point, ``n`` the replicates behind k's critical values."""

    h: FloatArray
    k: FloatArray
    p: IntArray
    n: IntArray
    h_critical_1: FloatArray
    h_critical_5: FloatArray
    k_critical_1: FloatArray
    k_critical_5: FloatArray
    h_reason: tuple[str | None, ...]
    k_reason: tuple[str | None, ...]


def _table(name: str, values: ArrayLike) -> FloatArray:
    arr = np.asarray(values, dtype=np.float64)
    if arr.ndim == 1:
        arr = arr[:, np.newaxis]  # one point
    if arr.ndim != 2 or arr.size == 0:
        raise CoreInputError(f"{name} must be a non-empty labs × points table, got {arr.shape}")
    if np.isinf(arr).any():
        i, j = np.argwhere(np.isinf(arr))[0]
        raise CoreInputError(f"{name} of lab row {i}, point {j} is infinite")
    return arr


def mandel_statistics(
    means: ArrayLike, sds: ArrayLike | None = None, n_replicates: ArrayLike | None = None
) -> MandelGraph:
    """Mandel's h and k per laboratory and point, ISO 5725-2 §7.3.3 (ISO 13528:2022 10.3).

    ``means``: labs × points (a 1-D array is one point), NaN where a laboratory has no
    result.  ``sds`` (same shape, ddof = 1) and ``n_replicates`` (scalar or same shape)
    give the within-laboratory spread; without them k is not available.
    h_i = (ȳ_i − ȳ)/s(ȳ_i); k_i = s_i·√p / √Σs_j²; the 1 % and 5 % indicators are
    (p−1)t/√(p(t²+p−2)) (t two-sided, p−2 dof) and √(p/(1+(p−1)/F)) (F at n−1 and
    (p−1)(n−1) dof), from ``analysis.core.consistency``.  h needs p ≥ 3; k needs n ≥ 2
    replicates in at least two cells, the same n in each (docs/domain.md §6)."""
    m = _table("means", means)
    points = m.shape[1]
    present = ~np.isnan(m)
    if sds is None:
        s = np.zeros_like(m)
        n = np.ones(m.shape)
    else:
        s = _table("sds", sds)
        if s.shape != m.shape:
            raise CoreInputError(f"sds must have the shape of means {m.shape}, got {s.shape}")
        n_arr = np.asarray(2 if n_replicates is None else n_replicates, dtype=np.float64)
        if n_arr.ndim == 1 and m.shape[1] == 1:
            n_arr = n_arr[:, np.newaxis]  # one point, given as 1-D like the means
        if n_arr.ndim and n_arr.shape != m.shape:
            raise CoreInputError(f"n_replicates must be a scalar or of shape {m.shape}")
        n = np.broadcast_to(n_arr, m.shape).copy()
        no_sd = np.isnan(s) | (n == 1)  # a mean without repeat data: in h, not in k
        s, n = np.where(no_sd, 0.0, s), np.where(no_sd, 1.0, n)
    lab, point = np.nonzero(present.T)[::-1]  # cells ordered by point, then lab
    if lab.size == 0:
        raise CoreInputError("no laboratory has a result at any point")
    cells = cells_from_summaries(
        m[lab, point], s[lab, point], n[lab, point], lab, Groups.from_index(point, points)
    )
    res = mandel_cells(cells)
    h = np.full(m.shape, np.nan)
    k = np.full(m.shape, np.nan)
    h_ok = res.h_tested[point]
    h[lab[h_ok], point[h_ok]] = res.h[h_ok]
    lo, hi = np.full(points, np.iinfo(np.intp).max), np.zeros(points, dtype=np.intp)
    np.minimum.at(lo, point[res.k_tested], cells.n[res.k_tested])
    np.maximum.at(hi, point[res.k_tested], cells.n[res.k_tested])
    unequal = hi > np.where(hi > 0, lo, 0)
    k_ok = res.k_tested & res.k_tested_group[point] & ~unequal[point]
    k[lab[k_ok], point[k_ok]] = res.k[k_ok]
    p = np.bincount(point, minlength=points).astype(np.intp)
    k_group = res.k_tested_group & ~unequal

    def crit(values: FloatArray, ok: BoolArray) -> FloatArray:
        return np.where(ok, values, np.nan)

    h_reason = tuple(
        None if ok else f"h needs at least 3 laboratories, the point has {int(c)}"
        for ok, c in zip(res.h_tested, p, strict=True)
    )
    k_reason = tuple(
        None
        if k_group[g]
        else "unequal numbers of repeats"
        if unequal[g]
        else "k needs repeat standard deviations (n ≥ 2) from at least 2 laboratories"
        for g in range(points)
    )
    return MandelGraph(
        h=h,
        k=k,
        p=p,
        n=res.n,
        h_critical_1=crit(res.h_critical_1, res.h_tested),
        h_critical_5=crit(res.h_critical_5, res.h_tested),
        k_critical_1=crit(res.k_critical_1, k_group),
        k_critical_5=crit(res.k_critical_5, k_group),
        h_reason=h_reason,
        k_reason=k_reason,
    )


def mandel_from_replicates(values: ArrayLike) -> MandelGraph:
    """:func:`mandel_statistics` from labs × points × replicates (NaN for a missing
    replicate): cell means and standard deviations (ddof = 1) first."""
    v = np.asarray(values, dtype=np.float64)
    if v.ndim == 2:
        v = v[:, np.newaxis, :]  # one point
    if v.ndim != 3 or v.size == 0:
        raise CoreInputError(f"values must be labs × points × replicates, got {v.shape}")
    if np.isinf(v).any():
        raise CoreInputError("values must be finite or NaN (missing)")
    n = np.sum(~np.isnan(v), axis=2)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = np.nansum(v, axis=2) / n
        ss = np.nansum((v - mean[..., np.newaxis]) ** 2, axis=2)
        sd = np.sqrt(ss / np.maximum(n - 1, 1))
    mean = np.where(n == 0, np.nan, mean)
    sd = np.where(n == 0, np.nan, np.where(n == 1, 0.0, sd))
    return mandel_statistics(mean, sd, np.maximum(n, 1))


# --------------------------------------------------------------------------- Youden


@dataclass(frozen=True)
class Ellipse:
    """A confidence ellipse of a bivariate normal (docs/domain.md §11.2).

    ``vertices`` (N, 2) lie on (v − c)ᵀ Σ⁻¹ (v − c) = ``quantile`` (the χ²(2) quantile
    of ``level``), not closed (the first vertex is not repeated); ``semi_axes`` =
    (major, minor) = √(λ·q) for the eigenvalues λ of Σ; ``angle`` of the major axis
    from the x axis, radians in (−π/2, π/2]."""

    centre: FloatArray
    covariance: FloatArray
    level: float
    quantile: float
    semi_axes: FloatArray
    angle: float
    vertices: FloatArray


def chi2_2_quantile(level: float) -> float:
    """χ²(2) quantile: the χ² distribution with 2 dof is exponential, so q = −2 ln(1 − level)."""
    if not 0 < level < 1:
        raise CoreInputError(f"level must lie in (0, 1), got {level!r}")
    return -2.0 * math.log1p(-level)


def confidence_ellipse(
    centre: ArrayLike, covariance: ArrayLike, *, level: float = 0.95, n_vertices: int = 100
) -> Ellipse:
    """The ``level`` region of N(centre, covariance) as a polyline of ``n_vertices``."""
    c = np.asarray(centre, dtype=np.float64).reshape(-1)
    cov = np.asarray(covariance, dtype=np.float64)
    if (
        c.shape != (2,)
        or cov.shape != (2, 2)
        or not (np.isfinite(c).all() and np.isfinite(cov).all())
    ):
        raise CoreInputError("centre must be 2 finite numbers and covariance a finite 2 × 2 matrix")
    if n_vertices < 3:
        raise CoreInputError(f"an ellipse needs at least 3 vertices, got {n_vertices}")
    cov = (cov + cov.T) / 2
    eigval, eigvec = np.linalg.eigh(cov)  # ascending
    if not eigval[0] > 1e-12 * max(eigval[1], 0.0) or not eigval[0] > 0:
        raise CoreInputError("the covariance is singular: the points lie on a line, no ellipse")
    q = chi2_2_quantile(level)
    axes = np.sqrt(eigval[::-1] * q)  # major, minor
    major = eigvec[:, 1]
    angle = math.atan2(major[1], major[0])
    if angle <= -math.pi / 2:
        angle += math.pi
    elif angle > math.pi / 2:
        angle -= math.pi
    t = np.linspace(0.0, 2 * np.pi, n_vertices, endpoint=False)
    unit = np.stack([np.cos(t), np.sin(t)])  # 2 × N on the unit circle
    vertices = (eigvec @ (np.sqrt(eigval * q)[:, np.newaxis] * unit)).T + c
    return Ellipse(c, cov, float(level), q, axes, angle, vertices)


@dataclass(frozen=True)
class YoudenData:
    """What a Youden plot draws: the pairs, the assigned values, the centre and the ellipse."""

    x: FloatArray
    y: FloatArray
    assigned: FloatArray
    method: Literal["robust", "classical"]
    ellipse: Ellipse


def _robust_scale(v: FloatArray) -> float:
    med = np.median(v)
    return float(MADE_FACTOR * np.median(np.abs(v - med)))


def robust_covariance(x: ArrayLike, y: ArrayLike) -> tuple[FloatArray, FloatArray]:
    """Centre (medians) and covariance from MADe scales and the Gnanadesikan–Kettenring
    correlation r = (s²(u+v) − s²(u−v)) / (s²(u+v) + s²(u−v)) of the standardised
    u, v, with s = MADe (docs/domain.md §11.2)."""
    xv, yv = np.asarray(x, dtype=np.float64), np.asarray(y, dtype=np.float64)
    centre = np.array([np.median(xv), np.median(yv)])
    sx, sy = _robust_scale(xv), _robust_scale(yv)
    if sx == 0 or sy == 0:
        raise CoreInputError(
            "the robust scale (MADe) is 0 at a point: more than half of the results are "
            "identical; use method='classical'"
        )
    u, v = (xv - centre[0]) / sx, (yv - centre[1]) / sy
    plus, minus = _robust_scale(u + v) ** 2, _robust_scale(u - v) ** 2
    r = (plus - minus) / (plus + minus) if plus + minus > 0 else 0.0
    cov = np.array([[sx * sx, r * sx * sy], [r * sx * sy, sy * sy]])
    return centre, cov


def youden_data(
    x: ArrayLike,
    y: ArrayLike,
    assigned_x: float,
    assigned_y: float,
    *,
    level: float = 0.95,
    n_vertices: int = 100,
    method: Literal["robust", "classical"] = "robust",
) -> YoudenData:
    """Youden plot of the same laboratories at two points (ISO 13528:2022 10.4).

    ``x[i]`` and ``y[i]`` are laboratory i's results at the two points (finite, at least
    3 pairs).  The ellipse is the ``level`` region of a bivariate normal with the centre
    and covariance of :func:`robust_covariance` (``method="robust"``) or the mean and the
    sample covariance (ddof = 1, ``"classical"``)."""
    xv = np.asarray(x, dtype=np.float64).reshape(-1)
    yv = np.asarray(y, dtype=np.float64).reshape(-1)
    if xv.shape != yv.shape:
        raise CoreInputError(f"x and y must pair up: {xv.size} and {yv.size} results")
    if xv.size < 3:
        raise CoreInputError(f"a Youden ellipse needs at least 3 pairs, got {xv.size}")
    if not (np.isfinite(xv).all() and np.isfinite(yv).all()):
        raise CoreInputError("x and y must be finite (leave out a laboratory without a pair)")
    assigned = np.array([assigned_x, assigned_y], dtype=np.float64)
    if method == "robust":
        centre, cov = robust_covariance(xv, yv)
    elif method == "classical":
        centre, cov = np.array([xv.mean(), yv.mean()]), np.cov(xv, yv, ddof=1)
    else:
        raise CoreInputError(f"method must be 'robust' or 'classical', got {method!r}")
    ellipse = confidence_ellipse(centre, cov, level=level, n_vertices=n_vertices)
    return YoudenData(xv, yv, assigned, method, ellipse)


# --------------------------------------------------------------------------- density


@dataclass(frozen=True)
class Density:
    """A Gaussian kernel density on a grid (docs/domain.md §11.3)."""

    grid: FloatArray
    density: FloatArray
    bandwidth: float
    sigma: float


def kde_bandwidth(x: ArrayLike) -> tuple[float, float]:
    """h = 0.9·σ̂·p^(−1/5), σ̂ = min(MADe, nIQR) (robust, as Silverman's min(s, IQR/1.34)),
    the sample standard deviation where both are 0.  Returns (h, σ̂)."""
    v = np.asarray(x, dtype=np.float64).reshape(-1)
    q1, q3 = np.quantile(v, [0.25, 0.75])
    sigma = min(_robust_scale(v), float(NIQR_FACTOR * (q3 - q1)))
    if sigma == 0 and v.size > 1:
        sigma = float(np.std(v, ddof=1))
    if not sigma > 0:
        raise CoreInputError("all results are identical: a kernel density needs a spread")
    return 0.9 * sigma * v.size ** (-0.2), sigma


def kernel_density(
    x: ArrayLike,
    *,
    bandwidth: float | None = None,
    grid: ArrayLike | None = None,
    n_grid: int = 512,
    extend: float = 4.0,
) -> Density:
    """Gaussian kernel density of a point's results (ISO 13528:2022 10.5):
    f(g) = 1/(p h) Σ φ((g − x_i)/h), on ``grid`` or on ``n_grid`` points from
    min − extend·h to max + extend·h.  ``bandwidth`` defaults to :func:`kde_bandwidth`."""
    v = np.asarray(x, dtype=np.float64).reshape(-1)
    if v.size == 0 or not np.isfinite(v).all():
        raise CoreInputError("a kernel density needs at least one result, all finite")
    if bandwidth is None:
        h, sigma = kde_bandwidth(v)
    else:
        h, sigma = float(bandwidth), math.nan
        if not (math.isfinite(h) and h > 0):
            raise CoreInputError(f"bandwidth must be finite and > 0, got {bandwidth!r}")
    if grid is None:
        g = np.linspace(v.min() - extend * h, v.max() + extend * h, n_grid)
    else:
        g = np.asarray(grid, dtype=np.float64).reshape(-1)
    z = (g[:, np.newaxis] - v[np.newaxis, :]) / h
    density = np.exp(-0.5 * z * z).sum(axis=1) / (v.size * h * math.sqrt(2 * math.pi))
    return Density(g, density, h, sigma)


# --------------------------------------------------------------------------- DoE


@dataclass(frozen=True)
class DoEData:
    """Degrees of equivalence at one point, one entry per laboratory (docs/domain.md §6)."""

    labels: tuple[str, ...]
    d: FloatArray
    u_d: FloatArray
    U_d: FloatArray
    corrected: BoolArray
    correction_failed: BoolArray


def doe_data(
    labels: list[str] | tuple[str, ...],
    x: ArrayLike,
    u: ArrayLike,
    x_pt: float,
    u_pt: float,
    *,
    in_assigned: ArrayLike | None = None,
    k: float = 2.0,
) -> DoEData:
    """d_i = x_i − x_pt and U(d_i) = k·u(d_i), u²(d_i) = u²(x_i) + u²(x_pt), or
    u²(x_i) − u²(x_pt) for a result inside x_pt (``in_assigned``), by
    ``analysis.core.compatibility.degrees_of_equivalence`` (docs/domain.md §6)."""
    xv = np.asarray(x, dtype=np.float64).reshape(-1)
    if len(labels) != xv.size:
        raise CoreInputError(f"{len(labels)} labels for {xv.size} results")
    inside = np.zeros(xv.size, dtype=bool) if in_assigned is None else np.asarray(in_assigned)
    groups = Groups.from_index(np.zeros(xv.size, dtype=np.intp), 1)
    res = degrees_of_equivalence(xv, u, [x_pt], [u_pt], groups, inside, k, pairwise=False)
    return DoEData(
        tuple(labels),
        res.d,
        res.standard_uncertainty,
        res.expanded_uncertainty,
        res.corrected,
        res.correction_failed,
    )


# --------------------------------------------------------------------------- sorted bars


@dataclass(frozen=True)
class SortedScores:
    """Scores of one point in ascending order with their labels; ``not_scored`` are the
    labels whose score is NaN, left out of the bars."""

    labels: tuple[str, ...]
    values: FloatArray
    not_scored: tuple[str, ...]


def sorted_scores(labels: list[str] | tuple[str, ...], values: ArrayLike) -> SortedScores:
    """Sort z, z′ or En per laboratory by value (ties by label), NaN left out."""
    v = np.asarray(values, dtype=np.float64).reshape(-1)
    if len(labels) != v.size:
        raise CoreInputError(f"{len(labels)} labels for {v.size} scores")
    if np.isinf(v).any():
        raise CoreInputError("a score is infinite")
    keep = np.flatnonzero(~np.isnan(v))
    names = np.asarray(labels, dtype=object)
    order = keep[np.lexsort((names[keep].astype(str), v[keep]))]
    return SortedScores(
        tuple(str(s) for s in names[order]),
        v[order],
        tuple(str(labels[i]) for i in np.flatnonzero(np.isnan(v))),
    )
