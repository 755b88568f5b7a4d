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

from collections.abc import Sequence
from typing import Any

from reportlab.lib import colors
from reportlab.platypus import Table
from reportlab.platypus.tables import CellStyle

from analysis.reports.styles import BAD_TEXT, BOLD, FONT

MEMO_CELLS = 20_000


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
    s.fontname, s.fontsize, s.leading = font, 7.5, 7.5 * 1.2  # FONT's leading: size x 1.2
    s.valign, s.topPadding, s.bottomPadding, s.color = "TOP", 1.5, 1.5, colour
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
