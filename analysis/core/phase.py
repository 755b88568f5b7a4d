"""Phase of a complex sensitivity: angles in degrees on the circle (docs/domain.md §12).

A phase of −179° and one of +179° differ by 2°, not 358°.  Every linear statistic of the
core (weighted mean, Algorithm A, the scores) therefore runs on phases *unwrapped about a
centre*: each result is replaced by ``centre + wrap(x − centre)``, the nearest copy of it
to the centre.  With the circular mean of a point's results as its centre, results that
straddle ±180° become neighbours on a line; the assigned value computed from them is
wrapped back into (−180°, 180°], and every difference d = x − x_pt is the wrapped one.
For results spread over less than a half circle — any real comparison of a phase — the
unwrapped values are the same set of angles, so the linear estimators answer the
question a metrologist asks.  Groups whose results point everywhere (the mean resultant
length below ``MIN_RESULTANT``) have no meaningful centre and are reported as such.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from analysis.core.groups import BoolArray, CoreInputError, FloatArray, Groups

FULL_TURN = 360.0
HALF_TURN = 180.0
#: below this mean resultant length a group's phases have no usable circular mean
MIN_RESULTANT = 1e-9


def wrap(angle: ArrayLike) -> FloatArray:
    """Angles in degrees wrapped into (−180°, 180°]: ``wrap(180) = 180``, ``wrap(-180) =
    180``, ``wrap(190) = -170``.  NaN stays NaN; an infinite angle is refused."""
    a = np.asarray(angle, dtype=np.float64)
    if np.isinf(a).any():
        raise CoreInputError("a phase must be a finite number of degrees")
    # exactly a − 360·n, so an angle already in (−180°, 180°] comes back bit for bit (0.1
    # stays 0.1): fmod is exact, and one turn added to or taken from a remainder of at
    # least a half turn is exact too (Sterbenz); shifting by 180° first rounded (0.1 gave
    # 0.0999999999999943).  + 0.0 makes −0 the 0 it stands for.
    r = np.fmod(a, FULL_TURN)  # (−360, 360), with the sign of the angle
    r = np.where(r > HALF_TURN, r - FULL_TURN, r)
    return np.where(r <= -HALF_TURN, r + FULL_TURN, r) + 0.0


def difference(x: ArrayLike, y: ArrayLike) -> FloatArray:
    """The wrapped difference x − y in (−180°, 180°] (the shortest way round from y to x)."""
    return wrap(np.asarray(x, dtype=np.float64) - np.asarray(y, dtype=np.float64))


@dataclass(frozen=True)
class CircularMean:
    """Per group: the direction of the (weighted) mean resultant vector and its length
    R̄ in [0, 1] (1: all phases equal; near 0: no preferred direction)."""

    mean: FloatArray
    resultant_length: FloatArray

    @property
    def defined(self) -> BoolArray:
        return np.asarray(self.resultant_length > MIN_RESULTANT)


def circular_mean(
    angle: ArrayLike, groups: Groups, weights: ArrayLike | None = None
) -> CircularMean:
    """Circular mean per group: atan2(Σ w sin θ, Σ w cos θ), in degrees in (−180°, 180°].
    ``weights`` default to 1 (pass 1/u² for a weighted centre).  An empty group is NaN."""
    theta = np.deg2rad(np.asarray(angle, dtype=np.float64))
    if theta.shape != groups.index.shape:
        raise CoreInputError("one phase per result is needed")
    w = np.ones_like(theta) if weights is None else np.asarray(weights, dtype=np.float64)
    if w.shape != theta.shape or (w < 0).any() or ~np.isfinite(w).all():
        raise CoreInputError("phase weights must be finite, non-negative, one per result")
    s = np.bincount(groups.index, weights=w * np.sin(theta), minlength=groups.n_groups)
    c = np.bincount(groups.index, weights=w * np.cos(theta), minlength=groups.n_groups)
    total = np.bincount(groups.index, weights=w, minlength=groups.n_groups)
    with np.errstate(invalid="ignore", divide="ignore"):
        length = np.hypot(s, c) / total
    mean = wrap(np.rad2deg(np.arctan2(s, c)))
    empty = total == 0
    mean = np.where(empty, np.nan, mean)
    return CircularMean(mean=mean, resultant_length=np.where(empty, np.nan, length))


def unwrap_about(angle: ArrayLike, centre: ArrayLike) -> FloatArray:
    """Each angle replaced by its copy nearest to ``centre`` (same shape, or one centre
    per result): ``centre + wrap(angle − centre)``, in [centre − 180°, centre + 180°]."""
    c = np.asarray(centre, dtype=np.float64)
    return c + difference(angle, c)


def unwrap_groups(angle: ArrayLike, groups: Groups) -> tuple[FloatArray, CircularMean]:
    """A point's phases brought onto a line about its circular mean (see the module
    docstring), ready for the linear estimators; with the centres used."""
    centres = circular_mean(angle, groups)
    if not centres.defined[np.unique(groups.index)].all():
        bad = int(np.flatnonzero(~centres.defined)[0])
        raise CoreInputError(
            f"the phases of group {bad} point in every direction (mean resultant length "
            f"{centres.resultant_length[bad]:.2g}): no consensus phase can be formed"
        )
    return unwrap_about(angle, centres.mean[groups.index]), centres
