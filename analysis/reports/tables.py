"""A platypus ``Table`` that writes its plain-text cells into one PDF text object.

reportlab's ``Table`` draws every string cell with ``Canvas.drawString``: a new text
object, its own ``BT … ET`` and font selection for each cell.  The results tables of a
large round have 10⁵ cells, and that overhead was most of the render time.  The cells
look the same (same font, colour and position as ``Table._drawCell`` computes for
left-aligned, top-aligned single-line strings); anything else falls back to ``Table``.
"""

from __future__ import annotations

from typing import Any

from reportlab.platypus import Table


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
        text._textOut(cellval)
