"""The demo's kits round IMU-2025-KITS (coordination/demo_kits.py: magnitudes, phases and
angular rates in two kits) as a metrologist reads it on the pages and in the reports: every
point names its kind by the registry's label (docs/domain.md §2), degrees are written ``°``,
right after the number (§3.1), charts never put two kinds on one axis, and the report's
tables hold their labels inside their columns (§9)."""

from __future__ import annotations

import html
import re
import statistics
from io import StringIO

import pytest
from django.contrib.auth import get_user_model
from django.core.management import call_command
from reportlab.lib.pagesizes import A4
from reportlab.pdfbase.pdfmetrics import stringWidth
from reportlab.platypus import Paragraph, Table

from analysis.graph_data import point_pairs, run_points
from analysis.models import AssignedValue, KitScore
from analysis.reports.assemble import clear_run_contexts, report_data
from analysis.reports.figures import youden_pair
from analysis.reports.render import MARGIN, render_report, story
from common import numbers
from coordination.demo_kits import KITS_ROUND_CODE as CODE
from coordination.demo_kits import LINEAR_LAB
from labs.models import Result
from proficiency.models import Comparison
from tests.analysis.reports.conftest import pdftotext

pytestmark = pytest.mark.django_db
RATE = "IMU 1, Z, 5 Hz, curvilinear tangential, angular-rate sensitivity"
ALPINE = "Alpine Vibration Metrology"  # Kit B, at all 18 points
RAW = re.compile(r"angular_rate|\bdeg\b")  # the kind's name, the unit as stored


@pytest.fixture
def kits(demo_kits_round):
    call_command("load_demo", password="demo-password-1", stdout=StringIO())
    clear_run_contexts()
    yield Comparison.objects.get(code=CODE)
    clear_run_contexts()


def visible(page: str) -> str:
    """The words a reader sees: no tags, scripts, attributes (form values keep names)."""
    body = re.sub(r"<(script|style)\b.*?</\1>", " ", page, flags=re.S)
    return " ".join(html.unescape(re.sub(r"<[^>]+>", " ", body)).split())


def get(client, url: str) -> str:
    answer = client.get(url)
    assert answer.status_code == 200, url
    return answer.content.decode()


def test_the_pages_name_the_kind_and_write_degrees_with_the_sign(client, kits):
    client.force_login(kits.coordinators.get())
    base = f"/coordinator/{CODE}/"
    scores = get(client, base + "scores/")
    # 6 laboratories and the curvilinear one at each of IMU 1's three angular-rate points
    assert scores.count("<td>tangential · angular-rate sensitivity</td>") == 21
    first = Result.objects.get(
        submission__participant__laboratory__name=ALPINE,
        measurement_point__device__name="IMU 1",
        measurement_point__quantity="angular_rate", measurement_point__frequency_hz=5,
    )  # fmt: skip
    value = numbers.round_to_uncertainty(first.value, first.expanded_uncertainty)
    assert first.unit == "D/(deg/s)"  # stored as written
    assert f'{value} <span class="small text-body-secondary">D/(°/s)</span>' in scores
    phases = get(client, base + "scores/?quantity=phase")
    assert "<td>vertical · sensitivity phase</td>" in phases
    assert 'U <span class="fw-normal text-nowrap d-block small">(°)</span>' in phases
    results = get(client, base + "results/")
    phase = AssignedValue.objects.get(
        run__comparison=kits, measurement_point__device__name="IMU 1",
        measurement_point__quantity="phase", measurement_point__frequency_hz=5,
    )  # fmt: skip
    x_pt = numbers.round_to_uncertainty(phase.value, phase.expanded_uncertainty)
    assert f'<td class="num">{x_pt}<span class="small text-body-secondary">°</span>' in results
    kits_tab = get(client, base + "results/kits/")
    assert f"<td>{RATE}</td>" in kits_tab
    compatibility = get(client, base + "compatibility/")
    assert "device=IMU 1, axis=Z, angular-rate sensitivity" in visible(compatibility)
    for page in (scores, phases, results, kits_tab, compatibility):
        assert RAW.findall(visible(page)) == []


