"""Phases in the analysis of a results table (docs/domain.md §12).

The analysis runs its linear estimators (weighted mean, Algorithm A, the scores, the
matrices' aggregates) on every kind of quantity.  For a circular kind (a phase, in
degrees) it first lays each point's results on a line about their circular mean
(``analysis.core.phase``): −179° next to 179°.  The assigned value computed there is
wrapped back into (−180°, 180°], and a result enters the scores as x_pt + wrap(x − x_pt),
so that D = wrap(x − x_pt) and En, ζ and z are formed from the wrapped D.  A point whose
phases point every way (mean resultant length R̄ = 0) has no centre: a consensus there is
refused with a message naming the point.  Plain numpy over the core, no Django.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from analysis.core import phase
from analysis.core.groups import BoolArray, FloatArray, Groups
from common.points import point_label
from common.sizes import counted

#: Methods that take no participant's result to form x_pt: no centre is needed for them.
NO_CENTRE_NEEDED = frozenset({"reference", "nominal"})


def circular_groups(circular: BoolArray, groups: Groups) -> BoolArray:
    """Per group: whether its results are of a circular kind."""
    return np.bincount(groups.index[circular], minlength=groups.n_groups) > 0


def linear_values(
    x: FloatArray, circular: BoolArray, groups: Groups
) -> tuple[FloatArray, BoolArray]:
    """``x`` with each circular group's phases unwrapped about the group's circular mean
    (docs/domain.md §12), the others as they are; and per group whether it is circular
    without a centre (R̄ = 0: its values are left wrapped)."""
    no_centre = np.zeros(groups.n_groups, dtype=bool)
    if not circular.any():
        return x, no_centre
    centres = phase.circular_mean(np.where(circular, x, 0.0), groups)
    no_centre = circular_groups(circular, groups) & ~centres.defined
    rows = circular & ~no_centre[groups.index]
    out = np.array(x, dtype=np.float64, copy=True)
    out[rows] = phase.unwrap_about(x[rows], centres.mean[groups.index[rows]])
    return out, no_centre


def wrap_groups(values: FloatArray, circular: BoolArray) -> FloatArray:
    """Per-group values with those of circular groups wrapped into (−180°, 180°] (NaN
    stays NaN)."""
    if not circular.any():
        return values
    out = np.array(values, dtype=np.float64, copy=True)
    sel = circular & np.isfinite(out)
    out[sel] = phase.wrap(out[sel])
    return out


def score_values(
    x: FloatArray, circular: BoolArray, groups: Groups, x_pt: FloatArray
) -> FloatArray:
    """The values the scores see: a circular result as x_pt + wrap(x − x_pt), so that
    D = x − x_pt is the wrapped difference; every other result as it is."""
    if not circular.any():
        return x
    out = np.array(x, dtype=np.float64, copy=True)
    centre = x_pt[groups.index[circular]]
    known = np.isfinite(centre)
    safe = np.where(known, centre, 0.0)
    out[circular] = np.where(known, safe + phase.difference(x[circular], safe), x[circular])
    return out


def no_centre_message(points: Sequence[tuple[Any, ...]], no_centre: BoolArray) -> str:
    """What to tell when phases point every way at some points (R̄ = 0)."""
    bad = np.flatnonzero(no_centre)
    names = "; ".join(point_label(points[g], sep=" ") for g in bad[:10])
    return (
        f"the phases of {counted(int(bad.size), 'measurement point')} point in every "
        f"direction (mean resultant length 0), so no consensus phase can be formed: {names}. "
        "Use a reference laboratory's value for these points, or check the results"
    )
