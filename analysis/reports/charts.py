"""Charts for the PDF reports: matplotlib (Agg, object-oriented API) at 200 dpi.

Plain numbers in, :class:`Raster` (RGB pixels, already Flate-compressed for the PDF) out.
Building, laying out and compressing a matplotlib figure is most of a chart's cost, and
every report of a run shows the same data, so a chart is built and rasterised once per
process (``lru_cache``); the reader's own result is an :class:`Overlay` of vector marks
that the PDF draws over the shared raster.  Margins are fixed (no constrained
layout), so the pixels depend on the data and the highlight only: a report renders
byte-identically however many reports the process rendered before it.

Above ``COLLECTED`` labs the error bars and the |En| bars are drawn as one collection
each from float arrays, not as matplotlib's ``errorbar`` / ``bar`` (a masked array per
bar, a ``Rectangle`` artist per bar and a "best" legend position tested against each):
the same pixels (tests/analysis/reports/test_charts_many.py); for 10,000 labs the |En|
chart takes ~0.45 s instead of ~11 s and a point chart ~0.25 s instead of ~0.45 s.
"""

from __future__ import annotations

import functools
import hashlib
import zlib
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, cast

import matplotlib
import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.collections import LineCollection, PolyCollection
from matplotlib.figure import Figure
from matplotlib.legend import Legend
from matplotlib.path import Path

from analysis.charts import value_axis

matplotlib.use("Agg")

DPI = 200
OWN = "#d63384"
LAB = "#1f3a5f"
BAND = "#9ec5fe"
BAD = "#dc3545"
LABELLED = 60  # above this many labs the x axis carries no codes (they would overlap)
COLLECTED = LABELLED  # above this many labs the bars are drawn as one collection
RC: dict[Any, Any] = {
    "font.family": "DejaVu Sans",
    "font.size": 8,
    "axes.spines.top": False,
    "axes.spines.right": False,
}


@dataclass(frozen=True)
class Raster:
    """An RGB bitmap ready for a PDF image XObject: ``stream`` is the zlib-compressed
    pixel rows, ``name`` their MD5 (the XObject name, as reportlab makes it)."""

    width: int
    height: int
    stream: bytes
    name: str


def _figure(width: float, height: float, **margins: float) -> tuple[Figure, Any]:
    fig = Figure(figsize=(width, height), dpi=DPI)
    FigureCanvasAgg(fig)
    fig.subplots_adjust(**({"left": 0.09, "right": 0.98, "top": 0.88, "bottom": 0.17} | margins))
    return fig, fig.add_subplot()


def _raster(fig: Figure, rc: dict[Any, Any] = RC) -> Raster:
    """Draw and grab the RGB pixels (white background, no alpha: no soft mask needed)."""
    with matplotlib.rc_context(rc):
        fig.canvas.draw()
    canvas = cast(FigureCanvasAgg, fig.canvas)  # the one _figure gave it
    rgb = np.ascontiguousarray(np.asarray(canvas.buffer_rgba())[:, :, :3]).tobytes()
    height, width = fig.canvas.get_width_height()[::-1]
    return Raster(width, height, zlib.compress(rgb), hashlib.md5(rgb).hexdigest())


def _x_axis(ax: Any, labels: Sequence[str]) -> dict[str, float]:
    """Lab codes under the x axis (rotated when many); the bottom margin that needs."""
    x = np.arange(len(labels))
    if len(labels) > LABELLED:
        ax.set_xticks([])
        ax.set_xlabel(f"{len(labels)} participants in code order")
        return {"bottom": 0.17}
    size = 8 if len(labels) <= 14 else (6 if len(labels) <= 40 else 4)
    ax.set_xticks(x, labels, rotation=90 if len(labels) > 14 else 0, fontsize=size)
    return {"bottom": 0.17 if len(labels) <= 14 else 0.28}


@functools.lru_cache(maxsize=8)
def _positions(labels: tuple[str, ...]) -> dict[str, int]:
    """Each lab's x position; one dict shared by the charts of a round's points."""
    return {label: i for i, label in enumerate(labels)}


