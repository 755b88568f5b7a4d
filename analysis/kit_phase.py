"""Phases in a kit round (docs/domain.md §12, §14): the observations of a phase point laid
on a line, so that its drift is fitted and its kits linked as for any other point.

At a circular point every observation — the results and every measurement of a kit — is
replaced by its copy nearest to their common circular mean (``analysis.core.phase``).
Where they spread over far less than a half circle (any real comparison of a phase) this
is the same set of angles without a cut between them: the differences the drift and the
link are made of (a laboratory's bias, a kit's offset, a change over time) are the same
on the line as on the circle, and the linked d and kit values are wrapped back into
(−180°, 180°].  Where the unwrapped observations spread over more than
:data:`MAX_SPREAD`, or point every way, the point is neither drift-corrected nor linked,
and its note says why.  Plain numpy, no Django.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from analysis.core.groups import BoolArray, FloatArray, Groups, IntArray
from analysis.core.phase import circular_mean, unwrap_about, wrap
from analysis.kit_link import PointLink

#: the largest spread (degrees) of a phase point's unwrapped observations that is linked
MAX_SPREAD = 90.0


@dataclass(frozen=True)
class OnLine:
    """The observations' values on a line (unwrapped at circular points, else as given)
    and, per point, whether it is circular, its spread and whether it is refused."""

    results: FloatArray
    measurements: FloatArray
    circular: BoolArray
    spread: FloatArray
    refused: BoolArray

    def note(self, g: int, n_kits: int) -> str | None:
        """Why point ``g`` is neither drift-corrected nor linked (None: it is)."""
        if not self.refused[g]:
            return None
        what = "not drift-corrected" + (" nor linked across kits" if n_kits >= 2 else "")
        if np.isfinite(self.spread[g]):
            why = (f"its phases spread over {self.spread[g]:.0f}° about their circular "
                   f"mean, more than {MAX_SPREAD:.0f}°: on a line they need not be the same "
                   "angles")  # fmt: skip
        else:
            why = "its phases point in every direction (mean resultant length 0)"
        # the reader has no docs/: the note says it all in words (docs/domain.md §14)
        return (f"{why}, so the point is {what}; its scores are against the round's "
                "assigned value")  # fmt: skip


def on_line(
    results: FloatArray, result_group: IntArray, measurements: FloatArray,
    measurement_group: IntArray, circular: BoolArray,
) -> OnLine:  # fmt: skip
    """Each circular point's results and measurements unwrapped about their common
    circular mean; ``circular``: per point (group)."""
    n = circular.size
    index = np.concatenate([result_group, measurement_group]).astype(np.intp)
    values = np.concatenate([results, measurements]).astype(np.float64)
    line = values.copy()
    spread = np.full(n, np.nan)
    on = circular[index]
    if on.any():
        centre = circular_mean(np.where(on, values, 0.0), Groups.from_index(index, n))
        rows = on & centre.defined[index]
        line[rows] = unwrap_about(values[rows], centre.mean[index[rows]])
        high, low = np.full(n, -np.inf), np.full(n, np.inf)
        np.maximum.at(high, index[rows], line[rows])
        np.minimum.at(low, index[rows], line[rows])
        spread = np.where(circular & centre.defined, high - low, np.nan)
    refused = circular & ~(spread <= MAX_SPREAD)
    return OnLine(line[: results.size], line[results.size :], circular, spread, refused)


def wrap_link(linked: PointLink) -> None:
    """A phase point's link back on the circle: d and the kit values wrapped into
    (−180°, 180°] (u, u_link and χ² are the line's)."""
    linked.d = [None if d is None else float(wrap(d)) for d in linked.d]
    for k in linked.kit_values:
        k["value"] = float(wrap(k["value"]))
