"""The consistency tests in the service: a run stores them per point (the offline tool's
numbers, chunked or not), the results pages and the run page show the verdicts (labs by
code), the CSV download has them at full precision, the summary report lists them."""

import csv
import io
import json
import math
from io import StringIO

import pytest
from django.contrib.auth import get_user_model
from django.core.management import call_command

from analysis.models import AssignedValue
from analysis.reports.assemble import clear_run_contexts, report_data
from analysis.reports.render import render_report
from analysis.selectors import accepted_results
from analysis.services import analysis_run_start
from common.points import POINT_FIELDS
from labs.models import Laboratory, Result
from proficiency.models import Comparison, ComparisonStatus
from tests.analysis.reports.conftest import pdf_text

pytestmark = pytest.mark.django_db(transaction=True)

CODE = "IMU-2024-DEMO"
C = f"/coordinator/{CODE}/"


@pytest.fixture
def demo(demo):
    """The demo round (tests/analysis/conftest.py) with repeat data added."""
    _add_repeats(demo)
    return demo


def _point_results(comparison, n):
    """The accepted results of the ``n``-th measurement point, by participant code."""
    point = comparison.measurement_points.order_by("pk")[n]
    found = accepted_results(comparison).filter(measurement_point=point)
    return point, sorted(found.select_related("submission__participant"),
                         key=lambda r: r.submission.participant.code)  # fmt: skip


def _add_repeats(comparison):
    """Point 0: every lab n = 5, s = 0.3 (+ 0.01 per lab), but the fourth lab s = 3: a
    Cochran and Mandel k outlier.  Point 1: n = 3 and 4 alternating (unequal repeats)."""
    _, results = _point_results(comparison, 0)
    for j, r in enumerate(results):
        Result.objects.filter(pk=r.pk).update(repeat_sd=3.0 if j == 3 else 0.3 + 0.01 * j,
                                              n_repeats=5)  # fmt: skip
    _, results = _point_results(comparison, 1)
    for j, r in enumerate(results):
        Result.objects.filter(pk=r.pk).update(repeat_sd=0.3, n_repeats=3 + j % 2)


def run_with(comparison, settings, chunk_results=10**9):
    settings.ANALYSIS_CHUNK_RESULTS = chunk_results
    run = analysis_run_start(comparison=comparison, user=None)  # eager: runs on commit
    run.refresh_from_db()
    assert run.status == "succeeded", run.error
    return run


def stored(run):
    return {a.measurement_point_id: a.consistency for a in AssignedValue.objects.filter(run=run)}


def close(a, b, path="") -> None:
    """Equal records, floats to 1e-12 (the service sums the results in another order)."""
    if isinstance(a, float) and isinstance(b, float):
        assert math.isclose(a, b, rel_tol=1e-12, abs_tol=1e-14), path
    elif isinstance(a, dict):
        assert a.keys() == b.keys(), path
        for k in a:
            close(a[k], b[k], f"{path}.{k}")
    elif isinstance(a, list):
        assert len(a) == len(b), path
        for i, (x, y) in enumerate(zip(a, b, strict=True)):
            close(x, y, f"{path}[{i}]")
    else:
        assert a == b, path


def test_a_run_stores_the_offline_tools_consistency_records(demo, settings, tmp_path):
    run = run_with(demo, settings)
    records = stored(run)
    point, results = _point_results(demo, 0)
    noisy = results[3].submission.participant.code
    rec = records[point.pk]
    assert rec["p"] == len(results) == rec["p_repeats"] and rec["n_repeats"] == 5
    assert (rec["cochran"]["verdict"], rec["cochran"]["labs"]) == ("outlier", [noisy])
    k = {lab["lab"]: lab for lab in rec["labs"]}
    assert k[noisy]["k_flag"] == "outlier" and rec["signals"] is True
    variances = [(3.0 if j == 3 else 0.3 + 0.01 * j) ** 2 for j in range(len(results))]
    assert rec["cochran"]["statistic"] == pytest.approx(max(variances) / sum(variances), 1e-13)
    unequal = records[_point_results(demo, 1)[0].pk]
    assert unequal["cochran"]["reason"].startswith("unequal numbers of repeats (n from 3 to 4)")
    export = tmp_path / "demo.csv"
    call_command("export_results", demo.code, "--output", str(export), stderr=StringIO())
    assert export.read_text().splitlines()[0].endswith("dof,repeat_sd,n_repeats,note")
    out = StringIO()
    call_command("pt_compare", str(export), "--format", "json", stdout=out)
    offline = json.loads(out.getvalue())["consistency"]
    points = {p.key.measurand: p.pk for p in demo.measurement_points.select_related("device")}
    assert len(offline) == len(records) == 81
    for rec in offline:
        pid = points[tuple(rec[k] for k in POINT_FIELDS)]
        close({k: v for k, v in rec.items() if k not in POINT_FIELDS}, records[pid], str(pid))


