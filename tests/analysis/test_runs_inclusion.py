"""A run says who made the assigned value: ``in_assigned_value`` on every score, the
excluded codes on the assigned value, the reference laboratory's own k in U(x_pt); the
same in the pages, the downloads and the PDF, and the same as the offline tool."""

import csv
import json
import math
from io import StringIO

import pytest
from django.contrib.auth import get_user_model
from django.core.management import call_command
from django.test import Client

from analysis.models import AssignedValue, Score
from analysis.reports.assemble import report_data
from analysis.reports.render import render_report
from analysis.services import analysis_run_start
from common.sizes import counted
from labs.models import Participant, Result
from tests.analysis.reports.conftest import pdf_text

pytestmark = pytest.mark.django_db(transaction=True)


def accepted(demo):
    return Result.objects.filter(
        submission__participant__comparison=demo, submission__status="accepted"
    ).select_related("submission__participant", "measurement_point__device")


def started(demo):
    run = analysis_run_start(comparison=demo, user=None)  # eager: runs inline
    run.refresh_from_db()
    assert run.status == "succeeded", run.error
    return run


def test_weighted_mean_run_marks_the_excluded_result_everywhere(demo, tmp_path):
    demo.assigned_value_method = "weighted_mean"
    demo.save(update_fields=["assigned_value_method"])
    outlier = accepted(demo).order_by("measurement_point_id", "submission__participant__code")[3]
    Result.objects.filter(pk=outlier.pk).update(value=outlier.value + 60.0)
    run = started(demo)
    code = outlier.submission.participant.code
    av = AssignedValue.objects.get(run=run, measurement_point=outlier.measurement_point)
    assert av.method == "largest_consistent_subset"
    assert code in av.diagnostics["excluded"] and av.diagnostics["n_excluded"] == len(
        av.diagnostics["excluded"]
    )
    assert av.coverage_factor == 2.0 and av.expanded_uncertainty == 2 * av.standard_uncertainty
    at_point = Score.objects.filter(run=run, result__measurement_point=outlier.measurement_point)
    flags = {s.result.submission.participant.code: s for s in at_point.select_related(
        "result__submission__participant")}  # fmt: skip
    assert flags[code].in_assigned_value is False and flags[code].correlation_applied is False
    inside = [c for c, s in flags.items() if c not in av.diagnostics["excluded"]]
    assert inside and all(flags[c].in_assigned_value is True for c in inside)
    assert all(flags[c].correlation_applied for c in inside)
    assert Score.objects.filter(run=run, in_assigned_value__isnull=True).count() == 0

    # the offline tool on the exported table says the same of every result
    export = tmp_path / "demo.csv"
    call_command("export_results", demo.code, "--output", str(export), stderr=StringIO())
    out = StringIO()
    call_command("pt_compare", str(export), "--format", "json", stdout=out)
    offline = {
        (s["lab"], s["device"], s["axis"], s["frequency_hz"], s["bench"], s["direction"]): s
        for s in json.loads(out.getvalue())["scores"]
    }
    stored = Score.objects.filter(run=run).select_related(
        "result__measurement_point__device", "result__submission__participant"
    )
    for s in stored:
        p = s.result.measurement_point
        key = (s.result.submission.participant.code, p.device.name, p.axis, p.frequency_hz,
               p.bench, p.direction)  # fmt: skip
        assert s.in_assigned_value == offline[key]["in_assigned_value"], key
        assert s.en == pytest.approx(offline[key]["en"], rel=1e-12, abs=1e-15)

    client = Client()
    client.force_login(get_user_model().objects.get(username="coordinator"))
    base = f"/coordinator/{demo.code}/"
    page = client.get(base + "results/")
    assert page.status_code == 200
    html = page.content.decode()
    assert f"<code>{code}</code>" in html and "U(x_pt)" in html
    scores = client.get(base + "scores/", {"lab": code})
    assert scores.status_code == 200 and 'title="not in the assigned value">○' in (
        scores.content.decode()
    )
    download = client.get(base + "scores.csv", {"lab": code})
    assert download.status_code == 200
    rows = list(csv.DictReader(StringIO(download.content.decode("utf-8-sig"))))
    by_point = {(r["device"], r["axis"], float(r["frequency_hz"]), r["bench"], r["direction"]):
                r for r in rows}  # fmt: skip
    p = outlier.measurement_point
    mine = by_point[(p.device.name, p.axis, p.frequency_hz, p.bench, p.direction)]
    assert mine["in_assigned_value"] == "FALSE", mine
    assert {r["in_assigned_value"] for r in rows} == {"TRUE", "FALSE"}

    data = report_data(run=run)
    assert any(a.excluded and code in a.excluded for a in data.assigned)
    text = " ".join(pdf_text(render_report(data))).replace("\n", " ")
    assert "Results left out of the largest consistent subset" in text
    assert f"{code} ○" in text and "●" in text


