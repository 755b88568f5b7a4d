"""A platypus ``Table`` that writes its plain-text cells into one PDF text object.

reportlab's ``Table`` draws every string cell with ``Canvas.drawString``: a new text
object, its own ``BT … ET`` and font selection for each cell.  The results tables of a
large round have 10⁵ cells, and that overhead was most of the render time.  The cells
look the same (same font, colour and position as ``Table._drawCell`` computes for
left-aligned, top-aligned single-line strings); anything else falls back to ``Table``.

Two more savings write the same bytes: the text operators of a cell string are
remembered per document (:meth:`FastTable._text_out`), and the cells' styles come as a
few shared objects (:func:`cell_styles`) instead of style commands applied cell by cell.
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Sequence
from html import escape
from typing import Any

import numpy as np
from reportlab.lib import colors
from reportlab.lib.styles import ParagraphStyle
from reportlab.pdfbase.pdfmetrics import stringWidth
from reportlab.platypus import Paragraph, Table
from reportlab.platypus.tables import CellStyle

from analysis.reports.styles import BAD_TEXT, BOLD, FONT
from analysis.reports.styles import STYLES as S

MEMO_CELLS = 20_000
CELL_SIZE = 7.5  # the cells' font size (pt)
V_PADDING = 1.5  # top and bottom padding of a cell
#: reportlab's left and right padding of a cell: its text has the column's width less twice this
H_PADDING = 6.0
ROW_HEIGHT = CELL_SIZE * 1.2 + 2 * V_PADDING  # one line of the cell font + its paddings
#: a single-line text may take part of its cell's right padding, but stops this far from
#: the next column (its top and bottom gap)
RIGHT_GAP = V_PADDING


class FastTable(Table):
    def draw(self) -> None:
        self._text = self.canv.beginText()
        self._text_state: tuple[Any, ...] = ()
        super().draw()
        self.canv.drawText(self._text)

    def _drawCell(self, cellval: Any, cellstyle: Any, pos: Any, size: Any) -> None:
        simple = (
            isinstance(cellval, str)
            and "\n" not in cellval
            and cellstyle.alignment == "LEFT"
            and cellstyle.valign == "TOP"
            and not (cellstyle.href or cellstyle.destination or cellstyle.direction)
        )
        if not simple:
            super()._drawCell(cellval, cellstyle, pos, size)
            return
        if not cellval:
            return
        text = self._text
        state = (cellstyle.fontname, cellstyle.fontsize, cellstyle.leading, cellstyle.color)
        if state != self._text_state:
            text.setFont(cellstyle.fontname, cellstyle.fontsize, cellstyle.leading)
            text.setFillColor(cellstyle.color)
            self._text_state = state
        (colpos, rowpos), (_, rowheight) = pos, size
        y = rowpos + rowheight - cellstyle.topPadding - cellstyle.fontsize
        text.setTextOrigin(colpos + cellstyle.leftPadding, y)
        self._text_out(text, state, cellval)

    def _text_out(self, text: Any, state: tuple[Any, ...], cellval: str) -> None:
        """``text._textOut(cellval)``, its operators remembered per document: the same
        string in the same font state (font, size, leading, colour, current subset of the
        embedded font) gives the same operators once its characters are in the font's
        subsets, and repeats (codes, flags, labels, matrix values) are most cells."""
        memo: dict[tuple[Any, ...], tuple[str, int]] = self.canv.__dict__.setdefault(
            "_fast_table_text", {}
        )
        key = (state, text._curSubset, cellval)
        found = memo.get(key) if type(cellval) is str else None
        if found is None:
            text._textOut(cellval)
            if len(memo) >= MEMO_CELLS:  # a summary of 10⁶ results: bounded memory
                memo.clear()
            memo[key] = text._code[-1], text._curSubset
        else:
            text._code.append(found[0])
            text._curSubset = found[1]


def _cell_style(font: str, colour: object) -> CellStyle:
    """What the style commands FONT (7.5 pt), VALIGN TOP, TOP/BOTTOMPADDING 1.5 and
    TEXTCOLOR make of a cell's default ``CellStyle``."""
    s = CellStyle("cell")
    s.fontname, s.fontsize, s.leading = font, CELL_SIZE, CELL_SIZE * 1.2  # FONT's leading
    s.valign, s.topPadding, s.bottomPadding, s.color = "TOP", V_PADDING, V_PADDING, colour
    return s