def test_chunks_store_the_same_records(demo, settings):
    single = stored(run_with(demo, settings))
    chunked = stored(run_with(demo, settings, 100))
    assert single == chunked


def login(client, name):
    client.force_login(get_user_model().objects.get(username=name))


def test_pages_show_the_verdicts_by_code(client, demo, settings):
    run = run_with(demo, settings)
    login(client, "coordinator")
    _, results = _point_results(demo, 0)
    noisy = results[3].submission.participant.code
    page = client.get(C + "consistency/?signals=1")
    assert page.status_code == 200
    body = page.content.decode()
    assert f"largest variance {noisy}, C = " in body
    assert f"{noisy} outlier (k = " in body
    assert "Critical 5 % / 1 %" in body and "a test signals" in body
    assert not any(lab in body for lab in Laboratory.objects.values_list("name", flat=True))
    everything = client.get(C + "consistency/?page=2").content.decode()
    assert "not applicable: no repeat data (repeat_sd, n_repeats)" in everything
    run_page = client.get(f"{C}analysis/runs/{run.pk}/").content.decode()
    assert "Consistency (ISO 5725-2): a test signals a straggler or an outlier at" in run_page
    assert f"consistency/?run={run.pk}&amp;signals=1" in run_page
    assert 'href="/coordinator/IMU-2024-DEMO/consistency/"' in body  # the results tab


def test_csv_download_at_full_precision(client, demo, settings):
    run = run_with(demo, settings)
    login(client, "coordinator")
    response = client.get(C + "consistency.csv")
    assert response.status_code == 200
    assert f"{CODE}-consistency-run{run.pk}.csv" in response["Content-Disposition"]
    rows = list(csv.DictReader(io.StringIO(response.content.decode("utf-8-sig"))))
    point, _ = _point_results(demo, 0)
    rec = stored(run)[point.pk]
    cochran = next(r for r in rows if r["test"] == "cochran" and r["verdict"] == "outlier")
    assert float(cochran["statistic"]) == rec["cochran"]["statistic"]
    assert {r["test"] for r in rows} == {"grubbs_single", "grubbs_double", "cochran",
                                         "mandel_h", "mandel_k"}  # fmt: skip


def test_participants_see_the_page_after_publication_with_their_code(client, demo, settings):
    run_with(demo, settings)
    login(client, "lab03")
    url = f"/results/{CODE}/consistency/"
    assert client.get(url).status_code == 404  # not published yet
    Comparison.objects.filter(pk=demo.pk).update(status=ComparisonStatus.PUBLISHED)
    page = client.get(url + "?signals=1")
    assert page.status_code == 200
    assert b'class="own-row"' in page.content
    assert client.get(f"/results/{CODE}/consistency.csv").status_code == 200


def test_summary_report_lists_the_points_where_a_test_signals(demo, settings):
    run = run_with(demo, settings)
    clear_run_contexts()
    text = "\n".join(pdf_text(render_report(report_data(run=run))))
    _, results = _point_results(demo, 0)
    noisy = results[3].submission.participant.code
    section = text.split("8 Consistency of the results (ISO 5725-2)", 1)[1].split("9 Graphs")[0]
    n = AssignedValue.objects.filter(run=run, consistency__signals=True).count()
    flat = " ".join(section.split())
    assert f"A test signals a straggler or an outlier at {n} of 81 measurement points" in flat
    assert "Cochran at 79 points (no repeat data); Cochran at 1 point (unequal numbers" in flat
    assert "Mandel k at 1 point (unequal numbers of repeats)" in flat
    lines = section.splitlines()
    assert "Device Point Test Lab Statistic Critical 5 % / 1 % Verdict" in lines
    rec = stored(run)[_point_results(demo, 0)[0].pk]
    c, c5, c1 = (f"{rec['cochran'][k]:#.3g}" for k in ("statistic", "critical_5", "critical_1"))
    assert f"Cochran {noisy} {c} {c5} / {c1} outlier" in section
    assert any(f" Mandel k {noisy} " in line and line.endswith(" outlier") for line in lines)
