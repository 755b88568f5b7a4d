"""The first page rasterised with poppler's pdftoppm: right size, not blank. No database:
the renderer is pure, so a small hand-made report is enough."""

import dataclasses
import functools
import shutil
import subprocess
from datetime import UTC, datetime
from pathlib import Path

import pytest
from PIL import Image

from analysis.reports.data import (
    AssignedRow,
    DeviceInfo,
    MatrixData,
    PointInfo,
    ReportData,
    ResultRow,
    ScoreRow,
)
from analysis.reports.render import render_report

LABS = ("L11", "L22", "L33")


def small_report(comments: str = "") -> ReportData:
    points = tuple(
        PointInfo(i, "MEMS 1", "X", f, "linear", "vertical", 10.0, "D/(m/s²)")
        for i, f in enumerate((5.0, 10.0))
    )
    results = tuple(
        ResultRow(p.index, lab, 418 + n + p.index, 4.0, 2.0)
        for p in points
        for n, lab in enumerate(LABS)
    )
    scores = tuple(
        ScoreRow(
            r.point,
            r.lab,
            r.value - 418,
            0.1,
            (r.value - 418) / 4.2,
            0.5,
            None,
            "z′",
            "satisfactory",
            "",
            False,
        )
        for r in results
    )
    return ReportData(
        kind="participant",
        provider="Test Provider σ ζ Δ ± ²",
        comparison_code="T-1",
        comparison_title="Small test",
        report_number="T-1-L22-v1",
        issue_date=datetime(2024, 5, 17, 12, 0, tzinfo=UTC),
        status="final",
        authorised_by="A. Coordinator",
        coordinators=("A. Coordinator",),
        software_version="0.1.0",
        protocol_title="Linear bench",
        protocol_description="",
        bench_descriptions=("tilt plate",),
        frequencies_hz=(5.0, 10.0),
        amplitudes=(),
        devices=(DeviceInfo("MEMS 1", "LSM6DSR", "S1", "D/(m/s²)", 418, 1, True, "Rectangular"),),
        participants=LABS,
        reference_code=None,
        points=points,
        results=results,
        assigned=tuple(AssignedRow(p.index, 418.0, 1.2, "Nominal", None) for p in points),
        scores=scores,
        matrices=(
            MatrixData(
                "bench",
                "device MEMS 1",
                ("a", "b"),
                (418.0, 419.0),
                (4.0, 4.0),
                ((0.0, 0.18), (0.18, 0.0)),
                0,
            ),
        ),
        comments=comments,
        own_code="L22",
        chart_points=(0,),
    )


@functools.cache
def small_round() -> ReportData:
    """``small_report()`` with its round's figures given (``stats``, as a large round's
    participant report carries them): the reports replaced from it that change none of its
    rows share that one round, so its charts are drawn once for all of them, as for the
    reports of one run, not once per render (the same bytes: ``stats`` is only read as
    ``ReportData.round``)."""
    data = small_report()
    return dataclasses.replace(data, stats=data.round)


def test_small_report_is_deterministic_and_prints_comments():
    data = small_report("Two labs reviewed their set-up.")
    assert render_report(data) == render_report(data)
    assert render_report(data) != render_report(small_report())


@pytest.mark.skipif(shutil.which("pdftoppm") is None, reason="poppler-utils not installed")
def test_first_page_rasterises_to_a4_and_is_not_blank(tmp_path: Path):
    pdf = tmp_path / "report.pdf"
    pdf.write_bytes(render_report(small_report()))
    subprocess.run(
        [
            "pdftoppm",
            "-r",
            "50",
            "-f",
            "1",
            "-l",
            "1",
            "-png",
            "-singlefile",
            str(pdf),
            str(tmp_path / "page"),
        ],
        check=True,
    )
    image = Image.open(tmp_path / "page.png").convert("L")
    width, height = image.size  # A4 (210 × 297 mm) at 50 dpi: 413.4 × 584.6 px
    assert abs(width - 413) <= 1 and abs(height - 585) <= 1
    dark = sum(image.histogram()[:200])  # pixels darker than 200 of 255
    assert dark > 0.005 * image.size[0] * image.size[1]


def test_own_rows_are_bold_on_a_background():
    from analysis.reports import sections
    from analysis.reports.styles import BOLD, OWN_BACKGROUND

    data = small_report()
    scores = {(s.point, s.lab): s for s in data.scores}
    table = sections._result_table(data, data.results, scores)
    own_rows = {i for i, row in enumerate(table._cellvalues) if row[1] == "L22"}
    assert own_rows == {2, 5}
    backgrounds = {cmd[1][1] for cmd in table._bkgrndcmds if cmd[3] == OWN_BACKGROUND}
    assert backgrounds == own_rows
    assert all(table._cellStyles[r][0].fontname == BOLD for r in own_rows)
    assert table._cellStyles[1][0].fontname != BOLD
