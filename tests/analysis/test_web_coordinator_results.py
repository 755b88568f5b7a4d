"""Coordinator analysis and results pages: run button, progress partial, failed runs,
results tables, downloads, publication and the participants' anonymised pages."""

import csv
import io

import openpyxl
import pytest
from django.contrib.auth import get_user_model

from analysis.models import AnalysisRun, Score
from analysis.services import analysis_run_start
from common.numbers import value_with_uncertainty
from labs.models import Laboratory, Participant
from proficiency.models import Comparison

CODE = "IMU-2024-DEMO"
C = f"/coordinator/{CODE}/"
LAB_NAMES = [b"Bench Calibration Laboratory", b"Alpine Vibration", b"Outlier Metrology"]


def login(client, name):
    client.force_login(get_user_model().objects.get(username=name))


@pytest.mark.django_db(transaction=True)
def test_run_button_runs_and_progress_shows_100(client, demo):
    login(client, "coordinator")
    response = client.post(C + "analysis/run/")
    assert response.status_code == 302
    run = AnalysisRun.objects.get(comparison=demo)
    assert response["Location"] == f"{C}analysis/runs/{run.pk}/"
    assert run.status == "succeeded" and run.progress == 100
    partial = client.get(f"{C}analysis/runs/{run.pk}/progress/")
    assert b"100 %" in partial.content and b"Succeeded" in partial.content
    assert b"hx-trigger" not in partial.content  # finished: polling stops
    page = client.get(response["Location"])
    assert b"current results" in page.content


def test_progress_partial_polls_while_running(client, run):
    login(client, "coordinator")
    AnalysisRun.objects.filter(pk=run.pk).update(status="running", progress=42, stage="scores")
    partial = client.get(f"{C}analysis/runs/{run.pk}/progress/").content
    assert b'hx-trigger="every 1s"' in partial
    assert b"42 %" in partial and b"Stage: scores" in partial


def test_failed_run_shows_error_and_previous_results(client, run, demo):
    login(client, "coordinator")
    failed = AnalysisRun.objects.create(comparison=demo, status="failed", error="No reference")
    page = client.get(f"{C}analysis/runs/{failed.pk}/").content
    assert b"No reference" in page
    assert f"previous successful run (run {run.pk}".encode() in page
    runs = client.get(C + "analysis/runs/").content
    assert b"current</span>" in runs and f"Run {failed.pk}".encode() in runs


def test_run_refused_while_open(client, demo):
    login(client, "coordinator")
    Comparison.objects.filter(pk=demo.pk).update(status="open")
    response = client.post(C + "analysis/run/", follow=True)
    assert b"close it before running the analysis" in response.content
    assert not AnalysisRun.objects.exists()


def test_results_page_assigned_values_and_bench_table(client, run):
    login(client, "coordinator")
    page = client.get(C + "results/").content.decode()
    assert "Assigned values" in page and "Nominal value with tolerance" in page
    assert "Linear vs curvilinear bench" in page and "all participants" in page
    assert "Publish results" in page
    a = run.assigned_values.first()
    x_text, u_text = value_with_uncertainty(a.value, a.expanded_uncertainty)
    assert f'<td class="num">{x_text}' in page and f'<td class="num">{u_text}' in page


def test_scores_table_filters_and_flags(client, run):
    login(client, "coordinator")
    outlier = Participant.objects.get(laboratory__name__startswith="Outlier").code
    page = client.get(C + "scores/", {"lab": outlier, "device": "MEMS 2"}).content.decode()
    assert "text-bg-danger" in page  # the outlier is flagged on MEMS 2
    assert "27 scores" in page
    score = Score.objects.filter(run=run, result__submission__participant__code=outlier).first()
    assert score is not None
    assert f"{score.en:.2f}" in client.get(C + "scores/", {"lab": outlier}).content.decode()
    page2 = client.get(C + "scores/", {"page": 2}).content.decode()
    assert "Page 2 of" in page2


def test_downloads_parse_back(client, run):
    login(client, "coordinator")
    csv_bytes = client.get(C + "scores.csv", {"device": "MEMS 1", "axis": "X"}).content
    rows = list(csv.DictReader(io.StringIO(csv_bytes.decode("utf-8-sig"))))
    assert len(rows) == Score.objects.filter(
        run=run, result__measurement_point__device__name="MEMS 1",
        result__measurement_point__axis="X").count()  # fmt: skip
    assert {"lab", "en", "flag", "assigned_value"} <= rows[0].keys()
    assert all(r["lab"].startswith("L") for r in rows)
    xlsx = client.get(C + "scores.xlsx").content
    sheet = openpyxl.load_workbook(io.BytesIO(xlsx)).active
    header = [c.value for c in next(sheet.iter_rows(max_row=1))]
    assert header[:2] == ["lab", "device"] and "zeta" in header
    assert sheet.max_row == Score.objects.filter(run=run).count() + 1