def _errorbars(ax: Any, y: np.ndarray, u: np.ndarray, *, ms: float, lw: float) -> None:
    """``ax.errorbar(x, y, yerr=u, fmt="o", ms=ms, color=LAB, ecolor=LAB, capsize=0,
    lw=lw)`` at x = 0, 1, ...: its marker line (zorder 2.1), its bars as one
    ``LineCollection`` (zorder 2) and the same data limits, without a masked array per bar."""
    x = np.arange(len(y), dtype=float)
    ax.plot(x, y, "o", ms=ms, color=LAB, lw=lw, zorder=2.1, label="_nolegend_")
    low, high = y - u, y + u
    segments: Any = np.stack([np.stack([x, low], axis=1), np.stack([x, high], axis=1)], axis=1)
    bars = _Segments(segments, colors=LAB, linewidths=lw, zorder=2, label="_nolegend_")
    ax.add_collection(bars, autolim=False)
    if len(x):
        ax.update_datalim(((x.min(), np.nanmin(low)), (x.max(), np.nanmax(high))))
        ax._request_autoscale_view()


class _Segments(LineCollection):
    """Straight segments given as one (n, 2, 2) float array, each one's ``Path`` as
    ``Path(segment)`` makes it (the attributes of the first copied to the others) without
    the per-segment checks: ~3 instead of ~15 µs a segment."""

    def set_segments(self, segments: Any) -> None:
        if segments is None or not len(segments) or isinstance(segments, np.ma.MaskedArray):
            super().set_segments(segments)
            return
        first = Path(np.asarray(segments[0], float))
        fast = Path._fast_from_codes_and_verts  # type: ignore[attr-defined]  # private, stable
        self._paths = [fast(s, None, first) for s in segments]
        self.stale = True


def _bars(ax: Any, heights: np.ndarray, colours: Sequence[str], width: float) -> _BarBoxes:
    """``ax.bar(x, heights, color=colours, width=width)`` at x = 0, 1, ... as one
    ``PolyCollection``: the same rectangles (left = x − width/2, right = left + width, as
    a ``Rectangle`` computes them), colours, data limits and sticky bottom edge."""
    left = np.arange(len(heights), dtype=float) - width / 2
    right, bottom = left + width, np.zeros(len(heights))
    corners = np.stack([left, bottom, right, heights], axis=1)
    verts: Any = corners[:, [[0, 1], [0, 3], [2, 3], [2, 1]]]
    bars = PolyCollection(verts, facecolors=colours, edgecolors="none", linewidths=0)
    bars.sticky_edges.y.append(0.0)
    ax.add_collection(bars, autolim=True)
    return _BarBoxes(bars, corners)


@dataclass(frozen=True, eq=False)
class _BarBoxes:
    """A ``_bars`` collection and its rectangles (left, bottom, right, top), data units."""

    collection: PolyCollection
    corners: np.ndarray

    def display_boxes(self, ax: Any) -> list[np.ndarray]:
        """Each bar's box in display units, as ``Rectangle.get_bbox().transformed(
        transData)`` gives it: x from the bottom corners, the top from the left corner."""
        c, to_px = self.corners, ax.transData
        low = to_px.transform(c[:, [0, 1]])
        high_x = to_px.transform(c[:, [2, 1]])[:, 0]
        high_y = to_px.transform(c[:, [0, 3]])[:, 1]
        return list(np.stack([low, np.stack([high_x, high_y], axis=1)], axis=1))


class _BarsLegend(Legend):
    """A legend whose "best" position counts each of the bars as a box, as it counts the
    ``Rectangle`` of each bar that ``ax.bar`` adds (one vectorised overlap count), and not
    as a path of a ``PolyCollection`` tested one by one (seconds for 10,000 bars)."""

    bars: _BarBoxes

    @classmethod
    def add(cls, ax: Any, bars: _BarBoxes, **kwargs: Any) -> None:
        """``ax.legend(**kwargs)`` with this class, set up as ``Axes.legend`` does."""
        handles, labels = ax.get_legend_handles_labels()
        legend = cls(ax, handles, labels, **kwargs)
        legend.bars = bars
        ax.legend_ = legend
        legend._remove_method = ax._remove_legend  # type: ignore[attr-defined]

    def _auto_legend_data(self, renderer: Any) -> tuple[list[Any], list[Any], list[Any]]:
        """matplotlib's hit-test data without the bars' collection, plus the bars' boxes."""
        ax: Any = self.parent
        children = ax._children
        ax._children = [c for c in children if c is not self.bars.collection]
        try:
            bboxes, lines, offsets = super()._auto_legend_data(renderer)  # type: ignore[misc]
        finally:
            ax._children = children
        return [*bboxes, *self.bars.display_boxes(ax)], lines, offsets


