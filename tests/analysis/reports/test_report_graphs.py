"""The report's score graphs (docs/domain.md §9): the sorted En and z bars of the chart
points and the participant's own scores over its points, each with its caption.  No
database: a hand-made report; the order and colours are checked against numpy and the
limits by hand."""

import dataclasses

import numpy as np

from analysis.reports import charts, figures
from analysis.reports.data import ReportData, ScoreRow
from analysis.reports.render import register_fonts, render_report
from tests.analysis.reports.conftest import pdftotext
from tests.analysis.reports.test_visual import small_report

LABS = ("L11", "L22", "L33", "L44", "L55")
EN = (0.4, -1.7, 2.6, -0.1, 0.9)
Z = (2.5, -3.4, 0.2, None, -1.1)  # L44 has no z at this point (not scored)


def scored() -> ReportData:
    """Five labs at point 0 with known En and z; L22 (the reader) also at point 1."""
    base = small_report()
    scores = (
        *(ScoreRow(0, lab, 0.0, 0.0, en, 0.0, z, "z", "action" if abs(en) > 1 else "satisfactory",
                   "" if z is None else "satisfactory", False)
          for lab, en, z in zip(LABS, EN, Z, strict=True)),
        ScoreRow(1, "L22", 0.0, 0.0, 4.2, 0.0, 7.0, "z", "action", "action", False),
    )  # fmt: skip
    results = tuple(dataclasses.replace(base.results[0], lab=s.lab, point=s.point) for s in scores)
    return dataclasses.replace(base, participants=LABS, results=results, scores=scores,
                               chart_points=(0,))  # fmt: skip


def test_sorted_bars_are_every_lab_in_ascending_order_with_the_readers_bar_marked():
    data = scored()
    en = figures._sorted_chart(data, 0, "en")
    z = figures._sorted_chart(data, 0, "z")
    assert en is not None and z is not None
    order = np.argsort(EN)
    assert list(en.index) == [LABS[i] for i in order]
    assert en.values == tuple(np.asarray(EN)[order])
    with_z = [(v, lab) for lab, v in zip(LABS, Z, strict=True) if v is not None]
    assert list(z.index) == [lab for _, lab in sorted(with_z)]  # L44 left out
    # the reader's bar: L22 is the lowest En, the first bar, reaching down to -1.7
    mark = en.overlay("L22")
    assert mark is not None and len(mark.rects) == 1
    x0, y0, x1, y1 = mark.rects[0]
    first, zero = en._px(0, 0.0), en._px(0, -1.7)
    assert x0 < first[0] < x1 and y0 == zero[1] and y1 == first[1]
    assert en.overlay("L99") is None


def test_bars_are_coloured_by_verdict():
    assert charts.verdict_colours(np.array([0.5, -1.2, 1.0]), (1.0,)) == [
        charts.LAB, charts.BAD, charts.LAB
    ]  # fmt: skip
    assert charts.verdict_colours(np.array([2.0, -2.5, 3.0, 0.1]), charts.Z_LIMITS) == [
        charts.LAB, charts.WARN, charts.BAD, charts.LAB
    ]  # fmt: skip


def test_overview_draws_the_readers_bars_clipped_at_the_frame():
    register_fonts()  # the caption is a paragraph in DejaVu Sans
    data = scored()
    flow = figures._overview(data)
    images = [f for f in flow if isinstance(f, figures.RasterImage)]
    assert len(images) == 2  # En and z
    en_marks = images[0].overlays
    rects = [r for m in en_marks for r in m.rects]
    assert len(rects) == 2  # L22's two points
    by_colour = {m.colour: m for m in en_marks}
    # -1.7 and 4.2 are both beyond |En| = 1: red; 4.2 is beyond the frame (±3): a dot
    assert set(by_colour) == {charts.BAD} and len(by_colour[charts.BAD].dots) == 1
    z_marks = {m.colour: m for m in images[1].overlays}
    assert set(z_marks) == {charts.BAD}  # z = -3.4 and 7.0: unsatisfactory
    assert len(z_marks[charts.BAD].dots) == 1  # 7.0 beyond ±5


def test_captions_say_how_to_read_each_graph(tmp_path):
    text = " ".join(pdftotext(render_report(scored()), tmp_path).split())
    assert "Your En (above) and z or z′ (below) at each of your points" in text
    assert "A bar ending in a dot goes beyond the frame (|En| > 3, |z| > 5)" in text
    assert "The same points' scores sorted from lowest to highest" in text
    assert "yours (L22) in pink" in text
    summary = dataclasses.replace(scored(), kind="summary", own_code=None)
    text = " ".join(pdftotext(render_report(summary), tmp_path).split())
    assert "The same points' scores sorted" in text and "at each of your points" not in text


def test_an_extreme_score_ends_at_the_frame_instead_of_failing_the_chart():
    """A score of 1e300 (a result with a tiny U far from x_pt is valid) would make the axis
    infinite: its bar stops at 1000 limits, the others are drawn as they are."""
    chart = charts.sorted_chart(("L1", "L2"), (0.5, 1e300), limits=(1.0,), title="t", ylabel="En")
    assert chart.values == (0.5, 1000.0)
    mark = chart.overlay("L2")
    assert mark is not None and all(np.isfinite(mark.rects[0]))
    assert chart.raster.width > 0
