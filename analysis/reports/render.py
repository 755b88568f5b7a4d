"""Render a PT report (domain.md §9) to PDF bytes with reportlab platypus.

Pure: :class:`~analysis.reports.data.ReportData` in, bytes out, no Django.  Output is
byte-stable: ``rl_config.invariant = 1`` removes the random document id, the creation
date comes from the data (the run's finish time), and the charts are deterministic PNGs.
DejaVu Sans (bundled with matplotlib) prints σ, ζ, Δ, ±, ².
"""

from __future__ import annotations

import functools
import io
from pathlib import Path
from typing import Any

import matplotlib
from reportlab import rl_config
from reportlab.lib.pagesizes import A4
from reportlab.lib.units import mm
from reportlab.pdfbase import pdfmetrics
from reportlab.pdfbase.ttfonts import TTFont
from reportlab.pdfgen.canvas import Canvas
from reportlab.platypus import Flowable, PageBreak, Paragraph, SimpleDocTemplate, Spacer

from analysis.reports import sections
from analysis.reports.data import ReportData
from analysis.reports.styles import BOLD, FONT, STYLES

rl_config.invariant = 1
END_MARK = "— End of report —"
MARGIN = 18 * mm


@functools.cache
def register_fonts() -> None:
    """DejaVu Sans and DejaVu Sans Bold from matplotlib's bundled fonts."""
    folder = Path(matplotlib.get_data_path()) / "fonts" / "ttf"
    pdfmetrics.registerFont(TTFont(FONT, str(folder / "DejaVuSans.ttf")))
    pdfmetrics.registerFont(TTFont(BOLD, str(folder / "DejaVuSans-Bold.ttf")))
    pdfmetrics.registerFontFamily(FONT, normal=FONT, bold=BOLD, italic=FONT, boldItalic=BOLD)


def pdf_date(data: ReportData) -> str:
    """The PDF date string of the issue date (UTC), used for CreationDate and ModDate."""
    return data.issue_date.strftime("D:%Y%m%d%H%M%S+00'00'")


class NumberedCanvas(Canvas):
    """Holds every page until the end so the footer can say "Page x of y"."""

    def __init__(self, *args: Any, footer: str = "", date: str = "", **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._pages: list[dict[str, Any]] = []
        self._footer_text = footer
        self.setDateFormatter(lambda *_: date)

    def showPage(self) -> None:
        self._pages.append(dict(self.__dict__))
        self._startPage()

    def save(self) -> None:
        total = len(self._pages)
        for state in self._pages:
            self.__dict__.update(state)
            self._draw_footer(total)
            super().showPage()
        super().save()

    def _draw_footer(self, total: int) -> None:
        width, _ = self._pagesize
        self.saveState()
        self.setFont(FONT, 7.5)
        self.setStrokeGray(0.6)
        self.line(MARGIN, 13 * mm, width - MARGIN, 13 * mm)
        self.drawString(MARGIN, 9 * mm, self._footer_text)
        self.drawRightString(width - MARGIN, 9 * mm, f"Page {self._pageNumber} of {total}")
        self.restoreState()


def render_report(data: ReportData) -> bytes:
    """The PDF of one summary or participant report."""
    register_fonts()
    buffer = io.BytesIO()
    doc = SimpleDocTemplate(
        buffer,
        pagesize=A4,
        leftMargin=MARGIN,
        rightMargin=MARGIN,
        topMargin=MARGIN,
        bottomMargin=20 * mm,
        title=f"{data.report_number}: {data.comparison_title}",
        author=data.provider,
        subject=_subject(data),
        creator=f"proficiency {data.software_version}",
        invariant=1,
    )
    footer = f"{data.provider} · {data.report_number} · {data.status} · issued " + (
        data.issue_date.strftime("%Y-%m-%d")
    )
    maker = functools.partial(NumberedCanvas, footer=footer, date=pdf_date(data))
    doc.build(story(data), canvasmaker=maker)
    return buffer.getvalue()


def _subject(data: ReportData) -> str:
    if data.is_participant:
        return f"Participant report for {data.own_code}, {data.comparison_code}"
    return f"Summary report, {data.comparison_code}"


def story(data: ReportData) -> list[Flowable]:
    """Every section of domain.md §9 in order, ending with the end-of-report mark."""
    flow: list[Flowable] = sections.title_page(data)
    flow += [PageBreak()]
    flow += sections.confidentiality(data)
    if data.is_participant:
        flow += sections.own_performance(data)
    flow += sections.design(data)
    flow += sections.artefacts(data)
    flow += sections.participants(data)
    flow += sections.assigned_values(data)
    flow += sections.results_and_scores(data)
    flow += sections.matrices(data)
    flow += sections.charts(data)
    flow += sections.comments(data)
    flow += [Spacer(1, 8 * mm), Paragraph(END_MARK, STYLES["end"])]
    return flow