def test_the_charts_draw_one_kind_on_one_axis(client, kits):
    client.force_login(kits.coordinators.get())
    charts = visible(get(client, f"/coordinator/{CODE}/charts/"))
    # the first point's results and density: its own quantity and unit, not the device's
    # sensitivity in D/(m/s²)
    title = "IMU 1 · Z · 5 Hz · curvilinear tangential · angular-rate sensitivity"
    assert f"Angular-rate sensitivity (D/(°/s)) {title} x_pt ± U(x_pt)" in charts
    assert re.search(
        rf"Angular-rate sensitivity \(D/\(°/s\)\) [\d. ]+ Density Kernel density · {title}", charts
    )
    for axis, kind in (("Angular-rate sensitivity (D/(°/s))", "angular-rate sensitivity"),
                       ("Sensitivity phase (°)", "sensitivity phase")):  # fmt: skip
        assert f"{axis} IMU 1, {kind}: mean of all labs per frequency" in charts
    assert "Sensitivity (D/(m/s²)) IMU 1: mean of all labs per frequency" in charts
    points = {p.pk: p for p in run_points(kits.analysis_runs.get())}
    pairs = [tuple(map(int, key.split("-"))) for key, _ in point_pairs(list(points.values()))]
    assert len(pairs) == 9  # each of IMU 1's points against IMU 2's, none across kinds
    assert all(points[a].quantity == points[b].quantity for a, b in pairs)
    client.force_login(get_user_model().objects.get(username="curvilinear-lab"))
    grid = get(client, f"/lab/comparisons/{CODE}/results/")
    assert (
        ' scope="rowgroup">IMU 1 · curvilinear bench, tangential · angular-rate '
        'sensitivity <span class="fw-normal text-body-secondary small">· D/(°/s)</span></th>'
    ) in grid
    assert RAW.findall(visible(grid)) == []


def test_the_report_names_the_kind_writes_degrees_and_keeps_its_cells(kits, tmp_path):
    run = kits.analysis_runs.get()
    data = report_data(run=run)
    text = pdftotext(render_report(data), tmp_path)
    assert RAW.findall(text) == []
    # the assigned values: each label wrapped in its column, line by line, with its unit
    wrapped = {
        "angular_rate": ["Z, 5 Hz, curvilinear", "tangential, angular-rate",
                         "sensitivity (D/(°/s))"],
        "phase": ["Z, 5 Hz, linear vertical,", "sensitivity phase (°)"],
    }  # fmt: skip
    for kind, lines in wrapped.items():
        a = AssignedValue.objects.get(
            run=run, measurement_point__device__name="IMU 1",
            measurement_point__quantity=kind, measurement_point__frequency_hz=5,
        )  # fmt: skip
        x_pt, u = (numbers.round_to_uncertainty(a.value, a.standard_uncertainty),
                   numbers.uncertainty(a.standard_uncertainty))  # fmt: skip
        first, *rest = map(re.escape, lines)
        row = rf"\n IMU 1 +{first} +{re.escape(x_pt)} +{re.escape(u)} .*"
        assert re.search(row + "".join(rf"\n +{line}" for line in rest) + r"\n", text), kind
    # the largest u_link per unit, the angular rate's with ° (stored D/(deg/s)), the phase's
    # in degrees: of a Kit B laboratory at all 18 points (phases linked too), and named too
    # for the linear bench's units, in the stored units' order
    (alpine, at_alpine), (linear, at_linear) = (
        largest_u_link(run, n) for n in (ALPINE, LINEAR_LAB)
    )

    def per_unit(largest: dict[str, float]) -> str:
        shown = {"D/(deg/s)": " D/(°/s)", "D/(m/s^2)": " D/(m/s²)", "deg": "°"}
        return "; ".join(f"{numbers.uncertainty(largest[u])}{shown[u]}" for u in sorted(largest))

    assert set(at_alpine) == {"D/(deg/s)", "D/(m/s^2)", "deg"}
    assert set(at_linear) == {"D/(m/s^2)", "deg"}
    row = r"\n +{} +Kit {} +{} +0 +[\d.]+ +{}\n"
    assert re.search(row.format(alpine, "B", 18, re.escape(per_unit(at_alpine))), text)
    assert re.search(row.format(linear, "A", 12, re.escape(per_unit(at_linear))), text)
    for who in (None, kits.participants.get(code=alpine)):
        assert_cells_fit(story(report_data(run=run, participant=who)))