def test_charts_and_heat_maps_are_inline_svg(client, run):
    login(client, "coordinator")
    page = client.get(C + "charts/").content.decode()
    # point, En, z, sorted En, density, DoE, Youden, Mandel h and k, 3 devices
    assert page.count("<svg") == 12
    assert "Sensitivity (D/(m/s²))" in page and "Frequency (Hz)" in page
    heat = client.get(C + "compatibility/", {"factor": "frequency", "device": "MEMS 1"}).content
    assert heat.count(b"<svg") == 3  # MEMS 1 x 3 axes
    lab = client.get(C + "compatibility/", {"factor": "lab"}).content.decode()
    assert lab.count("<svg") == 1 and "L" in lab


def test_old_runs_stay_browsable(client, run, demo, django_capture_on_commit_callbacks):
    with django_capture_on_commit_callbacks(execute=True):
        newer = analysis_run_start(comparison=demo, user=None)
    login(client, "coordinator")
    page = client.get(C + "results/", {"run": run.pk}).content
    assert b"older run" in page
    assert client.get(C + "results/").content.count(b"current</span>") == 1
    assert newer.pk != run.pk


def test_publish_then_participant_sees_anonymised_pages(
    client, run, demo, django_capture_on_commit_callbacks
):
    lab = Laboratory.objects.get(name__startswith="Alpine")
    lab.name = "<script>alert(1)</script>"
    lab.save()
    own = Participant.objects.get(laboratory=lab).code
    member = lab.members.get(role="staff").user  # (its manager, lab03-manager, is the other)
    client.force_login(member)
    assert client.get(f"/results/{CODE}/").status_code == 404  # not published yet
    login(client, "coordinator")
    with django_capture_on_commit_callbacks(execute=True):  # the job's task, eager
        response = client.post(C + "publish/")
    assert response.status_code == 302
    job = demo.publications.get()
    assert response["Location"] == f"{C}publication/{job.pk}/" and job.status == "succeeded"
    demo.refresh_from_db()
    assert demo.status == "published"
    client.force_login(member)
    for page in ("", "scores/", "charts/", "compatibility/", "compatibility/?factor=lab"):
        response = client.get(f"/results/{CODE}/{page}")
        assert response.status_code == 200, page
        content = response.content
        assert f'<code class="text-reset">{own}</code>'.encode() in content
        assert b"<script>alert(1)</script>" not in content
        assert b"&lt;script&gt;" not in content  # not even escaped: no lab names at all
        for name in LAB_NAMES:
            assert name not in content, (page, name)
    scores = client.get(f"/results/{CODE}/scores/", {"lab": own}).content
    assert b'class="own-row"' in scores
    csv_bytes = client.get(f"/results/{CODE}/scores.csv").content
    assert b"Alpine" not in csv_bytes and own.encode() in csv_bytes
    assert client.get(C + "results/").status_code == 404  # still not a coordinator


def test_participant_of_another_comparison_gets_404(client, run, demo):
    Comparison.objects.filter(pk=demo.pk).update(status="published")
    outsider = get_user_model().objects.create_user("outsider", password="x")
    client.force_login(outsider)
    assert client.get(f"/results/{CODE}/").status_code == 404
    client.logout()
    assert client.get(f"/results/{CODE}/").status_code == 302


def test_publish_refused_without_run(client, demo):
    login(client, "coordinator")
    response = client.post(C + "publish/", follow=True)
    assert b"no successful analysis run" in response.content
    demo.refresh_from_db()
    assert demo.status == "closed"


def test_lab_comparison_page_links_to_published_results(client, demo):
    client.force_login(get_user_model().objects.get(username="lab05"))
    page = client.get("/lab/comparisons/IMU-2024-DEMO/")
    assert page.status_code == 200 and b"Published results" not in page.content
    Comparison.objects.filter(code=CODE).update(status="published")
    page = client.get("/lab/comparisons/IMU-2024-DEMO/")
    assert b'href="/results/IMU-2024-DEMO/"' in page.content
