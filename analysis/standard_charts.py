"""The standard graphs of ISO 13528:2022 Clause 10 drawn for the results pages (docs/domain.md
§11): plain data in, a matplotlib ``Figure`` out (``*_figure``), SVG text (``*_chart``) or PNG
bytes (``analysis.charts.render``) from it.

A module of its own beside ``analysis.charts`` (whose helpers, colours and style it uses)
to keep both under the size the code keeps a module to; the score bars (z and En sorted,
one laboratory's overview) are ``analysis.score_charts``, named here too.  The chart
cache's key carries the digest of the three files.  The numbers come from
``analysis.core.graphs``; nothing is computed again here.  Every chart copes with one or
two laboratories (a graph that needs three says "too few results" instead) and with more
than ``charts.MANY`` laboratories (codes not written, except the reader's own).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Literal

import numpy as np
from matplotlib.figure import Figure
from numpy.typing import ArrayLike

from analysis.charts import (
    BAD,
    BAND,
    LAB,
    MANY,
    OWN,
    WARN,
    _figure,
    _lab_ticks,
    _note,
    _runs,
    _with_rc,
    axis_unit,
    value_axis,
)
from analysis.charts import svg_of as _svg_of
from analysis.core import graphs
from analysis.core.groups import CoreInputError
from analysis.score_charts import en_bar_chart as en_bar_chart
from analysis.score_charts import en_bar_figure, lab_overview_figure, z_figure
from analysis.score_charts import lab_overview_chart as lab_overview_chart
from analysis.score_charts import z_chart as z_chart

if TYPE_CHECKING:
    from matplotlib.axes import Axes

FEW = 3  # a Youden ellipse, a kernel density and Mandel's h need at least three results
#: "how to read this" under each figure (pages; the reports reuse the text), by chart name
CAPTIONS: dict[str, str] = {
    "point": "Each participant's result with its expanded uncertainty U; the band is "
    "x_pt ± U(x_pt) (k = 2).",
    "en": "En per participant in the order of their codes; dashed lines at ± the En limit; "
    "red bars are outside it (an action signal).",
    "z": "The score that counts at this point (z, or z′ where u(x_pt) > 0.3 σ_pt), sorted; "
    "dashed lines at ±2 (warning, amber bars beyond) and ±3 (action, red bars beyond). A "
    "participant far from the others on one side points to a bias of its own.",
    "en-bars": "En per participant sorted from the most negative to the most positive; dashed "
    "lines at ± the En limit, red bars outside it. A run of bars on one side shows results "
    "that agree with each other but not with x_pt.",
    "overview": "One participant's En (top) and z or z′ (bottom) at every point it measured, "
    "grouped by device and bench (the grey separators); dashed lines at ± the En limit and "
    "at ±2 and ±3 for z. A group of bars on one side shows a bias of one device or bench.",
    "youden": "Each participant's results at the two points, one against the other, with the "
    "assigned values as cross lines, the 45° line through the centre and the 95 % ellipse "
    "of the robust centre and covariance. A participant far along the 45° line has a "
    "systematic error (both results high or both low); far across it, a random one.",
    "mandel-h": "Mandel's h per participant, grouped by measurement point: how far each "
    "participant's result lies from the others' mean, in standard deviations of the results; "
    "amber lines at the 5 % and red lines at the 1 % indicator. The same sign over many "
    "points shows a bias of that participant.",
    "mandel-k": "Mandel's k per participant, grouped by measurement point: each participant's "
    "repeat standard deviation against the pooled one; amber line at the 5 % and red at the "
    "1 % indicator. A high k over many points shows a participant whose repeats scatter.",
    "density": "The kernel density of the results at this point (robust Silverman bandwidth), "
    "the results as ticks on the axis, x_pt (dashed) with its band ± U(x_pt). More than one "
    "peak shows participants that form groups (a difference of method or bench).",
    "doe": "Degrees of equivalence d_i = x_i − x_pt with their expanded uncertainty U(d_i) "
    "(k = 2), as in a key comparison; a bar that does not reach the zero line is a result "
    "that differs from x_pt by more than its uncertainty allows.",
}


# --------------------------------------------------------------------------- helpers


def _few(title: str, n: int, needed: int = FEW, what: str = "results") -> Figure:
    """A small figure that says why there is no graph (instead of failing the page)."""
    fig = _figure(5.6, 1.6)
    ax = fig.add_subplot()
    ax.set_axis_off()
    text = f"Too few {what}: {n}; this graph needs at least {needed}."
    ax.text(0.5, 0.5, text, ha="center", va="center", transform=ax.transAxes)
    ax.set_title(title)
    return fig


# --------------------------------------------------------------------------- Youden


@_with_rc
def youden_figure(
    labels: Sequence[str], x: ArrayLike, y: ArrayLike, *, assigned_x: float,
    assigned_y: float, x_label: str, y_label: str, unit: str, highlight: str | None = None,
) -> Figure:  # fmt: skip
    """Each lab's (x, y) at two points, the assigned values' cross lines, the 45° line through
    the centre and the 95 % ellipse of ``core.graphs.youden_data`` (robust; the classical
    one where more than half of the results are identical)."""
    title = "Youden plot"
    if len(labels) < FEW:
        return _few(title, len(labels), what="participants with results at both points")
    data = _youden(x, y, assigned_x, assigned_y)
    fig = _figure(5.0, 4.6)
    ax = fig.add_subplot()
    xv, yv = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
    if data is not None:
        ring = np.vstack([data.ellipse.vertices, data.ellipse.vertices[:1]])
        ax.fill(ring[:, 0], ring[:, 1], color=BAND, alpha=0.35, lw=0)
        ax.plot(ring[:, 0], ring[:, 1], color=LAB, lw=0.8, label=f"95 % ellipse ({data.method})")
        cx, cy = data.ellipse.centre
        ax.axline((float(cx), float(cy)), slope=1.0, color="#6c757d", lw=0.8, ls=":",
                  label="45° line")  # fmt: skip
    ax.axvline(assigned_x, color=LAB, lw=1, ls="--", label="assigned values")
    ax.axhline(assigned_y, color=LAB, lw=1, ls="--")
    own = np.array([lab == highlight for lab in labels], dtype=bool)
    size = 16 if len(labels) <= MANY else 4
    ax.scatter(xv[~own], yv[~own], s=size, color=LAB, zorder=3)
    if own.any():
        ax.scatter(xv[own], yv[own], s=40, color=OWN, zorder=4, label=str(highlight))
    for lab, px, py, o in zip(labels, xv, yv, own, strict=True):
        if o or len(labels) <= 20:  # codes beside the points while they can be read
            ax.annotate(lab, (px, py), xytext=(3, 3), textcoords="offset points", fontsize=7,
                        color=OWN if o else LAB)  # fmt: skip
    ax.set_xlabel(f"{x_label} ({axis_unit(unit)})")
    ax.set_ylabel(f"{y_label} ({axis_unit(unit)})")
    ax.set_title(title)
    fig.legend(loc="outside lower center", ncols=3, frameon=False)
    return fig


def _youden(
    x: ArrayLike, y: ArrayLike, assigned_x: float, assigned_y: float
) -> graphs.YoudenData | None:
    methods: tuple[Literal["robust", "classical"], ...] = ("robust", "classical")
    for method in methods:
        try:
            return graphs.youden_data(x, y, assigned_x, assigned_y, method=method)
        except CoreInputError:
            continue  # MADe 0 (robust) or the points on a line (both): no ellipse
    return None


youden_chart = _svg_of(youden_figure)


# --------------------------------------------------------------------------- Mandel


@_with_rc
def mandel_figure(
    labs: Sequence[str], points: Sequence[str], values: ArrayLike, critical_5: ArrayLike,
    critical_1: ArrayLike, *, statistic: str,
    reasons: Sequence[str | None] = (), groups: Sequence[str] = (),
    highlight: str | None = None,
) -> Figure:  # fmt: skip
    """Mandel's h or k (``statistic``) per lab (``values``: labs × points, NaN where none),
    grouped by point (and the points by ``groups``, the device), with each point's 5 % and
    1 % indicator lines (± for h) from ``core.graphs.mandel_statistics``."""
    v = np.asarray(values, dtype=float).reshape(len(labs), len(points))
    title = f"Mandel's {statistic} per participant and point"
    if not np.isfinite(v).any():
        why = next((r for r in reasons if r), f"no {statistic} at any point")
        return _note(title, f"Mandel's {statistic} is not available: {why}.")
    n_labs, n_points = v.shape
    fig = _figure(min(14.0, 4.5 + 0.02 * v.size + 0.1 * n_points), 3.4)
    ax = fig.add_subplot()
    slot = n_labs + 1  # one free slot between the points' groups
    x = np.arange(n_points)[np.newaxis, :] * slot + np.arange(n_labs)[:, np.newaxis]
    ok = np.isfinite(v)
    own = np.array([lab == highlight for lab in labs], dtype=bool)[:, np.newaxis] & ok
    ax.vlines(x[ok & ~own], 0, v[ok & ~own], colors=LAB, lw=1.6 if v.size <= 400 else 0.8)
    ax.vlines(x[own], 0, v[own], colors=OWN, lw=2.6)
    _indicators(ax, np.asarray(critical_5, float), np.asarray(critical_1, float), slot, n_labs,
                signs=(1, -1) if statistic == "h" else (1,))  # fmt: skip
    ax.axhline(0, color="black", lw=0.6)
    centres = np.arange(n_points) * slot + (n_labs - 1) / 2
    if n_points <= 40:
        ticks = [_tick_lines(p) for p in points]
        ax.set_xticks(centres, ticks, rotation=90, fontsize=6 if n_points > 12 else 8)
    else:
        ax.set_xticks([])
    if groups:
        _point_groups(ax, groups, slot)
    ax.set_xlabel(f"Measurement point ({n_points}), participants in code order within each")
    ax.set_ylabel(statistic)
    ax.set_title(title, pad=14 if groups else None)
    return fig


def _tick_lines(label: str, width: int = 24) -> str:
    """A point's label (``Z · 5 Hz · curvilinear tangential · angular-rate sensitivity``)
    on lines of at most ``width`` characters, broken at its ``·``: a long label standing
    upright under its bars would take the height of the plot."""
    lines: list[str] = []
    for part in label.split(" · "):
        if lines and len(lines[-1]) + 3 + len(part) <= width:
            lines[-1] += " · " + part
        else:
            lines.append(part)
    return "\n".join(lines)


def _indicators(
    ax: Axes, crit_5: np.ndarray, crit_1: np.ndarray, slot: int, n_labs: int,
    signs: tuple[int, ...],
) -> None:  # fmt: skip
    """Each point's indicator lines over its labs' bars: one line collection per colour."""
    start = np.arange(crit_5.size) * slot - 0.5
    for crit, colour in ((crit_5, WARN), (crit_1, BAD)):
        ok = np.isfinite(crit)
        for sign in signs:
            ax.hlines(sign * crit[ok], start[ok], start[ok] + n_labs, colors=colour, lw=0.9,
                      linestyles="--")  # fmt: skip


def _point_groups(ax: Axes, groups: Sequence[str], slot: int) -> None:
    for start, end in _runs(groups):
        if start:
            ax.axvline(start * slot - 1, color="#adb5bd", lw=0.8)
        ax.text((start + end) * slot / 2 - 1, 1.02, groups[start], ha="center", va="bottom",
                fontsize=7, transform=ax.get_xaxis_transform())  # fmt: skip


mandel_chart = _svg_of(mandel_figure)


# --------------------------------------------------------------------------- density


@_with_rc
def density_figure(
    values: ArrayLike, *, assigned_value: float, assigned_expanded_uncertainty: float,
    title: str, unit: str, own_value: float | None = None, quantity: str | None = None,
) -> Figure:  # fmt: skip
    """The kernel density of one point's results (``core.graphs.kernel_density``), the
    results as a rug, x_pt with its ±U band, the reader's own result in ``OWN``."""
    v = np.asarray(values, dtype=float)
    if v.size < FEW:
        return _few(title, int(v.size))
    try:
        kde = graphs.kernel_density(v)
    except CoreInputError as exc:
        return _note(title, f"No density: {exc}.")
    fig = _figure(5.6, 3.0)
    ax = fig.add_subplot()
    lo, hi = (assigned_value - assigned_expanded_uncertainty,
              assigned_value + assigned_expanded_uncertainty)  # fmt: skip
    ax.axvspan(lo, hi, color=BAND, alpha=0.45, label="x_pt ± U(x_pt)")
    ax.axvline(assigned_value, color=LAB, lw=1, ls="--", label="x_pt")
    ax.plot(kde.grid, kde.density, color=LAB, lw=1.2, label="kernel density")
    ax.fill_between(kde.grid, kde.density, color=LAB, alpha=0.12, lw=0)
    ax.plot(v, np.zeros_like(v), "|", color=LAB, ms=10, mew=0.8)
    if own_value is not None:
        ax.plot([own_value], [0], "|", color=OWN, ms=18, mew=2.4, label="your result")
    ax.set_ylim(bottom=0)
    ax.set_xlabel(value_axis(unit, quantity))
    ax.set_ylabel("Density")
    ax.set_title(title)
    fig.legend(loc="outside lower center", ncols=4, frameon=False)
    return fig