@dataclass(frozen=True)
class Overlay:
    """The reader's own result drawn as vector marks over a shared chart, in the chart's
    pixel coordinates (origin bottom left): segments, dots and filled rectangles."""

    lines: tuple[tuple[float, float, float, float], ...] = ()
    line_width: float = 0.0
    dots: tuple[tuple[float, float], ...] = ()
    dot_radius: float = 0.0
    rects: tuple[tuple[float, float, float, float], ...] = ()
    colour: str = OWN


PX = DPI / 72  # pixels per point


class Shared:
    """A figure drawn once per process: every report of a run embeds the same raster, and
    a participant's own result is an :class:`Overlay` drawn on top of it in the PDF."""

    fig: Figure
    ax: Any
    to_px: Any  # the axes' data → pixel transform, frozen once drawn (the figure is dropped)

    def _freeze(self, rc: dict[Any, Any] = RC) -> None:
        """Rasterise, keep the data → pixel transform and drop the figure: a cached chart
        of ten thousand labs would otherwise hold its artists (megabytes) for good."""
        self.raster = _raster(self.fig, rc)
        self.to_px = self.ax.transData.frozen()
        del self.fig, self.ax

    def _px(self, x: float, y: float) -> tuple[float, float]:
        px, py = self.to_px.transform((x, y))
        return float(px), float(py)


class PointChart(Shared):
    """Each lab's result ± U against x_pt and its ±U band, for one measurement point."""

    def __init__(
        self,
        labels: tuple[str, ...],
        values: tuple[float, ...],
        expanded: tuple[float, ...],
        *,
        x_pt: float,
        u_x_pt_expanded: float,
        title: str,
        unit: str,
        quantity: str | None = None,
    ) -> None:
        self.index = _positions(labels)
        self.values, self.expanded = values, expanded
        many = len(labels) > LABELLED
        self.style = (1.5, 0.6, 0) if many else (3, 1.0, 2)  # marker size, line width, cap
        with matplotlib.rc_context(RC):
            self.fig, self.ax = _figure(6.4, 2.6)
            ax = self.ax
            ax.axhspan(
                x_pt - u_x_pt_expanded,
                x_pt + u_x_pt_expanded,
                color=BAND,
                alpha=0.45,
                label="x_pt ± U(x_pt)",
            )
            ax.axhline(x_pt, color=LAB, lw=1, ls="--", label="x_pt")
            ms, lw, cap = self.style
            if len(labels) > COLLECTED:
                _errorbars(ax, np.asarray(values, dtype=float), np.asarray(expanded, dtype=float),
                           ms=ms, lw=lw)  # fmt: skip
            else:
                ax.errorbar(
                    np.arange(len(labels)), values, yerr=expanded, fmt="o", ms=ms, color=LAB,
                    ecolor=LAB, capsize=cap, lw=lw,
                )  # fmt: skip
            self.fig.subplots_adjust(**_x_axis(ax, labels))
            ax.set_ylabel(value_axis(unit, quantity))
            ax.ticklabel_format(axis="y", useOffset=False)
            ax.set_title(title)
            ax.legend(loc="best", fontsize=7, frameon=False)
        self._freeze()

    def overlay(self, highlight: str | None) -> Overlay | None:
        """``highlight``'s result ± U as matplotlib drew it, for drawing in pink on top."""
        i = self.index.get(highlight) if highlight else None
        if i is None:
            return None
        y, u = self.values[i], self.expanded[i]
        ms, lw, cap = self.style
        (x0, y0), (x1, y1) = self._px(i, y - u), self._px(i, y + u)
        lines = [(x0, y0, x1, y1)]
        half = cap * PX
        lines += [(x0 - half, yy, x0 + half, yy) for yy in (y0, y1)] if cap else []
        # a little wider than matplotlib's marks, so no blue shows at the anti-aliased edges
        return Overlay(tuple(lines), 1.5 * lw * PX, (self._px(i, y),), 0.6 * ms * PX)