def cell_styles(
    n_rows: int, n_cols: int, own_rows: Sequence[int], bad_cells: Sequence[tuple[int, int]]
) -> list[list[CellStyle]]:
    """Cell styles of :func:`analysis.reports.sections.table`: the header bold white, the
    reader's own rows bold, incompatible cells in red.  Cells that look alike share one
    object (reportlab reads them and only ``setStyle`` would change them): a results page
    had ~10⁴ cells, each with its own style object set by eight commands."""
    styles: dict[tuple[str, object], CellStyle] = {}

    def style(font: str, colour: object) -> CellStyle:
        found = styles.get((font, colour))
        if found is None:
            found = styles[(font, colour)] = _cell_style(font, colour)
        return found

    body, own = style(FONT, "black"), style(BOLD, "black")
    own_set = set(own_rows)
    out = [[style(BOLD, colors.white)] * n_cols]
    out += [[own if r in own_set else body] * n_cols for r in range(1, n_rows)]
    for r, c in bad_cells:  # each row is a list of its own
        out[r][c] = style(BOLD if r in own_set else FONT, BAD_TEXT)
    return out


# Cells that may hold a long text (a point's label: "Z, 10 Hz, curvilinear tangential,
# angular-rate sensitivity") are wrapped where the text is wider than its column, as a
# Paragraph of the report's "cell" style broken at spaces, and their row grows to fit;
# every other cell stays the single-line string FastTable draws fast.


@functools.lru_cache(maxsize=4096)
def _paragraph_style(font: str, colour: object) -> ParagraphStyle:
    return ParagraphStyle(f"cell-{font}-{colour}", parent=S["cell"], fontName=font,
                          textColor=colour)  # fmt: skip


def width_needed(text: str, font: str = FONT) -> float:
    """The column width a single-line cell ``text`` needs: its left padding and, on its
    right, at least :data:`RIGHT_GAP` before the column's edge."""
    return stringWidth(text, font, CELL_SIZE) + H_PADDING + RIGHT_GAP


@functools.lru_cache(maxsize=8192)
def _fits(text: str, font: str, width: float) -> bool:
    return width_needed(text, font) <= width


@functools.lru_cache(maxsize=8192)
def _paragraph_height(text: str, font: str, width: float) -> float:
    return float(Paragraph(escape(text), _paragraph_style(font, "black")).wrap(
        width - 2 * H_PADDING, 1e6)[1])  # fmt: skip


def cell_height(text: str, width: float, font: str = FONT) -> float:
    """The height of the row a cell ``text`` needs in a column ``width`` wide: one line
    (:data:`ROW_HEIGHT`), or its wrapped paragraph's lines with the paddings."""
    if _fits(text, font, width):
        return ROW_HEIGHT
    return max(ROW_HEIGHT, _paragraph_height(text, font, width) + 2 * V_PADDING)


def wrapped_cells(
    rows: list[list[str]], widths: Sequence[float], columns: Sequence[int],
    styles: list[list[CellStyle]],
) -> tuple[list[list[Any]], list[float]]:  # fmt: skip
    """``rows`` with each cell of ``columns`` that is wider than its column made a
    Paragraph (in the cell's font and colour: the header's bold white, the reader's own
    rows bold), and the row heights: :data:`ROW_HEIGHT`, or what a wrapped cell needs."""
    out: list[list[Any]] = rows
    heights = [ROW_HEIGHT] * len(rows)
    for r, row in enumerate(rows):
        for c in columns:
            text, style = row[c], styles[r][c]
            if not isinstance(text, str) or _fits(text, style.fontname, widths[c]):
                continue
            if out is rows:
                out = [list(x) for x in rows]
            out[r][c] = Paragraph(escape(text), _paragraph_style(style.fontname, style.color))
            heights[r] = max(heights[r], cell_height(text, widths[c], style.fontname))
    return out, heights


class LabelRows:
    """The height wrapped labels add to rows of a listing that prints a point's label on
    the point's first row and again on the first row of each part (page): ``points`` the
    listing's point per row, from row ``offset``; ``label_height(point)`` the height of the
    row that prints the point's label (:func:`cell_height`).  :meth:`added` is what they
    add to rows ``start:stop`` over :data:`ROW_HEIGHT` each, in O(log n) per call, so that
    a listing of 10⁶ rows is split into pages in linear time."""

    def __init__(
        self, points: np.ndarray, offset: int, label_height: Callable[[int], float]
    ) -> None:
        self.points, self.offset = points, offset
        self.extra = {int(p): label_height(int(p)) - ROW_HEIGHT for p in np.unique(points)}
        self.wraps = any(v > 0 for v in self.extra.values())
        self.rows, self.cum = np.zeros(0, dtype=np.int64), np.zeros(1)
        if self.wraps:
            starts = np.flatnonzero(points[1:] != points[:-1]) + 1  # where a point begins
            extra = np.array([self.extra[int(p)] for p in points[starts]], dtype=float)
            self.rows, self.cum = starts + offset, np.concatenate(([0.0], np.cumsum(extra)))

    def added(self, start: int, stop: int) -> float:
        if not self.wraps or stop <= start:
            return 0.0
        first = self.extra[int(self.points[start - self.offset])]
        lo, hi = np.searchsorted(self.rows, [start + 1, stop])
        return first + float(self.cum[hi] - self.cum[lo])
