"""The report's graphs as platypus flowables: data → :mod:`charts` raster → PDF image.

:class:`RasterImage` writes the chart's pre-compressed pixels as an image XObject, so a
chart shared by many reports is compressed once per process, not once per report.
"""

from __future__ import annotations

import copy
import functools
import weakref

from reportlab import rl_config
from reportlab.lib.colors import HexColor
from reportlab.lib.rl_accel import asciiBase85Encode
from reportlab.lib.units import mm
from reportlab.pdfbase.pdfdoc import PDFImageXObject
from reportlab.platypus import Flowable, Paragraph

from analysis.reports import charts
from analysis.reports.charts import Overlay, Raster
from analysis.reports.data import AssignedRow, ReportData, RoundStats
from analysis.reports.styles import STYLES

WIDTH = 170 * mm


@functools.lru_cache(maxsize=256)
def _xobject(raster: Raster) -> PDFImageXObject:
    """The XObject reportlab's ``drawImage`` would build from these pixels (same filters).

    The ASCII85 text is kept as the bytes the PDF writer would encode it to (ASCII85 is
    ASCII, so the same bytes and length): encoding ~700 kB of chart text per report
    through reportlab's pure-Python "extpdfdoc" codec took ~15 % of a report's CPU."""
    obj = PDFImageXObject(raster.name)
    obj.width, obj.height = raster.width, raster.height
    obj.bitsPerComponent, obj.colorSpace, obj.mask = 8, "DeviceRGB", None
    if rl_config.useA85:
        obj.streamContent = asciiBase85Encode(raster.stream).encode("ascii")
        obj._filters = ("ASCII85Decode", "FlateDecode")
    else:
        obj.streamContent = raster.stream
        obj._filters = ("FlateDecode",)
    return obj


class RasterImage(Flowable):
    """A chart at full text width, with the reader's own result drawn over it as vector
    marks; the image is what ``Canvas.drawImage`` writes, minus re-encoding."""

    def __init__(self, raster: Raster, overlay: Overlay | None = None) -> None:
        super().__init__()
        self.raster, self.overlay = raster, overlay
        self.width, self.height = WIDTH, WIDTH * raster.height / raster.width

    def wrap(self, available_width: float, available_height: float) -> tuple[float, float]:
        return self.width, self.height

    def draw(self) -> None:
        canvas, name = self.canv, self.raster.name
        canvas._currentPageHasImages = 1
        registered = canvas._doc.getXObjectName(name)
        if not canvas._doc.idToObject.get(registered):
            obj = copy.copy(_xobject(self.raster))  # per document: reportlab sets attributes
            canvas._setXObjects(obj)
            canvas._doc.Reference(obj, registered)
            canvas._doc.addForm(name, obj)
        canvas.saveState()
        canvas.scale(self.width, self.height)
        canvas._code.append(f"/{registered} Do")
        canvas.restoreState()
        canvas._formsinuse.append(name)
        if self.overlay:
            self._draw_overlay(self.overlay)

    def _draw_overlay(self, mark: Overlay) -> None:
        canvas = self.canv
        canvas.saveState()
        canvas.scale(self.width / self.raster.width, self.height / self.raster.height)
        colour = HexColor(mark.colour)
        canvas.setStrokeColor(colour)
        canvas.setFillColor(colour)
        canvas.setLineWidth(mark.line_width)
        if mark.lines:
            canvas.lines(mark.lines)
        for x, y in mark.dots:
            canvas.circle(x, y, mark.dot_radius, stroke=0, fill=1)
        for x0, y0, x1, y1 in mark.rects:
            canvas.rect(x0, y0, x1 - x0, y1 - y0, stroke=0, fill=1)
        canvas.restoreState()


def figures(data: ReportData) -> list[Flowable]:
    """Values vs x_pt for the chosen points, largest |En| per lab, x_pt vs frequency."""
    out: list[Flowable] = []
    if data.own_code:
        note = f"Your result ({data.own_code}) is drawn in pink; the others in blue."
        out.append(Paragraph(note, STYLES["small"]))
    out += _point_charts(data)
    out += _en_chart(data)
    out += _frequency_charts(data)
    if not out:
        out.append(Paragraph("No graphs: the run has no results.", STYLES["body"]))
    return out


# The charts of a round by its RoundStats (one object per run and process, shared by
# every report of a large round): a report finds its charts without building the
# round-sized tuples that key the ``charts`` caches (10,000 labs: ~10 ms a report).
_ROUND_CHARTS: weakref.WeakKeyDictionary[RoundStats, dict[object, charts.Shared]] = (
    weakref.WeakKeyDictionary()
)


def _round_charts(data: ReportData) -> dict[object, charts.Shared]:
    return _ROUND_CHARTS.setdefault(data.round, {})


def _point_chart(
    data: ReportData, index: int, assigned: dict[int, AssignedRow]
) -> charts.PointChart | None:
    """The shared chart of point ``index``; None when it has no assigned value or result."""
    p, a = data.points[index], assigned.get(index)
    if a is None:
        return None
    key = ("point", index, a.value, a.expanded_uncertainty, p.full_label, p.unit)
    found = _round_charts(data)
    chart = found.get(key)
    if chart is None:
        rows = data.round.point_values.get(index)
        if rows is None or not rows.labs:
            return None
        chart = found[key] = charts.point_chart(
            rows.labs,
            rows.values,
            rows.uncertainties,
            x_pt=a.value,
            u_x_pt_expanded=a.expanded_uncertainty,
            title=p.full_label,
            unit=p.unit,
        )
    assert isinstance(chart, charts.PointChart)
    return chart


def _point_charts(data: ReportData) -> list[Flowable]:
    out: list[Flowable] = []
    assigned = {a.point: a for a in data.assigned}
    for index in data.chart_points:
        chart = _point_chart(data, index, assigned)
        if chart is not None:
            out.append(RasterImage(chart.raster, chart.overlay(data.own_code)))
    return out


def point_charts_build(data: ReportData) -> int:
    """Build the chart of every point of ``data``'s round now; the number built.  In a
    large round each point is among some participant's worst, so every report process
    needs them all: built together with the round's shared data (the batch's first
    report), not one by one in whichever later reports need them."""
    assigned = {a.point: a for a in data.assigned}
    return sum(_point_chart(data, p.index, assigned) is not None for p in data.points)


def _en_chart(data: ReportData) -> list[Flowable]:
    largest = data.round.largest_en
    if not largest:
        return []
    found = _round_charts(data)
    chart = found.get(("en", data.en_limit))
    if chart is None:
        labs = tuple(lab for lab, _ in largest)
        chart = charts.en_chart(labs, tuple(en for _, en in largest), limit=data.en_limit)
        found[("en", data.en_limit)] = chart
    assert isinstance(chart, charts.EnChart)
    return [RasterImage(chart.raster, chart.overlay(data.own_code))]


def _frequency_charts(data: ReportData) -> list[Flowable]:
    """Median of the participants' results against frequency, one line per bench,
    direction and axis (the same in every report of a run, so the raster is cached)."""
    out: list[Flowable] = []
    for device, series in data.round.frequency:
        unit = next(p.unit for p in data.points if p.device == device)
        title = f"{device}: median sensitivity against frequency"
        out.append(RasterImage(charts.frequency_chart(series, title=title, unit=unit)))
    return out
