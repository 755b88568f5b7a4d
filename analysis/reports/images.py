"""A chart in the PDF: :class:`RasterImage` writes a chart's pre-compressed pixels as an
image XObject, so a chart shared by many reports is compressed once per process, not once
per report, and draws the reader's own marks over it; the round's shared charts are found
by the run's :class:`~analysis.reports.data.RoundStats` (:func:`round_charts`)."""

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
from analysis.reports.data import ReportData, RoundStats
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

    def __init__(
        self, raster: Raster, overlay: Overlay | tuple[Overlay, ...] | None = None
    ) -> None:
        super().__init__()
        self.raster = raster
        self.overlays = (overlay,) if isinstance(overlay, Overlay) else (overlay or ())
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
        for mark in self.overlays:
            self._draw_overlay(mark)

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


def caption(text: str) -> Paragraph:
    return Paragraph(text, STYLES["caption"])


# The charts of a round by its RoundStats (one object per run and process, shared by
# every report of a large round): a report finds its charts without building the
# round-sized tuples that key the ``charts`` caches (10,000 labs: ~10 ms a report).
_ROUND_CHARTS: weakref.WeakKeyDictionary[RoundStats, dict[object, charts.Shared]] = (
    weakref.WeakKeyDictionary()
)


def round_charts(data: ReportData) -> dict[object, charts.Shared]:
    return _ROUND_CHARTS.setdefault(data.round, {})