@functools.lru_cache(maxsize=128)
def point_chart(
    labels: tuple[str, ...],
    values: tuple[float, ...],
    expanded: tuple[float, ...],
    *,
    x_pt: float,
    u_x_pt_expanded: float,
    title: str,
    unit: str,
    quantity: str | None = None,
) -> PointChart:
    """The (cached) chart of one point: every report of a run shares it."""
    return PointChart(
        labels,
        values,
        expanded,
        x_pt=x_pt,
        u_x_pt_expanded=u_x_pt_expanded,
        title=title,
        unit=unit,
        quantity=quantity,
    )


class BarChart(Shared):
    """One bar per lab at x = 0, 1, ... (``index``: a lab's position, ``values``: the bars'
    heights as drawn); the reader's own bar is an overlay of the same box."""

    WIDTH: float
    index: dict[str, int]
    values: tuple[float, ...]

    def overlay(self, highlight: str | None) -> Overlay | None:
        i = self.index.get(highlight) if highlight else None
        if i is None:
            return None
        half = self.WIDTH / 2
        (x0, y0), (x1, y1) = self._px(i - half, 0.0), self._px(i + half, self.values[i])
        return Overlay(rects=((x0, min(y0, y1), x1, max(y0, y1)),))


class EnChart(BarChart):
    """Largest |En| of each lab over all points, with the compatibility limit."""

    WIDTH = 0.6

    def __init__(self, labs: tuple[str, ...], max_en: tuple[float, ...], *, limit: float) -> None:
        self.index = _positions(labs)
        self.values = max_en
        with matplotlib.rc_context(RC):
            self.fig, self.ax = _figure(6.4, 2.4)
            ax = self.ax
            colours = [BAD if e > limit else LAB for e in max_en]
            many = len(labs) > COLLECTED
            if many:
                bars = _bars(ax, np.asarray(max_en, dtype=float), colours, self.WIDTH)
            else:
                ax.bar(np.arange(len(labs)), max_en, color=colours, width=self.WIDTH)
            ax.axhline(limit, color=BAD, lw=1, ls="--", label=f"|En| = {limit:g}")
            self.fig.subplots_adjust(**_x_axis(ax, labs))
            ax.set_ylabel("largest |En|")
            ax.set_title("Largest |En| per participant")
            if many:
                _BarsLegend.add(ax, bars, loc="best", fontsize=7, frameon=False)
            else:
                ax.legend(loc="best", fontsize=7, frameon=False)
        self._freeze()


@functools.lru_cache(maxsize=8)
def en_chart(labs: tuple[str, ...], max_en: tuple[float, ...], *, limit: float) -> EnChart:
    return EnChart(labs, max_en, limit=limit)


@functools.lru_cache(maxsize=16)
def frequency_chart(
    series: tuple[tuple[str, tuple[float, ...], tuple[float, ...]], ...],
    *,
    title: str,
    unit: str,
    quantity: str | None = None,
) -> Raster:
    """Sensitivity against frequency, one line per (bench, direction, axis); the same in
    every report of a run, so the raster itself is cached."""
    with matplotlib.rc_context(RC):
        fig, ax = _figure(6.4, 2.8, right=0.72, bottom=0.16)
        for label, freqs, values in series:
            ax.plot(freqs, values, marker="o", ms=3, lw=1, label=label)
        ax.set_xlabel("Frequency (Hz)")
        ax.set_ylabel(value_axis(unit, quantity))
        ax.ticklabel_format(axis="y", useOffset=False)
        ax.set_title(title)
        ax.legend(loc="center left", bbox_to_anchor=(1.0, 0.5), fontsize=6, frameon=False)
    return _raster(fig)


