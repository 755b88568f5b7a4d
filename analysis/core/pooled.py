"""Compatibility matrices from per-point sufficient statistics (docs/domain.md §3, §6).

A fanned-out analysis sees the results one chunk of measurement points at a
time.  The §3 aggregate of a matrix level (mean x̄, mean standard uncertainty
ū, sample standard deviation s) pools many points, so each chunk keeps, per
point, the moments ``n``, ``Σx``, ``Σu`` and ``M2 = Σ(x − x̄_point)²``; the
final step pools them per level with the parallel-variance identity (Chan,
Golub & LeVeque, 1979)

    M2_level = Σ_p [M2_p + n_p·(x̄_p − x̄_level)²]

which is the two-pass centred sum of :func:`analysis.core.aggregate.aggregate`
rearranged exactly (equal up to rounding, ~1e-15 relative), and needs memory
proportional to the number of points, not of results.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from analysis.core.aggregate import Aggregate, check_coverage_factor
from analysis.core.compatibility import (
    CompatibilityMatrix,
    _by_columns,
    _encode,
    _encode_many,
    _factor_column,
    _matrices_of_levels,
    with_quantity,
)
from analysis.core.groups import CoreInputError, FloatArray, Groups, IntArray, as_finite


@dataclass(frozen=True, eq=False)
class Moments:
    """Per group: count, Σx, Σu (standard uncertainties) and M2 about the group mean."""

    n: IntArray
    sum_x: FloatArray
    sum_u: FloatArray
    m2: FloatArray

    @property
    def mean(self) -> FloatArray:
        return self.sum_x / self.n


def moments(x: ArrayLike, u: ArrayLike, groups: Groups) -> Moments:
    """Moments of every group of results (two-pass: M2 is centred on each group's mean)."""
    xv, uv = as_finite("x", x), as_finite("u", u, positive=True)
    n = groups.counts()
    if np.any(n == 0):
        raise CoreInputError("every group needs at least one result to take its moments")
    sum_x = groups.sum(xv)
    dev = xv - groups.broadcast(sum_x / n)
    return Moments(n=n, sum_x=sum_x, sum_u=groups.sum(uv), m2=groups.sum(dev * dev))


def pool(parts: Moments, groups: Groups) -> Moments:
    """Moments of unions of parts: ``groups`` assigns each part to its union."""
    n = np.bincount(groups.index, weights=parts.n, minlength=groups.n_groups).astype(np.int64)
    sum_x = groups.sum(parts.sum_x)
    shift = parts.mean - groups.broadcast(sum_x / n)
    m2 = groups.sum(parts.m2 + parts.n * shift * shift)
    return Moments(n=n, sum_x=sum_x, sum_u=groups.sum(parts.sum_u), m2=m2)


def aggregate_moments(m: Moments, k: float = 2.0) -> Aggregate:
    """The §3 aggregate of each group from its moments: u(x̄) = √(ū² + s²), s with ddof 1."""
    kf = check_coverage_factor(k)
    n = m.n.astype(np.float64)
    s = np.sqrt(np.divide(m.m2, n - 1, out=np.zeros_like(m.m2), where=n > 1))
    u_mean = m.sum_u / n
    std_u = np.hypot(u_mean, s)
    return Aggregate(
        mean=m.mean,
        standard_uncertainty=std_u,
        expanded_uncertainty=kf * std_u,
        n=m.n,
        s=s,
        u_mean=u_mean,
        coverage_factor=kf,
    )


def compatibility_matrices_pooled(
    labels: Mapping[str, ArrayLike],
    parts: Moments,
    factor: str,
    by: Sequence[str] | None = None,
    *,
    k: float = 2.0,
    limit: float = 1.0,
) -> list[CompatibilityMatrix]:
    """:func:`analysis.core.compatibility.compatibility_matrices` from moments.

    ``labels`` holds one entry per part (typically a measurement point) in each
    label column the factor and ``by`` need; parts sharing (by-keys, level) are
    pooled into one level.  Not for the ``lab`` factor unless parts are per lab.  With a
    ``quantity`` column, kinds are never pooled together and phases' moments are taken of
    values unwrapped about each point's centre (``analysis.pipeline.linear_values``).
    """
    col = _factor_column(factor)
    by_cols = with_quantity(_by_columns(by, col), labels)
    n_parts = parts.n.size
    if n_parts == 0:
        raise CoreInputError("no measurement points to build compatibility matrices from")
    lvl_code, lvl_names = _encode(labels, col, n_parts)
    by_code, by_shape, by_names = _encode_many(labels, by_cols, n_parts)
    n_lvl = lvl_names.size
    present, idx = np.unique(by_code * n_lvl + lvl_code, return_inverse=True)
    agg = aggregate_moments(pool(parts, Groups.from_index(idx.reshape(-1), present.size)), k)
    return _matrices_of_levels(
        factor, agg, present, lvl_names, (by_cols, by_shape, by_names), limit=limit
    )
