"""Server-side charts of the results pages: plain data in, SVG text out (no ORM here).

matplotlib with the Agg canvas and the object-oriented API (``Figure()``, never
``pyplot``), so nothing is shared between requests or threads.  ``svg.hashsalt``
and empty metadata make the output byte-stable: the same data gives the same SVG.
"""

from __future__ import annotations

import io
import math
import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from html import escape
from typing import TYPE_CHECKING, Any, ParamSpec, TypeVar

import matplotlib
import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.colors import LinearSegmentedColormap
from matplotlib.figure import Figure

from common.quantities import label_shown, unit_text

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.typing import RcKeyType

matplotlib.use("Agg")  # no display; the canvas is attached explicitly anyway

MANY = 80  # more laboratories than this: their codes are not written under the bars
OWN = "#d63384"  # the reader's own lab: the same colour in every chart
LAB = "#1f3a5f"
BAND = "#9ec5fe"
BAD = "#dc3545"
WARN = "#e0a800"  # a warning signal (2 < |z| < 3): amber
PNG_DPI = 150
SERIES = ("#1f77b4", "#ff7f0e", "#2ca02c", "#9467bd", "#8c564b", "#17becf")
RC: dict[RcKeyType, Any] = {
    "svg.hashsalt": "pt-charts",
    "svg.fonttype": "none",  # text stays text: searchable, selectable, smaller
    "font.family": "DejaVu Sans",
    "font.size": 9,
    "axes.spines.top": False,
    "axes.spines.right": False,
}
_SIZE = re.compile(r'width="([\d.]+)pt" height="[\d.]+pt"')
EN_CMAP = LinearSegmentedColormap.from_list("en", ["#d1e7dd", "#fff3cd", "#f8d7da", "#dc3545"])


@dataclass(frozen=True)
class Series:
    """One line of the sensitivity-vs-frequency chart."""

    label: str
    x: Sequence[float]
    y: Sequence[float]
    expanded_uncertainty: Sequence[float]


