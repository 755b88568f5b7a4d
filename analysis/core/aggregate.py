"""Aggregation of several results of the same quantity into one mean (docs/domain.md §3).

The seed study (Chiominto et al., Micromachines 15:727, 2024, Table 1 "Total"
columns) pools repetitions, frequencies and directions of one device and axis
into one value:

    x̄ = mean(x_i),   u(x̄) = √(ū² + s²),   U = k·u(x̄)

with ū the mean of the single standard uncertainties and s the sample
standard deviation of the x_i (ddof = 1).  Computed for all groups at once
with ``np.bincount`` reductions (:class:`~analysis.core.groups.Groups`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import SupportsFloat

import numpy as np
from numpy.typing import ArrayLike

from analysis.core.groups import CoreInputError, FloatArray, Groups, IntArray, as_finite


@dataclass(frozen=True, eq=False)
class Aggregate:
    """Per-group result of :func:`aggregate`; every array has one entry per group."""

    mean: FloatArray
    standard_uncertainty: FloatArray
    expanded_uncertainty: FloatArray
    n: IntArray
    s: FloatArray
    u_mean: FloatArray
    coverage_factor: float


def aggregate(x: ArrayLike, u: ArrayLike, groups: Groups, k: float = 2.0) -> Aggregate:
    """Mean and uncertainty of each group by the rule of docs/domain.md §3.

    ``x`` and ``u`` (standard uncertainties, > 0) have one entry per result;
    ``groups`` assigns each result to a group, and every group must hold at
    least one result.  A group of one result has s = 0 by definition (the
    sample standard deviation is undefined for n = 1; the single result's own
    uncertainty is then the whole uncertainty), so u(x̄) = u and no NaN appears.
    The spread s uses a two-pass (centred) sum so that values near 420 with a
    spread of 1e-3 lose no digits.
    """
    kf = check_coverage_factor(k)
    xv, uv = _validate(x, u, groups)
    n = groups.counts()
    mean = groups.mean(xv)
    u_mean = groups.mean(uv)
    dev = xv - groups.broadcast(mean)
    ss = groups.sum(dev * dev)
    s = np.sqrt(np.divide(ss, n - 1, out=np.zeros_like(ss), where=n > 1))
    std_u = np.hypot(u_mean, s)
    return Aggregate(
        mean=mean,
        standard_uncertainty=std_u,
        expanded_uncertainty=kf * std_u,
        n=n,
        s=s,
        u_mean=u_mean,
        coverage_factor=kf,
    )


def check_coverage_factor(k: SupportsFloat) -> float:
    """Check a coverage factor k (finite, > 0) and return it as a float."""
    try:
        kf = math.nan if isinstance(k, str | bytes | bool) else float(k)
    except (TypeError, ValueError):
        kf = math.nan
    if not (math.isfinite(kf) and kf > 0):
        raise CoreInputError(f"coverage factor k must be a finite number > 0, got {k!r}")
    return kf


def _validate(x: ArrayLike, u: ArrayLike, groups: Groups) -> tuple[FloatArray, FloatArray]:
    xv = as_finite("x", x)
    uv = as_finite("u", u, positive=True)
    if xv.size == 0:
        raise CoreInputError("no results to aggregate: x is empty")
    if xv.size != uv.size or xv.size != groups.size:
        raise CoreInputError(
            f"x, u and the group index must have the same length, "
            f"got {xv.size}, {uv.size} and {groups.size}"
        )
    empty = np.flatnonzero(groups.counts() == 0)
    if empty.size:
        raise CoreInputError(
            f"group {int(empty[0])} has no results ({empty.size} empty group(s)); "
            "every group needs at least one result"
        )
    return xv, uv
