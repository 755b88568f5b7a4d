"""The standard graphs of ISO 13528:2022 Clause 10 in the reports (docs/domain.md §9, §11):
the kernel density and the degrees of equivalence at the chart points, Mandel's h and k of
the round, and a participant's history over the rounds.

Each is the web's own figure (``analysis.standard_charts``, ``analysis.history_chart``)
drawn from the same numbers (``analysis.core.graphs`` on the run's results, Mandel's
statistics as ``analysis.graph_data.mandel_data`` read them), built without a reader,
resized for the page and rasterised once per run and process: the reader's own marks are
an :class:`~analysis.reports.charts.Overlay` drawn over the shared raster, so a batch of
participant reports draws each graph once.  The captions are the pages' ``CAPTIONS``.
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Sequence

import numpy as np
from matplotlib.figure import Figure
from reportlab.lib.units import mm
from reportlab.platypus import Flowable, KeepTogether, Paragraph, Spacer

from analysis import standard_charts as std
from analysis.charts import MANY
from analysis.charts import RC as WEB_RC
from analysis.core import graphs
from analysis.history_chart import CAPTION as HISTORY_CAPTION
from analysis.history_chart import history_figure
from analysis.reports.charts import DPI, PX, Overlay, Shared
from analysis.reports.data import MandelRound, PointValues, ReportData
from analysis.reports.images import RasterImage, round_charts
from analysis.reports.styles import STYLES

POINT_SIZE = (6.4, 2.5)  # inches: a density or DoE chart, as wide as the report's others
MANDEL_SIZE = (6.4, 3.6)  # room for the points' names under the bars
HISTORY_SIZE = (6.4, 3.4)


class FigureChart(Shared):
    """A figure of the pages drawn without a reader, at the report's size and resolution
    (in the pages' style, ``analysis.charts.RC``); ``drawn``: it has axes, not a note."""

    def __init__(self, fig: Figure, size: tuple[float, float]) -> None:
        fig.set_size_inches(*size)
        fig.set_dpi(DPI)
        self.fig, self.ax = fig, fig.axes[0]
        self.drawn = bool(self.ax.axison)
        self._freeze(WEB_RC)


def _own(labels: Sequence[str], own: str | None) -> int | None:
    return list(labels).index(own) if own is not None and own in labels else None


class DensityChart(FigureChart):
    """``standard_charts.density_figure`` of one point; the reader's result a pink tick."""

    def overlay(self, value: float | None) -> Overlay | None:
        if value is None or not self.drawn:
            return None
        x, y = self._px(value, 0.0)
        return Overlay(lines=((x, y, x, y + 9 * PX),), line_width=2.4 * PX)


class DoEChart(FigureChart):
    """``standard_charts.doe_figure`` of one point; the reader's d ± U(d) in pink."""

    def __init__(self, fig: Figure, d: Sequence[float], big_u: Sequence[float]) -> None:
        super().__init__(fig, POINT_SIZE)
        self.d, self.big_u, self.many = tuple(d), tuple(big_u), len(d) > MANY

    def overlay(self, i: int | None) -> Overlay | None:
        if i is None or not self.drawn:
            return None
        d, u = self.d[i], self.big_u[i]
        (x0, y0), (x1, y1) = self._px(i, d - u), self._px(i, d + u)
        lines = [(x0, y0, x1, y1)]
        if not self.many:  # the caps, 3 pt each side as doe_figure draws them
            lines += [(x0 - 3 * PX, yy, x0 + 3 * PX, yy) for yy in (y0, y1)]
        radius = (1.0 if self.many else 2.0) * PX * 1.2
        return Overlay(tuple(lines), 1.5 * PX, (self._px(i, d),), radius)


class MandelChart(FigureChart):
    """``standard_charts.mandel_figure`` of one device's points; the reader's bars pink."""

    def __init__(self, fig: Figure, values: np.ndarray) -> None:
        super().__init__(fig, MANDEL_SIZE)
        self.values = values  # labs × points, as drawn

    def overlay(self, i: int | None) -> Overlay | None:
        if i is None or not self.drawn:
            return None
        n_labs = self.values.shape[0]
        slot = n_labs + 1  # mandel_figure's layout: one free slot between the points
        row = self.values[i]
        at = [(j * slot + i, float(v)) for j, v in enumerate(row.tolist()) if np.isfinite(v)]
        if not at:
            return None
        lines = tuple((*self._px(x, 0.0), *self._px(x, v)) for x, v in at)
        width = self._px(1.0, 0.0)[0] - self._px(0.0, 0.0)[0]  # one slot, in pixels
        bar = 1.6 if self.values.size <= 400 else 0.8  # mandel_figure's bar width, points
        return Overlay(lines, max(min(2.6 * PX, width), 1.3 * bar * PX))


def _caption(text: str) -> Paragraph:
    return Paragraph(text, STYLES["caption"])


def _group(images: list[Flowable], text: str) -> list[Flowable]:
    """Charts with their caption under the last one: the caption never starts a page."""
    if not images:
        return []
    return [*images[:-1], KeepTogether([images[-1], _caption(text)])]


def _cached(data: ReportData, key: tuple[object, ...], build: Callable[[], Shared]) -> Shared:
    found = round_charts(data)
    chart = found.get(key)
    if chart is None:
        chart = found[key] = build()
    return chart


# --------------------------------------------------------------------------- points


def point_graphs(data: ReportData) -> list[Flowable]:
    """The kernel density and the degrees of equivalence of each chart point."""
    assigned = {a.point: a for a in data.assigned}
    densities: list[Flowable] = []
    does: list[Flowable] = []
    for index in data.chart_points:
        rows, a = data.round.point_values.get(index), assigned.get(index)
        if rows is None or not rows.standard or a is None:
            continue
        p = data.points[index]
        i = _own(rows.labs, data.own_code)
        label, unit = p.full_label, p.unit
        density = _cached(data, ("density", index), functools.partial(
            density_chart, rows, a.value, a.expanded_uncertainty, label, unit,
            p.quantity))  # fmt: skip
        assert isinstance(density, DensityChart)
        mine = None if i is None else rows.values[i]
        densities.append(RasterImage(density.raster, density.overlay(mine)))
        doe = _cached(data, ("doe", index), functools.partial(
            doe_chart, rows, a.value, a.standard_uncertainty, label, unit))  # fmt: skip
        assert isinstance(doe, DoEChart)
        does.append(RasterImage(doe.raster, doe.overlay(i)))
    own = data.own_code
    mark = f" Your result ({own}) is the pink tick." if own else ""
    doe_mark = f" Yours ({own}) is drawn in pink." if own else ""
    return [*_group(densities, std.CAPTIONS["density"] + mark),
            *_group(does, std.CAPTIONS["doe"] + doe_mark)]  # fmt: skip


def density_chart(
    rows: PointValues,
    x_pt: float,
    big_u_pt: float,
    label: str,
    unit: str,
    quantity: str | None = None,
) -> DensityChart:
    """``density_figure`` of a point's results (``core.graphs.kernel_density`` inside)."""
    fig = std.density_figure(rows.values, assigned_value=x_pt,
                             assigned_expanded_uncertainty=big_u_pt,
                             title=f"Kernel density · {label}", unit=unit,
                             quantity=quantity)  # fmt: skip
    return DensityChart(fig, POINT_SIZE)


def doe_data(rows: PointValues, x_pt: float, u_pt: float) -> graphs.DoEData:
    """d_i and U(d_i) of a point's results, as ``graph_data.PointData.doe`` computes them
    (``core.graphs.doe_data`` on U/k and the correlation correction of each result)."""
    return graphs.doe_data(rows.labs, rows.values, rows.standard, x_pt, u_pt,
                           in_assigned=rows.in_assigned)  # fmt: skip


def doe_chart(rows: PointValues, x_pt: float, u_pt: float, label: str, unit: str) -> DoEChart:
    """``doe_figure`` of :func:`doe_data`."""
    found = doe_data(rows, x_pt, u_pt)
    d, big_u = found.d.tolist(), found.U_d.tolist()
    title = f"Degrees of equivalence · {label}"
    return DoEChart(std.doe_figure(rows.labs, d, big_u, title=title, unit=unit), d, big_u)


# --------------------------------------------------------------------------- Mandel


def mandel_graphs(data: ReportData) -> list[Flowable]:
    """Mandel's h, then k, of every participant at every point, one chart per device (the
    whole round in one would leave a pixel per bar), each statistic with its caption."""
    found = data.mandel
    if found is None:
        return []
    out: list[Flowable] = []
    i = _own(found.labs, data.own_code)
    own = f" Your bars ({data.own_code}) are pink." if i is not None else ""
    for statistic in ("h", "k"):
        g = found.graph
        values, reasons = (g.h, g.h_reason) if statistic == "h" else (g.k, g.k_reason)
        if not np.isfinite(values).any():  # one sentence, not a note per device
            why = next((r for r in reasons if r), f"no {statistic} at any point")
            out.append(Paragraph(f"Mandel's {statistic} is not available: {why}.", STYLES["body"]))
            continue
        images: list[Flowable] = []
        for device in dict.fromkeys(found.devices):
            build = functools.partial(mandel_chart, found, statistic, device)
            chart = _cached(data, ("mandel", statistic, device), build)
            assert isinstance(chart, MandelChart)
            images.append(RasterImage(chart.raster, chart.overlay(i)))
        out += _group(images, std.CAPTIONS[f"mandel-{statistic}"] + own)
    return out


def mandel_chart(found: MandelRound, statistic: str, device: str) -> MandelChart:
    """``mandel_figure`` of ``device``'s points (the points' names without the device)."""
    g = found.graph
    columns = [j for j, d in enumerate(found.devices) if d == device]
    values, reasons = (g.h, g.h_reason) if statistic == "h" else (g.k, g.k_reason)
    crit_5, crit_1 = (g.h_critical_5, g.h_critical_1) if statistic == "h" else (
        g.k_critical_5, g.k_critical_1)  # fmt: skip
    prefix = f"{device} · "
    names = [found.points[j].removeprefix(prefix) for j in columns]
    shown = np.asarray(values, dtype=float)[:, columns]
    fig = std.mandel_figure(
        found.labs, names, shown, crit_5[columns], crit_1[columns], statistic=statistic,
        reasons=[reasons[j] for j in columns], groups=[device] * len(columns),
    )  # fmt: skip
    return MandelChart(fig, shown)


# --------------------------------------------------------------------------- history


def history_graph(data: ReportData) -> list[Flowable]:
    """The participant's trend over the rounds (the web's ``/lab/history/`` chart), drawn
    where it has at least two rounds; only its own scores, so not shared."""
    found = data.history
    if found is None or len(found.trend) < 2:
        return []
    codes = [c for c, _, _ in found.trend]
    en = [list(e) for _, e, _ in found.trend]
    z = [list(z) for _, _, z in found.trend]
    chart = FigureChart(history_figure(codes, en, z), HISTORY_SIZE)
    image = RasterImage(chart.raster)
    return [KeepTogether([Spacer(1, 3 * mm), image, _caption(HISTORY_CAPTION)])]
