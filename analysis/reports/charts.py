"""Charts for the PDF reports: matplotlib (Agg, object-oriented API) at 200 dpi.

Plain numbers in, :class:`Raster` (RGB pixels, already Flate-compressed for the PDF) out.
Building, laying out and compressing a matplotlib figure is most of a chart's cost, and
every report of a run shows the same data, so a chart is built and rasterised once per
process (``lru_cache``); the reader's own result is an :class:`Overlay` of vector marks
that the PDF draws over the shared raster.  Margins are fixed (no constrained
layout), so the pixels depend on the data and the highlight only: a report renders
byte-identically however many reports the process rendered before it.
"""

from __future__ import annotations

import functools
import hashlib
import zlib
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import matplotlib
import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

matplotlib.use("Agg")

DPI = 200
OWN = "#d63384"
LAB = "#1f3a5f"
BAND = "#9ec5fe"
BAD = "#dc3545"
LABELLED = 60  # above this many labs the x axis carries no codes (they would overlap)
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


def _raster(fig: Figure) -> Raster:
    """Draw and grab the RGB pixels (white background, no alpha: no soft mask needed)."""
    with matplotlib.rc_context(RC):
        fig.canvas.draw()
    rgb = np.ascontiguousarray(np.asarray(fig.canvas.buffer_rgba())[:, :, :3]).tobytes()
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

    def _freeze(self) -> None:
        """Rasterise, keep the data → pixel transform and drop the figure: a cached chart
        of ten thousand labs would otherwise hold its artists (megabytes) for good."""
        self.raster = _raster(self.fig)
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
    ) -> None:
        self.index = {label: i for i, label in enumerate(labels)}
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
            ax.errorbar(
                np.arange(len(labels)), values, yerr=expanded, fmt="o", ms=ms, color=LAB,
                ecolor=LAB, capsize=cap, lw=lw,
            )  # fmt: skip
            self.fig.subplots_adjust(**_x_axis(ax, labels))
            ax.set_ylabel(f"Sensitivity ({unit})")
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
    )


class EnChart(Shared):
    """Largest |En| of each lab over all points, with the compatibility limit."""

    WIDTH = 0.6

    def __init__(self, labs: tuple[str, ...], max_en: tuple[float, ...], *, limit: float) -> None:
        self.index = {lab: i for i, lab in enumerate(labs)}
        self.max_en = max_en
        with matplotlib.rc_context(RC):
            self.fig, self.ax = _figure(6.4, 2.4)
            colours = [BAD if e > limit else LAB for e in max_en]
            self.ax.bar(np.arange(len(labs)), max_en, color=colours, width=self.WIDTH)
            self.ax.axhline(limit, color=BAD, lw=1, ls="--", label=f"|En| = {limit:g}")
            self.fig.subplots_adjust(**_x_axis(self.ax, labs))
            self.ax.set_ylabel("largest |En|")
            self.ax.set_title("Largest |En| per participant")
            self.ax.legend(loc="best", fontsize=7, frameon=False)
        self._freeze()

    def overlay(self, highlight: str | None) -> Overlay | None:
        i = self.index.get(highlight) if highlight else None
        if i is None:
            return None
        half = self.WIDTH / 2
        (x0, y0), (x1, y1) = self._px(i - half, 0.0), self._px(i + half, self.max_en[i])
        return Overlay(rects=((x0, y0, x1, y1),))


@functools.lru_cache(maxsize=8)
def en_chart(labs: tuple[str, ...], max_en: tuple[float, ...], *, limit: float) -> EnChart:
    return EnChart(labs, max_en, limit=limit)


@functools.lru_cache(maxsize=16)
def frequency_chart(
    series: tuple[tuple[str, tuple[float, ...], tuple[float, ...]], ...], *, title: str, unit: str
) -> Raster:
    """Sensitivity against frequency, one line per (bench, direction, axis); the same in
    every report of a run, so the raster itself is cached."""
    with matplotlib.rc_context(RC):
        fig, ax = _figure(6.4, 2.8, right=0.72, bottom=0.16)
        for label, freqs, values in series:
            ax.plot(freqs, values, marker="o", ms=3, lw=1, label=label)
        ax.set_xlabel("Frequency (Hz)")
        ax.set_ylabel(f"Sensitivity ({unit})")
        ax.ticklabel_format(axis="y", useOffset=False)
        ax.set_title(title)
        ax.legend(loc="center left", bbox_to_anchor=(1.0, 0.5), fontsize=6, frameon=False)
    return _raster(fig)