WARN = "#fd7e14"
SORTED_CAP = 1000.0  # a sorted chart's bars end at ±1000 limits (its frame's edge)
Z_LIMITS = (2.0, 3.0)  # |z| above the first is questionable, at or above the second not


def verdict_colours(values: np.ndarray, limits: tuple[float, ...]) -> list[str]:
    """Blue within the first limit, orange between the two (z), red beyond the last."""
    a = np.abs(values)
    if len(limits) == 1:
        return [BAD if v > limits[0] else LAB for v in a.tolist()]
    low, high = limits
    return [BAD if v >= high else (WARN if v > low else LAB) for v in a.tolist()]


def _limit_lines(ax: Any, limits: tuple[float, ...]) -> None:
    for limit, colour in zip(limits, (WARN, BAD) if len(limits) == 2 else (BAD,), strict=True):
        for sign in (-1, 1):
            ax.axhline(sign * limit, color=colour, lw=0.8, ls="--")
    ax.axhline(0.0, color="#6c757d", lw=0.6)


class SortedChart(BarChart):
    """Every lab's score at one point in ascending order (ISO 13528:2022 10.3, sorted bar
    chart), coloured by verdict, with the limits; the reader's own bar is an overlay."""

    WIDTH = 0.7

    def __init__(
        self, labels: tuple[str, ...], values: tuple[float, ...], *, limits: tuple[float, ...],
        title: str, ylabel: str,
    ) -> None:  # fmt: skip
        self.index = {label: i for i, label in enumerate(labels)}
        y = np.asarray(values, dtype=float)
        colours = verdict_colours(y, limits)
        cap = SORTED_CAP * limits[-1]  # extreme scores (1e300) drawn to the frame's edge
        y = np.clip(y, -cap, cap)
        self.values = tuple(y.tolist())
        with matplotlib.rc_context(RC):
            self.fig, self.ax = _figure(6.4, 2.2)
            ax = self.ax
            if len(labels) > COLLECTED:
                _bars(ax, y, colours, self.WIDTH)
            else:
                ax.bar(np.arange(len(labels)), y, color=colours, width=self.WIDTH)
            _limit_lines(ax, limits)
            top = max(float(np.max(np.abs(y))) if len(y) else 0.0, limits[-1]) * 1.1
            ax.set_ylim(-top, top)
            self.fig.subplots_adjust(**_x_axis(ax, labels))
            ax.set_ylabel(ylabel)
            ax.set_title(title)
        self._freeze()


@functools.lru_cache(maxsize=64)
def sorted_chart(
    labels: tuple[str, ...], values: tuple[float, ...], *, limits: tuple[float, ...],
    title: str, ylabel: str,
) -> SortedChart:  # fmt: skip
    """The (cached) sorted bar chart of one point and score: every report of a run shares it."""
    return SortedChart(labels, values, limits=limits, title=title, ylabel=ylabel)


class OverviewFrame(Shared):
    """The axes of one laboratory's scores over every point of a round (points in report
    order, grouped by device), with the limits, clipped at ±``top``; the laboratory's own
    bars are overlays (:meth:`bars`), so one raster serves every participant."""

    WIDTH = 0.7

    def __init__(
        self, groups: tuple[tuple[str, int, int], ...], n: int, *, limits: tuple[float, ...],
        top: float, title: str, ylabel: str,
    ) -> None:  # fmt: skip
        self.top = top
        with matplotlib.rc_context(RC):
            self.fig, self.ax = _figure(6.4, 1.9, bottom=0.2)
            ax = self.ax
            _limit_lines(ax, limits)
            ax.set_xlim(-0.5, n - 0.5)
            ax.set_ylim(-top, top)
            for start in [start for _, start, _ in groups if start]:
                ax.axvline(start - 0.5, color="#adb5bd", lw=0.6)
            ax.set_xticks([(start + stop - 1) / 2 for _, start, stop in groups],
                          [name for name, _, _ in groups])  # fmt: skip
            ax.tick_params(axis="x", length=0)
            ax.set_ylabel(ylabel)
            ax.set_title(title)
        self._freeze()

    def bars(
        self, at: Sequence[int], values: Sequence[float], colours: Sequence[str]
    ) -> tuple[Overlay, ...]:
        """The bars at point positions ``at``, one overlay per colour; a bar beyond the
        frame ends at its edge with a dot."""
        rects: dict[str, list[tuple[float, float, float, float]]] = {}
        dots: dict[str, list[tuple[float, float]]] = {}
        half = self.WIDTH / 2
        for i, v, colour in zip(at, values, colours, strict=True):
            y = min(max(v, -self.top), self.top)
            (x0, y0), (x1, y1) = self._px(i - half, 0.0), self._px(i + half, y)
            rects.setdefault(colour, []).append((x0, min(y0, y1), x1, max(y0, y1)))
            if y != v:
                dots.setdefault(colour, []).append(((x0 + x1) / 2, y1))
        return tuple(
            Overlay(rects=tuple(r), dots=tuple(dots.get(c, ())), dot_radius=2.5 * PX, colour=c)
            for c, r in sorted(rects.items())
        )