def test_the_reports_frequency_medians_are_one_kinds(kits):
    """Per device and kind, the median of every result at each frequency: a phase (−2°)
    pooled with its magnitude (418 D/(m/s²)) gave the magnitude's value."""
    data = report_data(run=kits.analysis_runs.get())
    charts = {(device, kind): (unit, dict((s[0], s[1:]) for s in series))
              for device, kind, unit, series in data.round.frequency}  # fmt: skip
    assert sorted(charts) == [(d, k) for d in ("IMU 1", "IMU 2")
                              for k in ("angular_rate", "magnitude", "phase")]  # fmt: skip
    unit, lines = charts["IMU 1", "phase"]
    scored = kits.analysis_runs.get().scores.filter(
        result__measurement_point__device__name="IMU 1",
        result__measurement_point__quantity="phase",
    ).values_list("result__measurement_point__frequency_hz", "result__value")  # fmt: skip
    assert unit == "deg" and list(lines) == ["linear vertical Z"]
    freqs, medians = lines["linear vertical Z"]
    expected = [statistics.median(v for at, v in scored if at == f) for f in freqs]
    assert freqs == (5.0, 10.0, 20.0) and list(medians) == expected
    assert all(m < 0 for m in medians)
    for participant in kits.participants.all():
        pair = youden_pair(report_data(run=kits.analysis_runs.get(), participant=participant))
        if pair is not None:
            a, b = (data.points[i] for i in pair)
            assert a.quantity == b.quantity


def largest_u_link(run, laboratory: str) -> tuple[str, dict[str, float]]:
    """A laboratory's code and its largest u_link per unit (as stored)."""
    code = run.comparison.participants.get(laboratory__name=laboratory).code
    largest: dict[str, float] = {}
    for k in KitScore.objects.filter(run=run, result__submission__participant__code=code
                                     ).select_related("result"):  # fmt: skip
        if k.u_link is not None:
            largest[k.result.unit] = max(largest.get(k.result.unit, 0.0), k.u_link)
    return code, largest


def assert_cells_fit(flow) -> None:
    """Every table of the story within the ruled width; every single-line cell within its
    column, its left padding and a gap of 1.5 pt on its right; every wrapped cell's longest
    word and lines within its paddings, and its row tall enough for its lines."""
    room = A4[0] - 2 * MARGIN
    seen = 0
    for t in tables(flow):
        assert t.wrap(room, 1e6)[0] <= room + 1e-6
        for r, row in enumerate(t._cellvalues):
            for c, cell in enumerate(row):
                style, width = t._cellStyles[r][c], t._colWidths[c]
                inner = width - style.leftPadding - style.rightPadding
                if isinstance(cell, str):  # may take its right padding but 1.5 pt
                    used = style.leftPadding + stringWidth(cell, style.fontname, style.fontsize)
                    assert used + 1.5 <= width, cell
                elif isinstance(cell, Paragraph):
                    wide, high = cell.wrap(inner, 1e6)
                    assert cell.minWidth() <= inner and wide <= inner, cell.text
                    assert t._argH[r] >= high + style.topPadding + style.bottomPadding
                seen += 1
    assert seen > 500


def tables(flow):
    for f in flow:
        if isinstance(f, Table):
            yield f
        elif hasattr(f, "_content"):  # KeepTogether
            yield from tables(f._content)
