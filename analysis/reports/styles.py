"""Fonts, paragraph styles and table colours shared by the report sections."""

from __future__ import annotations

from reportlab.lib import colors
from reportlab.lib.enums import TA_CENTER
from reportlab.lib.styles import ParagraphStyle

FONT = "DejaVuSans"
BOLD = "DejaVuSans-Bold"
OWN_BACKGROUND = colors.HexColor("#fde2ef")
HEAD_BACKGROUND = colors.HexColor("#1f3a5f")
BAD_TEXT = colors.HexColor("#b02a37")
GRID = colors.HexColor("#adb5bd")


def _style(name: str, size: float, *, bold: bool = False, **kw: object) -> ParagraphStyle:
    options: dict[str, object] = {"leading": size * 1.3} | kw
    return ParagraphStyle(name, fontName=BOLD if bold else FONT, fontSize=size, **options)


STYLES: dict[str, ParagraphStyle] = {
    "title": _style("title", 20, bold=True, spaceAfter=6, leading=25),
    "subtitle": _style("subtitle", 13, spaceAfter=14),
    "h1": _style("h1", 13, bold=True, spaceBefore=10, spaceAfter=5),
    "h2": _style("h2", 10.5, bold=True, spaceBefore=8, spaceAfter=4),
    "body": _style("body", 9, spaceAfter=4),
    # a body sentence that introduces the table or figure after it: kept with it
    "intro": _style("intro", 9, spaceAfter=4),
    "small": _style("small", 7.5),
    "caption": _style("caption", 7.5, spaceBefore=2, spaceAfter=8, textColor="#495057"),
    "cell": _style("cell", 7.5),
    "bullet": _style("bullet", 8.5, leftIndent=10, bulletIndent=2, spaceAfter=2),
    "end": _style("end", 10, bold=True, alignment=TA_CENTER),
}
