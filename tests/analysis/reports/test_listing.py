"""The summary of a large round (reports at scale): every result is listed from
columns (:class:`ResultListing`), one page-sized table at a time, so the summary of a
national round costs memory and time in proportion to its rows."""

import dataclasses

import numpy as np
import pytest

from analysis.reports import assemble, render, sections
from analysis.reports.assemble import clear_run_contexts, report_data
from analysis.reports.data import ResultListing
from analysis.reports.render import render_report
from tests.analysis.reports.conftest import pdf_text, pdftotext
from tests.analysis.reports.test_render import table_rows
from tests.analysis.reports.test_visual import small_report


@pytest.fixture(autouse=True)
def fresh_contexts():
    clear_run_contexts()
    yield
    clear_run_contexts()


class Built:
    """The results tables built by :class:`sections.ListingTable`: rows of each."""

    def __init__(self, monkeypatch: pytest.MonkeyPatch) -> None:
        self.sizes: list[int] = []
        build = sections.ListingTable.table

        def table(flowable, start, stop):
            self.sizes.append(stop - start)
            return build(flowable, start, stop)

        monkeypatch.setattr(sections.ListingTable, "table", table)


@pytest.mark.django_db(transaction=True)
def test_large_round_summary_lists_every_result_as_the_full_table_does(monkeypatch, analysed):
    """The demo (891 results) as a large round: the summary's results table, built a page
    at a time from columns, prints exactly the rows of the one-table summary."""
    small = render_report(report_data(run=analysed))
    assert report_data(run=analysed).listing is None
    clear_run_contexts()
    monkeypatch.setattr(assemble, "FULL_TABLE_ROWS", 10)
    monkeypatch.setattr(sections, "FULL_TABLE_ROWS", 10)
    data = report_data(run=analysed)
    assert data.listing is not None and len(data.listing) == 891
    assert data.results == () and data.scores == ()
    assert [name for name, _, _ in data.listing.devices] == ["MEMS 1", "MEMS 2", "MEMS 3"]
    assert [stop - start for _, start, stop in data.listing.devices] == [297, 297, 297]
    built = Built(monkeypatch)
    large = render_report(data)
    codes = set(analysed.comparison.participants.values_list("code", flat=True))
    expected = table_rows("\n".join(pdf_text(small)), codes)
    printed = table_rows("\n".join(pdf_text(large)), codes)
    assert len(expected) == 891
    assert printed == expected
    # one table per page of rows: none larger than a page, each row built once
    assert sum(built.sizes) == 891
    assert max(built.sizes) <= 62
    assert len(built.sizes) <= 891 // 50 + 2 * 3


def listing_report(n_labs: int, n_points: int = 2):
    """``small_report`` as the summary of ``n_labs`` labs x ``n_points`` points, as columns."""
    base = small_report()
    points = tuple(
        dataclasses.replace(base.points[0], index=i, frequency_hz=5.0 * (i + 1))
        for i in range(n_points)
    )
    labs = tuple(f"L{i:05d}" for i in range(n_labs))
    n = n_labs * n_points
    point = np.repeat(np.arange(n_points, dtype=np.int32), n_labs)
    lab = np.tile(np.arange(n_labs, dtype=np.int32), n_points)
    value = 418.0 + (np.arange(n) % 7)
    en = (value - 418.0) / 4.2
    listing = ResultListing(
        labs=labs,
        flags=("satisfactory", "action"),
        devices=(("MEMS 1", 0, n),),
        point=point,
        lab=lab,
        value=value,
        expanded_uncertainty=np.full(n, 4.0),
        coverage_factor=np.full(n, 2.0),
        d=value - 418.0,
        en=en,
        zeta=en,
        z=np.full(n, np.nan),
        flag=(np.abs(en) > 1).astype(np.int8),
    )
    return dataclasses.replace(
        base,
        kind="summary",
        own_code=None,
        report_number="T-1-S-v1",
        participants=labs,
        points=points,
        assigned=tuple(dataclasses.replace(base.assigned[0], point=p.index) for p in points),
        listing=listing,
        chart_points=(),
    )


def test_listing_cost_is_linear_in_the_rows(monkeypatch, tmp_path):
    """Each row is formatted once (plus at most one table a page tried and dropped), and
    no table holds more than a page of rows, at 3,000 and at 12,000 results."""
    per_page = []
    for n_labs in (1500, 6000):
        data = listing_report(n_labs)
        built = Built(monkeypatch)
        pdf = render_report(data)
        # the pages counted by pypdf, their text read by poppler (270 pages: pypdf's text
        # takes 35 s, pdftotext's 1 s)
        pages = pdf_text(pdf)
        n = 2 * n_labs
        assert sum(built.sizes) == n
        assert max(built.sizes) <= 62
        assert len(built.sizes) <= len(pages)
        text = pdftotext(pdf, tmp_path)
        assert text.count("satisfactory") + text.count("action") >= n
        assert all(f"L{i:05d}" in text for i in (0, 1, n_labs // 2, n_labs - 1))
        per_page.append(n / len(pages))
    assert per_page[1] == pytest.approx(per_page[0], rel=0.05)


def test_listing_rows_print_every_result_with_its_label_on_each_page():
    data = listing_report(200, n_points=2)
    pages = pdf_text(render_report(data))
    body = "\n".join(pages).split("6 Results and scores", 1)[1].split("7 Compatibility", 1)[0]
    codes = set(data.listing.labs)
    rows = table_rows("6 Results and scores\n" + body + "7 Compatibility matrices", codes)
    assert len(rows) == 400
    assert [r[0] for r in rows] == [f"L{i:05d}" for i in range(200)] * 2
    first = rows[0]
    # U 4 to two significant digits, the value and D to its last digit
    assert first[1:] == ["418.0", "4.0", "2", "0.0", "0.00", "0.00", "–", "satisfactory"]
    # row 6 of each point: value 418 + 6 → En 1.43 > 1, flag "action"
    assert rows[6][1] == "424.0" and rows[6][4] == "+6.0"
    assert rows[6][5] == "1.43" and rows[6][8] == "action"
    # the point's label at its first row and again at the top of each later page
    label = data.points[0].label
    result_pages = [p for p in pages if "L00" in p]
    assert len(result_pages) >= 7
    assert all(label in p or data.points[1].label in p for p in result_pages)


class HeldCanvas(render.NumberedCanvas):
    """The canvas as it was: every page's state held as is, reportlab compresses at save."""

    def showPage(self):
        self._pages.append(dict(self.__dict__))
        self._startPage()

    def save(self):
        total = len(self._pages)
        for state in self._pages:
            self.__dict__.update(state)
            self._draw_footer(total)
            render.Canvas.showPage(self)
        render.Canvas.save(self)


def test_compressed_held_pages_give_the_same_bytes(monkeypatch):
    """Holding pages compressed (and compressing each page's stream when it is written)
    changes no byte of the PDF, small report or a 4-page results listing."""
    reports = (small_report("Comments."), listing_report(120))
    mine = [render.render_report(d) for d in reports]
    monkeypatch.setattr(render, "NumberedCanvas", HeldCanvas)
    assert [render.render_report(d) for d in reports] == mine
    assert len(pdf_text(mine[1])) > 4
