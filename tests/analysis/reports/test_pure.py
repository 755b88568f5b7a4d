"""Renderer properties that need no database: output independent of what the process
rendered before (shared chart caches), escaping, authorisation, large rounds, stability."""

import dataclasses

import pytest

from analysis.reports import charts, figures, sections
from analysis.reports.data import StabilityRow
from analysis.reports.render import render_report
from tests.analysis.reports.conftest import pdf_text
from tests.analysis.reports.test_visual import small_report


def flat(pdf: bytes) -> str:
    return " ".join("\n".join(pdf_text(pdf)).split())


def clear_caches() -> None:
    for cached in (charts.point_chart, charts.en_chart, charts.frequency_chart, figures._xobject):
        cached.cache_clear()


def test_bytes_do_not_depend_on_reports_rendered_before():
    mine = small_report("Comments.")
    theirs = dataclasses.replace(mine, own_code="L11", report_number="T-1-L11-v1")
    clear_caches()
    first = render_report(mine)
    other = render_report(theirs)
    assert render_report(mine) == first and other != first
    clear_caches()
    assert render_report(theirs) == other
    assert render_report(mine) == first


def test_own_result_is_drawn_in_pink_over_the_shared_chart():
    data = small_report()
    chart = charts.point_chart(
        ("L11", "L22"), (418.0, 420.0), (4.0, 2.0), x_pt=419.0, u_x_pt_expanded=1.0,
        title="t", unit="u",
    )  # fmt: skip
    mark = chart.overlay("L22")
    assert chart.overlay(None) is None and chart.overlay("nobody") is None
    assert mark is not None
    ((x, y),) = mark.dots
    assert (x, y) == pytest.approx(chart.to_px.transform((1, 420.0)))
    bottom, top = mark.lines[0][1], mark.lines[0][3]
    assert (bottom, top) == pytest.approx(
        (chart.to_px.transform((1, 418.0))[1], chart.to_px.transform((1, 422.0))[1])
    )
    from io import BytesIO

    from pypdf import PdfReader

    pages = PdfReader(BytesIO(render_report(data))).pages
    streams = b""
    for page in pages:
        contents = page.get_contents()
        assert contents is not None
        streams += contents.get_data()
    assert b".839216 .2 .517647 RG" in streams  # #d63384 strokes the overlay


def test_coordinator_text_is_escaped_not_interpreted():
    text = 'Check <b>this</b> & <font size="30">that</font>; 1 < 2 > 0.\nNext line.'
    data = dataclasses.replace(small_report(text), conclusions="Fine <i>overall</i> & done.")
    printed = flat(render_report(data))
    assert text.split("\n")[0] in printed and "Next line." in printed
    assert "Fine <i>overall</i> & done." in printed


def test_unauthorised_report_is_preliminary_and_says_so():
    data = dataclasses.replace(small_report(), authorised_by="", status="preliminary")
    first = " ".join(pdf_text(render_report(data))[0].split())
    assert "Authorised by not yet authorised" in first
    assert "Preliminary report, not yet authorised for issue" in first
    assert "Status Preliminary" in first


def test_large_round_participant_report_lists_own_rows_and_the_spread(monkeypatch):
    monkeypatch.setattr(sections, "FULL_TABLE_ROWS", 3)
    text = flat(render_report(small_report()))
    results = text.split("6 Results and scores", 1)[1].split("7 Compatibility", 1)[0]
    assert "the summary report lists every result by code" in results
    assert "L22" in results and "L11" not in results and "L33" not in results
    # spread per point: n = 3, min / median / max of 418+0+i, 418+1+i, 418+2+i
    assert "3 418.000 419.000 420.000 418.000" in results
    assert "3 419.000 420.000 421.000 418.000" in results


def test_stability_rows_are_printed_with_the_verdict():
    rows = (
        StabilityRow(0, 418.1, 418.3, 0.2, 0.156, 1.254, True, 0.0),
        StabilityRow(1, 418.0, 420.0, 2.0, 7.07, 1.254, False, 1.1547),
    )
    text = flat(render_report(dataclasses.replace(small_report(), stability_rows=rows)))
    assert "418.100 418.300 +0.200 0.16 1.3 yes 0" in text
    assert "418.000 420.000 +2.000 7.07 1.3 no 1.2" in text
