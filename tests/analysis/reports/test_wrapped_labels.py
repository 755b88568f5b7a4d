"""A point's label wider than its column is wrapped in the report's tables (docs/domain.md
§9): the row grows to its lines, no cell runs into the next, and the large round's
listing, which splits itself into pages by its rows' heights, knows those heights."""

from __future__ import annotations

import dataclasses
import re

import pytest
from reportlab.platypus import Paragraph

from analysis.reports import sections
from analysis.reports.render import register_fonts, render_report
from analysis.reports.tables import ROW_HEIGHT, width_needed
from tests.analysis.reports.conftest import pdftotext
from tests.analysis.reports.test_listing import listing_report

RATE = {"bench": "curvilinear", "direction": "tangential", "quantity": "angular_rate",
        "unit": "D/(deg/s)", "amplitude_m_s2": None}  # fmt: skip


def rate_listing(n_labs: int, n_points: int):
    """The listing summary of ``test_listing`` at angular-rate points, whose labels
    (``X, 10 Hz, curvilinear tangential, angular-rate sensitivity (D/(°/s))``) take three
    lines of the results table's Point column."""
    data = listing_report(n_labs, n_points)
    points = tuple(dataclasses.replace(p, **RATE) for p in data.points)
    return dataclasses.replace(data, points=points)


def test_a_long_label_wraps_and_its_row_grows():
    register_fonts()
    label = "X, 10 Hz, curvilinear tangential, angular-rate sensitivity (D/(°/s))"
    rows = [["Point", "Lab"], [label, "L01"], ["", "L02"], ["X, 5 Hz, linear vertical", "L01"]]
    widths = sections.RESULT_WIDTHS[:2]
    assert width_needed(label) > widths[0]  # one line would run into the Lab column
    t = sections.table(rows, widths, wrap=(0,))
    cell = t._cellvalues[1][0]
    assert isinstance(cell, Paragraph) and cell.text == label.replace("&", "&amp;")
    _, height = cell.wrap(widths[0] - 12, 1e6)
    assert height == pytest.approx(3 * 7.5 * 1.3)  # three lines of the "cell" style
    assert t._argH == [ROW_HEIGHT, height + 3.0, ROW_HEIGHT, ROW_HEIGHT]
    assert [type(c) for c in (t._cellvalues[0][0], t._cellvalues[3][0])] == [str, str]


@pytest.mark.parametrize(("start", "stop"), [(0, 90), (0, 45), (3, 41), (29, 31), (44, 46)])
def test_the_listing_knows_the_height_of_its_wrapped_rows(start, stop):
    """What a ``ListingTable`` of rows ``start:stop`` says it needs is what its table takes:
    the label on the range's first row and on each point's first row, three lines each."""
    register_fonts()
    data = rate_listing(30, 3)
    listing = sections.ListingTable(data, data.listing, 0, len(data.listing))
    part = sections.ListingTable(data, data.listing, start, stop, listing.labels)
    built = listing.table(start, stop)
    assert part.wrap(500, 800)[1] == pytest.approx(built.wrap(500, 800)[1])
    labels = {start} | {r for r in range(start, stop) if r % 30 == 0}
    assert part.height > (stop - start + 1) * ROW_HEIGHT + len(labels) * 2 * 9.75 - 1e-6


def test_every_page_of_a_wrapped_listing_fits_its_frame(monkeypatch, tmp_path):
    """Each page-sized part a split makes is no taller than the room it was made for, and
    every result is printed once, the label at its point's start and atop each page."""
    data = rate_listing(200, 3)
    made: list[tuple[float, float]] = []
    split = sections.ListingTable.split

    def recorded(self, width, height):
        out = split(self, width, height)
        made.extend((out[0].wrap(width, height)[1], height) for _ in out[:1])
        return out

    monkeypatch.setattr(sections.ListingTable, "split", recorded)
    text = pdftotext(render_report(data), tmp_path)
    assert len(made) >= 5 and all(used <= room for used, room in made)
    results = text.split("6 Results and scores", 1)[1].split("7 Compatibility", 1)[0]
    assert sum(len(re.findall(rf"\bL{i:05d}\b", results)) for i in range(200)) == 600
    # the label's second line (of three) atop each page and at each point's start
    assert results.count("tangential, angular-rate\n") >= len(made)
