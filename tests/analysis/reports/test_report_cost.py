"""A participant report's CPU does not grow with the round: its charts are
found, not rebuilt from round-sized tuples; table cells share their styles and repeated
cells are formatted once per document; chart streams are stored as the bytes the PDF
writer writes.  Each shortcut writes the bytes reportlab's own way writes."""

import dataclasses
import io
import zlib

from PIL import Image
from reportlab.lib import colors
from reportlab.lib.utils import ImageReader
from reportlab.pdfbase.pdfdoc import PDFDocument, PDFImageXObject
from reportlab.pdfgen.canvas import Canvas
from reportlab.pdfgen.textobject import PDFTextObject
from reportlab.platypus import TableStyle

from analysis.reports import charts, figures, sections, tables
from analysis.reports.data import RoundStats
from analysis.reports.render import register_fonts, render_report
from analysis.reports.styles import BAD_TEXT, BOLD, FONT, GRID, HEAD_BACKGROUND, OWN_BACKGROUND
from tests.analysis.reports.test_visual import small_report

ROWS = [["Point", "Lab", "Flag"]] + [
    [f"X, {f} Hz" if lab == "L01" else "", lab, "satisfactory" if f % 3 else "action"]
    for f in range(5, 80, 5)
    for lab in ("L01", "L02", "L03")
]
WIDTHS = [120.0, 60.0, 90.0]
OWN = [r for r, row in enumerate(ROWS) if row[1] == "L02"]
BAD = [(r, 2) for r, row in enumerate(ROWS) if row[2] == "action"]


def commanded_table(rows, widths, own_rows, bad_cells) -> tables.FastTable:
    """The table as :func:`sections.table` built it with style commands (the older form)."""
    height = [sections.ROW_HEIGHT] * len(rows)
    t = tables.FastTable(rows, colWidths=list(widths), rowHeights=height, repeatRows=1)
    style = [
        ("FONT", (0, 0), (-1, -1), FONT, 7.5),
        ("FONT", (0, 0), (-1, 0), BOLD, 7.5),
        ("TEXTCOLOR", (0, 0), (-1, 0), colors.white),
        ("BACKGROUND", (0, 0), (-1, 0), HEAD_BACKGROUND),
        ("GRID", (0, 0), (-1, -1), 0.25, GRID),
        ("VALIGN", (0, 0), (-1, -1), "TOP"),
        ("TOPPADDING", (0, 0), (-1, -1), 1.5),
        ("BOTTOMPADDING", (0, 0), (-1, -1), 1.5),
    ]
    for r in own_rows:
        style += [("BACKGROUND", (0, r), (-1, r), OWN_BACKGROUND), ("FONT", (0, r), (-1, r), BOLD)]
    style += [("TEXTCOLOR", (c, r), (c, r), BAD_TEXT) for r, c in bad_cells]
    t.setStyle(TableStyle(style))
    return t


def pdf_of(table, canvases: list[Canvas] | None = None) -> bytes:
    register_fonts()
    buf = io.BytesIO()
    canvas = Canvas(buf, invariant=1)
    table.wrapOn(canvas, 500, 800)
    table.drawOn(canvas, 40, 40)
    canvas.showPage()
    canvas.save()
    if canvases is not None:
        canvases.append(canvas)
    return buf.getvalue()


def test_shared_cell_styles_draw_what_the_style_commands_drew():
    shared = sections.table(ROWS, WIDTHS, OWN, BAD)
    assert pdf_of(shared) == pdf_of(commanded_table(ROWS, WIDTHS, OWN, BAD))
    # header, body, own rows, incompatible cells (own and not): five style objects
    assert len({id(s) for row in shared._cellStyles for s in row}) == 5


def test_repeated_cells_are_formatted_once_per_document(monkeypatch):
    calls = []
    real = PDFTextObject._textOut

    def counted(s, t, *a):
        calls.append(t)
        return real(s, t)

    monkeypatch.setattr(PDFTextObject, "_textOut", counted)
    remembered = pdf_of(sections.table(ROWS, WIDTHS, OWN, BAD))
    distinct = {c for row in ROWS for c in row if c}
    assert len(calls) < 2 * len(distinct) < sum(bool(c) for row in ROWS for c in row)
    calls.clear()
    monkeypatch.setattr(tables.FastTable, "_text_out", lambda self, text, state, cell: (
        text._textOut(cell)
    ))  # fmt: skip
    assert pdf_of(sections.table(ROWS, WIDTHS, OWN, BAD)) == remembered


def test_remembered_cells_are_bounded(monkeypatch):
    monkeypatch.setattr(tables, "MEMO_CELLS", 4)
    canvases: list[Canvas] = []
    bounded = pdf_of(sections.table(ROWS, WIDTHS, OWN, BAD), canvases)
    assert 0 < len(canvases[0].__dict__["_fast_table_text"]) <= 4
    monkeypatch.setattr(tables, "MEMO_CELLS", 10**6)
    assert pdf_of(sections.table(ROWS, WIDTHS, OWN, BAD)) == bounded


def test_chart_stream_is_kept_as_the_bytes_the_pdf_writer_writes():
    chart = charts.point_chart(
        ("L1", "L2"), (1.0, 2.0), (0.5, 0.5), x_pt=1.5, u_x_pt_expanded=0.2, title="t", unit="u"
    )
    raster = chart.raster
    pixels = Image.frombytes("RGB", (raster.width, raster.height), zlib.decompress(raster.stream))
    ours = figures._xobject(raster)
    theirs = PDFImageXObject(raster.name, ImageReader(pixels))  # what drawImage embeds
    assert isinstance(ours.streamContent, bytes)  # not re-encoded in every report
    assert ours.format(PDFDocument()) == theirs.format(PDFDocument())


def test_reports_sharing_a_rounds_figures_reuse_its_charts(monkeypatch):
    """Reports of a large round share one RoundStats (the run's context): after the
    first, a report finds its point and |En| charts without calling the chart caches,
    whose keys are tuples of every lab's values (10,000 labs: rebuilt and hashed in
    every report)."""
    first = small_report()
    stats = first.round
    assert isinstance(stats, RoundStats)
    mine = dataclasses.replace(first, stats=stats)
    theirs = dataclasses.replace(mine, own_code="L11", report_number="T-1-L11-v1")
    render_report(mine)
    calls = []
    for name in ("point_chart", "en_chart"):
        real = getattr(charts, name)

        def counted(*a, _r=real, _n=name, **k):
            calls.append(_n)
            return _r(*a, **k)

        monkeypatch.setattr(charts, name, counted)
    other = render_report(theirs)
    assert calls == []
    assert other == render_report(dataclasses.replace(theirs, stats=None))  # same bytes
    assert calls == ["point_chart", "en_chart"]  # figures of its own rows: looked up


def test_every_point_chart_of_a_round_is_built_at_once():
    data = small_report()
    before = len(figures._round_charts(data))
    assert figures.point_charts_build(data) == len(data.points) == 2
    # each point's chart and its sorted En chart (the small round has no z)
    assert len(figures._round_charts(data)) == before + 4