def test_reference_laboratory_u_is_its_reported_u_with_its_own_k(demo):
    n_points = (
        demo.devices.count() and accepted(demo).values("measurement_point").distinct().count()
    )
    ref = next(
        p
        for p in Participant.objects.filter(comparison=demo).order_by("code")
        if accepted(demo).filter(submission__participant=p).count() == n_points
    )  # a participant with a result at every point (codes are random)
    Participant.objects.filter(pk=ref.pk).update(is_reference=True)
    mine = accepted(demo).filter(submission__participant=ref)
    assert mine.exists()
    mine.update(coverage_factor=2.4)
    demo.assigned_value_method = "reference"
    demo.save(update_fields=["assigned_value_method"])
    run = started(demo)
    values = AssignedValue.objects.filter(run=run)
    assert {a.coverage_factor for a in values} == {2.4}
    pilot = {r.measurement_point_id: r for r in mine}
    for a in values:
        assert a.expanded_uncertainty == pytest.approx(
            pilot[a.measurement_point_id].expanded_uncertainty, rel=1e-12
        )
    other = (
        Score.objects.filter(run=run).exclude(result__submission__participant=ref)
        .select_related("result").first()
    )  # fmt: skip
    assert other is not None
    r, big_u_ref = other.result, pilot[other.result.measurement_point_id].expanded_uncertainty
    x_ref = pilot[r.measurement_point_id].value
    assert other.en == pytest.approx(
        (r.value - x_ref) / math.hypot(r.expanded_uncertainty, big_u_ref), rel=1e-12
    )
    assert other.in_assigned_value is False
    own = Score.objects.get(run=run, result=mine.first())
    assert own.in_assigned_value is True and own.correlation_failed is True


def test_points_beyond_the_exact_budget_are_flagged_on_page_csv_json_and_report(
    demo, monkeypatch, tmp_path
):
    """With the exact search's budget lowered below the demo's 11 results per point, every
    inconsistent point gets the sequential approximation: it must say so everywhere."""
    from analysis.core import assigned

    monkeypatch.setattr(assigned, "EXHAUSTIVE_MAX", 4)
    monkeypatch.setattr(assigned, "EXACT_MAX", 4)
    demo.assigned_value_method = "weighted_mean"
    demo.save(update_fields=["assigned_value_method"])
    outlier = accepted(demo).order_by("measurement_point_id", "submission__participant__code")[3]
    Result.objects.filter(pk=outlier.pk).update(value=outlier.value + 60.0)
    run = started(demo)
    approximate = AssignedValue.objects.filter(run=run, diagnostics__exhaustive=False)
    assert approximate.filter(measurement_point=outlier.measurement_point).exists()
    assert (
        not AssignedValue.objects.filter(run=run, diagnostics__exhaustive=True)
        .exclude(method="weighted_mean")
        .exists()
    )  # every inconsistent point is approximate here
    n = approximate.count()

    client = Client()
    client.force_login(get_user_model().objects.get(username="coordinator"))
    html = client.get(f"/coordinator/{demo.code}/results/").content.decode()
    assert f"{n} measurement point{'s' if n > 1 else ''} " in html
    assert 'id="approximate-subsets"' in html and ">approximate</span>" in html

    text = " ".join(pdf_text(render_report(report_data(run=run)))).replace("\n", " ")
    assert f"{counted(n, 'point')} had too many results for the exact" in text

    export = tmp_path / "demo.csv"
    call_command("export_results", demo.code, "--output", str(export), stderr=StringIO())
    out, err = StringIO(), StringIO()
    call_command("pt_compare", str(export), "--format", "json", stdout=out, stderr=err)
    doc = json.loads(out.getvalue())
    assert sum(a.get("exhaustive") is False for a in doc["assigned_values"]) == n
    have = "has" if n == 1 else "have"
    assert f"warning: {counted(n, 'measurement point')} {have} too many results" in err.getvalue()
    out = StringIO()
    call_command("pt_compare", str(export), "--format", "csv", stdout=out, stderr=StringIO())
    rows = list(csv.DictReader(StringIO(out.getvalue().split("\n\n")[0])))
    assert {r["exhaustive"] for r in rows} == {"FALSE", "TRUE"}
    out = StringIO()
    call_command("pt_compare", str(export), stdout=out, stderr=StringIO())
    assert f"Warning: {counted(n, 'measurement point')} {have} too many" in out.getvalue()
