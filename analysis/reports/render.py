"""Render a PT report (docs/domain.md §9) to PDF bytes with reportlab platypus.

Pure: :class:`~analysis.reports.data.ReportData` in, bytes out, no Django.  Output is
byte-stable: ``rl_config.invariant = 1`` removes the random document id, the creation
date comes from the data (the run's finish time), and the charts are deterministic PNGs.
DejaVu Sans (bundled with matplotlib) prints σ, ζ, Δ, ±, ².
"""

from __future__ import annotations

import functools
import zlib
from pathlib import Path
from typing import Any

import matplotlib
from reportlab import rl_config
from reportlab.lib.pagesizes import A4
from reportlab.lib.units import mm
from reportlab.pdfbase import pdfdoc, pdfmetrics
from reportlab.pdfbase.ttfonts import TTFont
from reportlab.pdfgen.canvas import Canvas
from reportlab.platypus import Flowable, PageBreak, Paragraph, SimpleDocTemplate, Spacer

from analysis.reports import sections
from analysis.reports.data import ReportData
from analysis.reports.kit_section import kits_section
from analysis.reports.styles import BOLD, FONT, STYLES

rl_config.invariant = 1
END_MARK = "— End of report —"
STATUS_WORD = {"final": "Final", "preliminary": "Preliminary", "preview": "Preview"}
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


class _Compressed:
    """The FlateDecode filter of a page stream compressed already (:class:`NumberedCanvas`)."""

    pdfname = "FlateDecode"

    def encode(self, content: bytes) -> bytes:
        return content


class NumberedCanvas(Canvas):
    """Holds every page until the end so the footer can say "Page x of y".

    A held page keeps its drawing operators compressed, and each page's stream is
    compressed as soon as the page is written, as reportlab would at save: the same bytes,
    but a summary of 20,000 pages holds tens of MB of page content, not GBs."""

    def __init__(
        self, *args: Any, header: str = "", footer: str = "", date: str = "", **kwargs: Any
    ) -> None:
        super().__init__(*args, **kwargs)
        self._pages: list[dict[str, Any]] = []
        self._header_text, self._footer_text = header, footer
        self.setDateFormatter(lambda *_: date)

    def showPage(self) -> None:
        state = dict(self.__dict__)
        code = self._code
        state["_code"] = zlib.compress("\n".join(code).encode("utf8"), 1) if code else None
        self._pages.append(state)
        self._startPage()

    def save(self) -> None:
        total = len(self._pages)
        pages, self._pages = self._pages, []
        for n, state in enumerate(pages):
            code = state["_code"]
            state["_code"] = [] if code is None else [zlib.decompress(code).decode("utf8")]
            self.__dict__.update(state)
            pages[n] = {}
            self._draw_footer(total)
            super().showPage()
            self._compress(self._doc.Pages.pages[-1])
        super().save()

    def _compress(self, page: Any) -> None:
        """What ``PDFPage.check_format`` does with the page's stream, done now."""
        if not page.compression or page.Contents or not page.stream or rl_config.useA85:
            return
        stream = pdfdoc.PDFStream()
        stream.filters = [_Compressed()]
        stream.content = zlib.compress(page.stream.encode("utf8"))
        stream.__Comment__ = "page stream"
        page.Contents, page.stream = stream, None

    def _draw_footer(self, total: int) -> None:
        """The page's furniture: the header (provider, round, report number) above a rule
        and the footer (status, issue date, "Page n of m") below one."""
        width, height = self._pagesize
        self.saveState()
        self.setFont(FONT, 7.5)
        self.setStrokeGray(0.6)
        self.drawString(MARGIN, height - 11 * mm, self._header_text)
        self.line(MARGIN, height - 12.5 * mm, width - MARGIN, height - 12.5 * mm)
        self.line(MARGIN, 13 * mm, width - MARGIN, 13 * mm)
        self.drawString(MARGIN, 9 * mm, self._footer_text)
        self.drawRightString(width - MARGIN, 9 * mm, f"Page {self._pageNumber} of {total}")
        self.restoreState()