@functools.lru_cache(maxsize=16)
def overview_frame(
    groups: tuple[tuple[str, int, int], ...], n: int, *, limits: tuple[float, ...], top: float,
    title: str, ylabel: str,
) -> OverviewFrame:  # fmt: skip
    return OverviewFrame(groups, n, limits=limits, top=top, title=title, ylabel=ylabel)


class YoudenChart(Shared):
    """Every lab's result at one point against its result at another (ISO 13528:2022
    10.4), the assigned values' cross lines, the 45° line through the centre and the 95 %
    ellipse (``ring``: its vertices; empty: none); the reader's own point is an overlay."""

    def __init__(
        self, labels: tuple[str, ...], x: tuple[float, ...], y: tuple[float, ...], *,
        assigned: tuple[float, float], centre: tuple[float, float] | None,
        ring: tuple[tuple[float, float], ...], x_label: str, y_label: str, title: str,
    ) -> None:  # fmt: skip
        self.index = {label: i for i, label in enumerate(labels)}
        self.x, self.y = x, y
        with matplotlib.rc_context(RC):
            self.fig, self.ax = _figure(6.4, 3.6, left=0.11, bottom=0.14, top=0.91)
            ax = self.ax
            if ring:
                closed = np.array([*ring, ring[0]], dtype=float)
                ax.fill(closed[:, 0], closed[:, 1], color=BAND, alpha=0.35, lw=0)
                ax.plot(closed[:, 0], closed[:, 1], color=LAB, lw=0.8, label="95 % ellipse")
            if centre is not None:
                ax.axline(centre, slope=1.0, color="#6c757d", lw=0.8, ls=":", label="45° line")
            ax.axvline(assigned[0], color=LAB, lw=1, ls="--", label="assigned values")
            ax.axhline(assigned[1], color=LAB, lw=1, ls="--")
            ax.scatter(x, y, s=16 if len(labels) <= LABELLED else 4, color=LAB, zorder=3)
            ax.ticklabel_format(useOffset=False)
            ax.set_xlabel(x_label)
            ax.set_ylabel(y_label)
            ax.set_title(title)
            ax.legend(loc="upper left", fontsize=7, frameon=False)
        self._freeze()

    def overlay(self, highlight: str | None) -> Overlay | None:
        i = self.index.get(highlight) if highlight else None
        if i is None:
            return None
        return Overlay(dots=(self._px(self.x[i], self.y[i]),), dot_radius=3.0 * PX)


@functools.lru_cache(maxsize=16)
def youden_chart(
    labels: tuple[str, ...], x: tuple[float, ...], y: tuple[float, ...], *,
    assigned: tuple[float, float], centre: tuple[float, float] | None,
    ring: tuple[tuple[float, float], ...], x_label: str, y_label: str, title: str,
) -> YoudenChart:  # fmt: skip
    """The (cached) Youden plot of one pair of points: every report of a run shares it."""
    return YoudenChart(labels, x, y, assigned=assigned, centre=centre, ring=ring,
                       x_label=x_label, y_label=y_label, title=title)  # fmt: skip