density_chart = _svg_of(density_figure)


# --------------------------------------------------------------------------- DoE


@_with_rc
def doe_figure(
    labels: Sequence[str], d: ArrayLike, expanded: ArrayLike, *, title: str,
    unit: str, highlight: str | None = None,
) -> Figure:  # fmt: skip
    """d_i ± U(d_i) per lab (``core.graphs.doe_data``), key-comparison style, zero line."""
    if not labels:
        return _note(title, "No result at this point.")
    fig = _figure(5.6, 3.2)
    ax = fig.add_subplot()
    x = np.arange(len(labels))
    y, err = np.asarray(d, dtype=float), np.asarray(expanded, dtype=float)
    own = np.array([lab == highlight for lab in labels], dtype=bool)
    size, cap = (4, 3) if len(labels) <= MANY else (2, 0)
    for mask, colour in ((~own, LAB), (own, OWN)):  # one artist per colour, not per lab
        if mask.any():
            ax.errorbar(x[mask], y[mask], yerr=err[mask], fmt="o", ms=size, color=colour,
                        ecolor=colour, capsize=cap, lw=1)  # fmt: skip
    ax.axhline(0, color="black", lw=0.8)
    ax.set_xlabel("Participant")
    _lab_ticks(ax, x, list(labels), highlight)
    ax.set_ylabel(f"d = x − x_pt ({axis_unit(unit)})")
    ax.set_title(title)
    return fig


doe_chart = _svg_of(doe_figure)

#: the figure builders by chart name (the downloads render any of them as SVG or PNG)
FIGURES: dict[str, Callable[..., Figure]] = {
    "z": z_figure, "en-bars": en_bar_figure, "overview": lab_overview_figure,
    "youden": youden_figure, "mandel-h": mandel_figure, "mandel-k": mandel_figure,
    "density": density_figure, "doe": doe_figure,
}  # fmt: skip