def render_report(data: ReportData) -> bytes:
    """The PDF of one summary or participant report."""
    register_fonts()
    sink = _Sink()
    doc = SimpleDocTemplate(
        sink,
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
    header = f"{data.provider} · {data.comparison_code} · report {data.report_number}"
    footer = f"{STATUS_WORD.get(data.status, data.status)} report · issued " + (
        data.issue_date.strftime("%Y-%m-%d")
    )
    maker = functools.partial(NumberedCanvas, header=header, footer=footer, date=pdf_date(data))
    doc.build(story(data), canvasmaker=maker)
    return sink.data


class _Sink:
    """The file reportlab writes the PDF to: keeps the bytes it is given, where a
    ``BytesIO`` would hold a copy and ``getvalue`` make another (85 MB each for a
    20,000-page summary)."""

    name = "report.pdf"

    def __init__(self) -> None:
        self.chunks: list[bytes] = []

    def write(self, data: bytes) -> None:
        self.chunks.append(data)

    @property
    def data(self) -> bytes:
        return self.chunks[0] if len(self.chunks) == 1 else b"".join(self.chunks)


def _subject(data: ReportData) -> str:
    if data.is_participant:
        return f"Participant report for {data.own_code}, {data.comparison_code}"
    return f"Summary report, {data.comparison_code}"


def story(data: ReportData) -> list[Flowable]:
    """Every section of docs/domain.md §9 in order, ending with the end-of-report mark;
    the performance summary follows the title block, each heading keeps with its next."""
    flow: list[Flowable] = sections.title_page(data)
    if data.is_participant:
        flow += sections.own_performance(data)
        flow += sections.own_history(data)
    else:
        flow += sections.participants_performance(data)
    flow += [PageBreak()]
    flow += sections.confidentiality(data)
    flow += sections.design(data)
    flow += sections.artefacts(data)
    flow += kits_section(data)
    flow += sections.participants(data)
    flow += sections.assigned_values(data)
    flow += sections.results_and_scores(data)
    flow += sections.matrices(data)
    flow += sections.consistency(data)
    flow += sections.charts(data)
    flow += sections.comments(data)
    flow += [Spacer(1, 8 * mm), Paragraph(END_MARK, STYLES["end"])]
    return keep_headings(flow)


#: the styles of what introduces the flowable after it: the headings and an intro sentence
#: (``sections.intro``: "Your laboratory took part in 3 rounds", then the rounds' table)
KEEP_WITH_NEXT = frozenset({"h1", "h2", "intro"})


def is_heading(f: Flowable) -> bool:
    """A heading or an intro sentence: never the last line of a page."""
    return isinstance(f, Paragraph) and f.style.name in KEEP_WITH_NEXT


def keep_headings(flow: list[Flowable]) -> list[Flowable]:
    """Each heading or intro sentence bound to the flowable after it (:class:`WithNext`),
    from the end so a heading followed by an intro (or a heading) keeps both with the
    table or text after them."""
    out: list[Flowable] = []
    for f in reversed(flow):
        if is_heading(f) and out:
            out[-1] = WithNext(f, out[-1])
        else:
            out.append(f)
    return out[::-1]


class WithNext(Flowable):
    """A heading and what follows it: the heading is placed only where the start of what
    follows fits below it (a table's first rows, a paragraph's first lines, the whole of
    an image), else both go to the next page.  (reportlab's ``keepWithNext`` and
    ``KeepTogether`` move a heading with the *whole* of what follows, so a heading over a
    long table would always start a new page.)

    It always splits: ``wrap`` asks for more than any page, and :meth:`split` gives the
    heading and the following flowable (or its first part) back to the frame."""

    def __init__(self, heading: Flowable, following: Flowable) -> None:
        super().__init__()
        self.heading, self.following = heading, following

    def wrap(self, availWidth: float, availHeight: float) -> tuple[float, float]:
        return availWidth, 0xFFFFFF  # force a split, as KeepTogether does

    def getSpaceBefore(self) -> float:
        return float(self.heading.getSpaceBefore())

    def split(self, availWidth: float, availHeight: float) -> list[Flowable]:
        frame = getattr(self, "_frame", None)
        chain = self.chain()  # what follows, down a heading → intro → table chain
        for f in chain:  # as the frame sets them on a flowable it wraps (KeepTogether needs)
            f.canv, f._frame = getattr(self, "canv", None), frame
        try:
            found = self.placed(availWidth, availHeight)
        finally:
            for f in chain:
                del f.canv, f._frame
        if found or not getattr(frame, "_atTop", False):
            return found
        return [self.heading, self.following]  # at the top of a page: as without a heading

    def chain(self) -> list[Flowable]:
        """What follows the heading: the flowable, or the nested ones of a :class:`WithNext`."""
        following = self.following
        return [following, *following.chain()] if isinstance(following, WithNext) else [following]

    def placed(self, width: float, height: float) -> list[Flowable]:
        """The heading and what follows (whole or split) if the start of what follows fits
        in ``height`` below the heading, else nothing.  The frame has taken the heading's
        space before; below the heading are its space after and the space before what
        follows."""
        _, heading = self.heading.wrap(width, height)
        room = height - heading - self.heading.getSpaceAfter() - self.following.getSpaceBefore()
        if room <= 0:
            return []
        if isinstance(self.following, WithNext):
            rest = self.following.placed(width, room)
        elif self.following.wrap(width, room)[1] <= room:
            rest = [self.following]
        else:
            rest = list(self.following.split(width, room))
        return [self.heading, *rest] if rest else []

    def draw(self) -> None:  # never drawn: always split
        raise AssertionError("WithNext is split, never drawn")