def _figure(width: float, height: float) -> Figure:
    fig = Figure(figsize=(width, height), layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def _svg(fig: Figure, label: str | None = None) -> str:
    svg = svg_file(fig)
    # Inline SVG in an HTML page: drop the XML prologue and the DOCTYPE, keep <svg ...>,
    # and let the viewBox scale it to its container (no fixed width in points).
    svg = svg[svg.index("<svg") :]
    title = label or (fig.axes[0].get_title() if fig.axes else "chart")
    width = _SIZE.search(svg)
    style = f"width:100%;height:auto;max-width:{width.group(1) if width else '100%'}pt"
    attrs = f'class="pt-chart" style="{style}" role="img" aria-label="{escape(title)}"'
    return _SIZE.sub(attrs, svg, count=1)


_P = ParamSpec("_P")
_R = TypeVar("_R")


def _with_rc(func: Callable[_P, _R]) -> Callable[_P, _R]:
    """Build the figure inside the chart style (fonts, spines) as well as save it."""

    def wrapper(*args: _P.args, **kwargs: _P.kwargs) -> _R:
        with matplotlib.rc_context(RC):
            return func(*args, **kwargs)

    wrapper.__doc__, wrapper.__name__ = func.__doc__, func.__name__
    return wrapper


def png(fig: Figure, dpi: int = PNG_DPI) -> bytes:
    """The figure as PNG (the Agg canvas), for a download beside the page's SVG."""
    buffer = io.BytesIO()
    with matplotlib.rc_context(RC):
        fig.savefig(buffer, format="png", dpi=dpi, metadata={"Software": None})
    return buffer.getvalue()


def svg_file(fig: Figure) -> str:
    """The figure as a standalone SVG document (XML prologue, its size in points): a file."""
    buffer = io.StringIO()
    with matplotlib.rc_context(RC):
        fig.savefig(buffer, format="svg", metadata={"Date": None, "Creator": None})
    return buffer.getvalue()


def render(fig: Figure, fmt: str) -> str | bytes:
    """One figure as ``inline`` SVG (a page), an ``svg`` file or ``png`` bytes (downloads)."""
    if fmt == "png":
        return png(fig)
    return svg_file(fig) if fmt == "svg" else _svg(fig)


def svg_of(builder: Callable[_P, Figure]) -> Callable[_P, str]:
    """The chart function of a figure builder: the same arguments, the SVG text out."""

    def chart(*args: _P.args, **kwargs: _P.kwargs) -> str:
        return _svg(builder(*args, **kwargs))

    chart.__doc__ = f"{builder.__name__} as inline SVG: {builder.__doc__}"
    chart.__name__ = builder.__name__.replace("_figure", "_chart")
    return chart


@_with_rc
def point_figure(
    labels: Sequence[str],
    values: Sequence[float],
    expanded_uncertainties: Sequence[float],
    *,
    assigned_value: float,
    assigned_expanded_uncertainty: float,
    title: str,
    unit: str,
    highlight: str | None = None,
    quantity: str | None = None,
) -> Figure:
    """The labs' results with error bars (U) against x_pt and its ±U band, one point."""
    fig = _figure(5.6, 3.4)
    ax = fig.add_subplot()
    x = np.arange(len(labels))
    lo, hi = (
        assigned_value - assigned_expanded_uncertainty,
        assigned_value + assigned_expanded_uncertainty,
    )
    ax.axhspan(lo, hi, color=BAND, alpha=0.45, label="x_pt ± U(x_pt)")
    ax.axhline(assigned_value, color=LAB, lw=1, ls="--", label="x_pt")
    own = np.array([label == highlight for label in labels], dtype=bool)
    y, err = np.asarray(values, dtype=float), np.asarray(expanded_uncertainties, dtype=float)
    size, cap = (4, 3) if len(labels) <= MANY else (2, 0)
    for mask, colour in ((~own, LAB), (own, OWN)):  # one artist per colour, not per lab
        if mask.any():
            ax.errorbar(x[mask], y[mask], yerr=err[mask], fmt="o", ms=size, color=colour,
                        ecolor=colour, capsize=cap, lw=1)  # fmt: skip
    ax.set_xlabel("Participant")
    _lab_ticks(ax, x, labels, highlight)
    ax.set_ylabel(value_axis(unit, quantity))
    ax.set_title(title)
    fig.legend(loc="outside lower center", ncols=2, frameon=False)
    return fig


point_chart = svg_of(point_figure)


def _note(title: str, text: str) -> Figure:
    """A small figure that says, where a graph would stand, why there is none."""
    fig = _figure(5.6, 1.6)
    ax = fig.add_subplot()
    ax.set_axis_off()
    ax.text(0.5, 0.5, text, ha="center", va="center", transform=ax.transAxes, wrap=True)
    ax.set_title(title)
    return fig


def _runs(groups: Sequence[str]) -> list[tuple[int, int]]:
    """(start, end) of each run of equal neighbours in ``groups``, the end exclusive."""
    starts = [i for i, g in enumerate(groups) if i == 0 or groups[i - 1] != g]
    return list(zip(starts, [*starts[1:], len(groups)], strict=True))


def _mark_own_tick(ax: Axes, labels: Sequence[str], highlight: str | None) -> None:
    for tick, label in zip(ax.get_xticklabels(), labels, strict=False):
        if label == highlight:
            tick.set_color(OWN)
            tick.set_fontweight("bold")


def _lab_ticks(ax: Axes, x: np.ndarray, labels: Sequence[str], highlight: str | None) -> None:
    """One tick per laboratory code up to ``MANY`` laboratories; beyond, where a code could
    not be read anyway (and laying out a thousand tick labels takes seconds), only the
    reader's own code is written and the axis says how many laboratories it holds."""
    if len(labels) <= MANY:
        ax.set_xticks(x, labels, rotation=90 if len(labels) > 14 else 0)
        _mark_own_tick(ax, labels, highlight)
        return
    own = [i for i, label in enumerate(labels) if label == highlight]
    ax.set_xticks(x[own], [labels[i] for i in own], rotation=90)
    _mark_own_tick(ax, [labels[i] for i in own], highlight)
    ax.set_xlim(-1, len(labels))
    ax.set_xlabel(f"Participant ({len(labels)}, codes not written)")


@_with_rc
def en_figure(
    labels: Sequence[str],
    en: Sequence[float],
    *,
    title: str,
    limit: float = 1.0,
    highlight: str | None = None,
) -> Figure:
    """Signed En per lab as bars in the labs' order, with the ±limit lines (|En| > limit:
    red); ``analysis.standard_charts.en_bar_chart`` is the same sorted."""
    fig = _figure(5.6, 3.0)
    ax = fig.add_subplot()
    x = np.arange(len(labels))
    values = np.asarray(en, dtype=float)
    colours = [
        OWN if lab == highlight else (BAD if abs(v) > limit else LAB)
        for lab, v in zip(labels, values, strict=True)
    ]
    if len(labels) <= MANY:
        ax.bar(x, values, color=colours, width=0.6)
    else:  # one line collection instead of a thousand rectangles (a bar is a line here)
        ax.vlines(x, 0, values, colors=colours, lw=0.8)
        own = np.array([lab == highlight for lab in labels], dtype=bool)
        if own.any():  # the reader's own bar drawn again on top, wider
            ax.vlines(x[own], 0, values[own], colors=OWN, lw=2.5)
    for y in (limit, -limit):
        ax.axhline(y, color=BAD, lw=1, ls="--")
    ax.axhline(0, color="black", lw=0.6)
    top = max(1.5 * limit, float(np.nanmax(np.abs(values))) * 1.1 if values.size else 0)
    ax.set_ylim(-top, top)
    ax.set_xlabel("Participant")
    _lab_ticks(ax, x, labels, highlight)
    ax.set_ylabel("En")
    ax.set_title(title)
    return fig


en_chart = svg_of(en_figure)


@_with_rc
def frequency_chart(
    series: Sequence[Series],
    *,
    title: str,
    unit: str,
    nominal: float | None = None,
    nominal_half_width: float | None = None,
    quantity: str | None = None,
) -> str:
    """Sensitivity against frequency, one line per series with U error bars (study Fig. 8/10).

    The nominal value and its tolerance are drawn as a band when given."""
    fig = _figure(5.2, 3.6)
    ax = fig.add_subplot()
    if nominal is not None:
        if nominal_half_width:
            ax.axhspan(nominal - nominal_half_width, nominal + nominal_half_width,
                       color="#e9ecef", label="nominal ± tolerance")  # fmt: skip
        ax.axhline(nominal, color="#6c757d", lw=0.8, ls=":", label="nominal")
    shift = _offsets(series)
    for i, s in enumerate(series):
        x = np.asarray(s.x, dtype=float) + shift[i]
        ax.errorbar(x, s.y, yerr=s.expanded_uncertainty, fmt="-o", ms=4, capsize=3, lw=1,
                    color=SERIES[i % len(SERIES)], label=s.label)  # fmt: skip
    ax.set_xlabel("Frequency (Hz)")
    ax.set_ylabel(value_axis(unit, quantity))
    ax.set_title(title)
    fig.legend(loc="outside lower center", ncols=5, frameon=False)
    return _svg(fig)


def _offsets(series: Sequence[Series]) -> list[float]:
    """Small x shifts (1.2 % of the span each) so that overlapping error bars stay readable."""
    xs = [float(x) for s in series for x in s.x]
    span = (max(xs) - min(xs)) if xs else 1.0
    n = len(series)
    return [0.012 * (span or 1.0) * (i - (n - 1) / 2) for i in range(n)]


def axis_unit(unit: str) -> str:
    """A unit on an axis: ``°`` for degrees, ``²`` for a square
    (``common.quantities.unit_text``)."""
    return unit_text(unit)


def value_axis(unit: str, quantity: str | None = None) -> str:
    """The axis of a point's values: its quantity's label and unit (docs/domain.md §3.1),
    ``Sensitivity (D/(m/s²))`` for a magnitude as before kinds existed, ``Sensitivity phase
    (°)``, ``Angular-rate sensitivity (D/(°/s))``."""
    shown = label_shown(quantity)
    return f"{shown[:1].upper() + shown[1:] if shown else 'Sensitivity'} ({axis_unit(unit)})"


@_with_rc
def heatmap(
    levels: Sequence[str],
    en: Sequence[Sequence[float]],
    *,
    title: str,
    limit: float = 1.0,
    highlight: str | None = None,
) -> str:
    """Pairwise En between levels as a heat map with the values printed in the cells."""
    n = len(levels)
    size = min(9.0, 1.9 + 0.45 * n)
    fig = _figure(size + 0.8, size)
    ax = fig.add_subplot()
    matrix = np.asarray(en, dtype=float).reshape(n, n)
    top = max(2.0 * limit, float(np.nanmax(matrix)) if matrix.size else 0.0)
    image = ax.imshow(matrix, cmap=EN_CMAP, vmin=0.0, vmax=top)
    small = n > 12
    for (i, j), v in np.ndenumerate(matrix):
        if i != j and math.isfinite(v):
            ax.text(j, i, f"{v:.2f}", ha="center", va="center", fontsize=6 if small else 8,
                    fontweight="bold" if v > limit else "normal")  # fmt: skip
    ax.set_xticks(range(n), levels, rotation=90 if n > 6 else 0)
    ax.set_yticks(range(n), levels)
    for ticks in (ax.get_xticklabels(), ax.get_yticklabels()):
        for tick, label in zip(ticks, levels, strict=False):
            if label == highlight:
                tick.set_color(OWN)
                tick.set_fontweight("bold")
    ax.spines[:].set_visible(False)
    fig.colorbar(image, ax=ax, shrink=0.8, label=f"En (incompatible > {limit:g})")
    return _svg(fig, label=f"En matrix: {title}")
