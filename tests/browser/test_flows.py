"""The three user journeys in real Chromium against pytest-django's live server.

1. A lab signs in, downloads the results template, uploads it with mistakes, reads the
   per-row errors, corrects the file and submits it.
2. The coordinator runs the analysis and watches the htmx progress bar reach 100 %, reads
   the results, charts and compatibility heat maps, is refused publication until an
   authoriser is named, names one and publishes.
3. A lab downloads its PDF report.

Every page is photographed into test-artifacts/browser/<test>/ (see conftest.py).
"""

from __future__ import annotations

import csv
import datetime as dt
import io
import re

import pytest
from django.utils import timezone
from playwright.sync_api import FilePayload, Page, expect
from pypdf import PdfReader

from analysis.models import AnalysisRun, Report, Score
from labs.models import Membership, Participant, Result, Submission
from labs.services import participant_add
from proficiency.models import Comparison, ComparisonStatus
from proficiency.services import comparison_apply_template
from tests.factories import ComparisonFactory, DeviceFactory, LaboratoryFactory, UserFactory

pytestmark = [pytest.mark.browser, pytest.mark.django_db(transaction=True)]

PASSWORD = "correct horse battery staple"  # tests.factories.UserFactory's
CODE = "IMU-BROWSER-01"
# docs/interfaces.md §1 without the coordinator-only `lab` column, in the spec's order, with the
# optional repeatability columns (repeat_sd, n_repeats) before the note.
TEMPLATE_HEADER = [
    "device", "axis", "frequency_hz", "bench", "direction", "amplitude_m_s2", "sensitivity",
    "unit", "expanded_uncertainty", "coverage_factor", "dof", "repeat_sd", "n_repeats", "note",
]  # fmt: skip
LINEAR_POINTS = {(axis, f) for axis in "XYZ" for f in (5.0, 10.0, 20.0)}  # protocols: linear


def _comparison(status: str, **fields: object) -> Comparison:
    """One MEMS on the linear bench: 3 axes x 5/10/20 Hz = 9 measurement points."""
    comparison = ComparisonFactory.create(code=CODE, status=status, protocol="linear", **fields)
    device = DeviceFactory.create(comparison=comparison, name="MEMS 1")
    comparison_apply_template(comparison=comparison, template_key="linear", devices=[device])
    return comparison


def _lab_member(comparison: Comparison, lab_name: str, username: str) -> Participant:
    lab = LaboratoryFactory.create(name=lab_name)
    user = UserFactory.create(username=username)
    Membership.objects.create(user=user, laboratory=lab, role=Membership.Role.STAFF)
    return participant_add(comparison=comparison, laboratory=lab)


def _sign_in(page: Page, base: str, username: str, shots, shot: str | None = None) -> None:
    response = page.goto(f"{base}/accounts/login/")
    assert response is not None
    # The pages run under the site's CSP, so a violation would show as a console error.
    assert "script-src 'self'" in response.headers["content-security-policy"]
    expect(page.get_by_role("heading", name="Sign in")).to_be_visible()
    page.get_by_label("Username").fill(username)
    page.get_by_label("Password").fill(PASSWORD)
    if shot:
        shots(page, shot, publish=True)
    page.get_by_role("button", name="Sign in").click()
    expect(page.get_by_role("button", name="Log out")).to_be_visible()


def _csv(rows: list[dict[str, str]]) -> bytes:
    out = io.StringIO()
    writer = csv.DictWriter(out, fieldnames=list(rows[0]), lineterminator="\n")
    writer.writeheader()
    writer.writerows(rows)
    return out.getvalue().encode()


def _upload(page: Page, name: str, data: bytes) -> None:
    page.locator("input[type=file]").set_input_files(
        files=[FilePayload(name=name, mimeType="text/csv", buffer=data)]
    )
    page.get_by_role("button", name="Upload and submit").click()


# --- 1. lab: template, upload with errors, correction, submission ---------------------------


def test_lab_uploads_fixes_and_submits(page: Page, live_server, shots, console_errors):
    comparison = _comparison(
        ComparisonStatus.OPEN, submission_deadline=timezone.now() + dt.timedelta(days=30)
    )
    participant = _lab_member(comparison, "Lab Alpha", "alpha")

    _sign_in(page, live_server.url, "alpha", shots, shot="login")
    shots(page, "lab-dashboard")
    page.get_by_role("link", name=CODE).first.click()
    expect(page.get_by_role("heading", name=CODE)).to_be_visible()
    shots(page, "lab-comparison")
    page.get_by_role("link", name="Upload a file").click()
    expect(page.get_by_role("heading", name=re.compile("Upload results"))).to_be_visible()

    with page.expect_download() as info:
        page.get_by_role("link", name="Template (CSV)").click()
    download = info.value
    assert download.suggested_filename == f"{CODE}-results-template.csv"
    text = open(download.path(), encoding="utf-8-sig").read()  # noqa: SIM115
    template = list(csv.DictReader(io.StringIO(text)))
    assert text.splitlines()[0].split(",") == TEMPLATE_HEADER
    assert {(r["axis"], float(r["frequency_hz"])) for r in template} == LINEAR_POINTS
    assert {r["device"] for r in template} == {"MEMS 1"}
    assert all(r["sensitivity"] == "" and r["expanded_uncertainty"] == "" for r in template)

    values = {(r["axis"], float(r["frequency_hz"])): 418.0 + i for i, r in enumerate(template)}
    filled = [
        r | {"sensitivity": f"{418.0 + i}", "expanded_uncertainty": "8.5"}
        for i, r in enumerate(template)
    ]
    broken = [dict(r) for r in filled]
    broken[1]["sensitivity"] = "-5"  # file row 3 (the header is row 1)
    broken[4]["expanded_uncertainty"] = "abc"  # file row 6
    _upload(page, "results.csv", _csv(broken))

    report = page.get_by_role("alert").filter(has_text="nothing was stored")
    expect(report).to_be_visible()
    rows = report.locator("table.error-report tbody tr")
    expect(rows).to_have_count(2)
    expect(rows.nth(0)).to_contain_text("row 3")
    expect(rows.nth(0)).to_contain_text("sensitivity")
    expect(rows.nth(1)).to_contain_text("row 6")
    expect(rows.nth(1)).to_contain_text("expanded_uncertainty")
    shots(page, "lab-upload-errors", publish=True)
    assert not Submission.objects.filter(participant=participant).exists()

    _upload(page, "results-fixed.csv", _csv(filled))
    expect(page.get_by_text("your results were submitted")).to_be_visible()
    expect(page).to_have_url(f"{live_server.url}/lab/comparisons/{CODE}/")
    shots(page, "lab-submitted")

    [submission] = Submission.objects.filter(participant=participant)
    assert (submission.version, submission.status) == (1, Submission.Status.SUBMITTED)
    stored = {
        (r.measurement_point.axis, r.measurement_point.frequency_hz): r
        for r in Result.objects.filter(submission=submission).select_related("measurement_point")
    }
    assert set(stored) == LINEAR_POINTS
    assert {k: r.value for k, r in stored.items()} == values
    assert {(r.expanded_uncertainty, r.coverage_factor) for r in stored.values()} == {(8.5, 2.0)}
    assert console_errors == []


# --- 2 and 3. coordinator: run, progress, heat maps, publication; lab: PDF ------------------


@pytest.fixture
def analysable(db) -> tuple[Comparison, dict[str, Participant]]:
    """A closed comparison with three labs' accepted results and no authoriser yet.

    At every point the labs report x, x + 1 and x + 12 with U = 8 (k = 2): chi2_obs =
    (4.33^2 + 3.33^2 + 7.67^2) / 16 = 5.54 < chi2_0.95(2) = 5.99, so the weighted mean of all
    three is the assigned value; pairwise En = 12 / (8 * sqrt 2) = 1.06 for Alpha-Gamma only.
    """
    comparison = _comparison(ComparisonStatus.CLOSED, assigned_value_method="weighted_mean")
    coordinator = UserFactory.create(username="carla")
    comparison.coordinators.add(coordinator)
    points = list(comparison.measurement_points.order_by("axis", "frequency_hz"))
    labs = {}
    for offset, name, user in ((0, "Lab Alpha", "alpha"), (1, "Lab Beta", "beta"),
                               (12, "Lab Gamma", "gamma")):  # fmt: skip
        participant = _lab_member(comparison, name, user)
        submission = Submission.objects.create(
            participant=participant, version=1, status=Submission.Status.ACCEPTED
        )
        Result.objects.bulk_create(
            Result(submission=submission, measurement_point=p, value=419.0 + offset + 0.1 * i,
                   unit="D/(m/s^2)", expanded_uncertainty=8.0, coverage_factor=2.0)
            for i, p in enumerate(points)
        )  # fmt: skip
        labs[user] = participant
    return comparison, labs


def test_coordinator_publishes_and_lab_downloads_pdf(
    page: Page, new_context, live_server, shots, console_errors, analysable, monkeypatch
):
    from analysis.tasks import analysis_run_task

    comparison, labs = analysable
    queued: list[int] = []  # hold the task back so the page shows the run from 0 %
    monkeypatch.setattr(analysis_run_task, "delay", queued.append)
    base = live_server.url

    _sign_in(page, base, "carla", shots)
    page.goto(f"{base}/coordinator/{CODE}/")
    shots(page, "coordinator-comparison")
    page.get_by_role("link", name="Run analysis…").click()  # its confirmation page
    page.get_by_role("button", name="Run analysis").click()
    expect(page.get_by_role("heading", name=re.compile(r"Analysis run \d+"))).to_be_visible()
    bar = page.locator("#run-progress .progress-bar")
    expect(bar).to_have_text("0 %")
    expect(page.locator("#run-progress")).to_have_attribute("hx-get", re.compile("/progress/$"))
    shots(page, "coordinator-run-pending")
    run = AnalysisRun.objects.get(comparison=comparison)
    assert queued == [run.pk] and run.status == AnalysisRun.Status.PENDING

    polls: list[str] = []
    page.on("request", lambda r: polls.append(r.url) if r.url.endswith("/progress/") else None)
    navigations: list[str] = []
    page.on("framenavigated", lambda f: navigations.append(f.url))
    analysis_run_task.apply(args=[run.pk])  # what the worker would do
    expect(bar).to_have_text("100 %", timeout=10_000)
    expect(page.locator("#run-progress")).not_to_have_attribute("hx-get", re.compile("."))
    expect(page.locator("#run-progress .badge")).to_have_text("Succeeded")
    assert polls and navigations == []  # htmx swapped the bar in place
    shots(page, "coordinator-run-done", publish=True)
    run.refresh_from_db()
    assert (run.status, run.progress) == (AnalysisRun.Status.SUCCEEDED, 100)
    assert Score.objects.filter(run=run).count() == 3 * 9

    page.get_by_role("link", name="See the results").click()
    expect(page.get_by_role("heading", name="Assigned values")).to_be_visible()
    # X 5 Hz: equal U = 8, values 419, 420, 431 -> x_pt = 423.333, u = 4 / sqrt 3 = 2.309,
    # Birge ratio sqrt(5.54 / 2) = 1.66; written as a metrologist does (GUM 7.2.6: the
    # uncertainty to two digits, x_pt to the same place as U(x_pt) = 4.6).
    first = page.locator("table tbody tr").first
    for shown in ("423.3", "2.3", "4.6", "5.54", "1.66"):  # U(x_pt) = 2·2.309
        expect(first).to_contain_text(shown)
    shots(page, "coordinator-results", publish=True)
    page.get_by_role("link", name="Charts").first.click()
    expect(page.locator("svg").first).to_be_visible()
    shots(page, "coordinator-charts")
    page.get_by_role("link", name="Compatibility").first.click()
    expect(page.locator(".heat svg")).to_have_count(3)  # bench matrix per axis
    page.get_by_label("Compare").select_option("lab")
    page.get_by_role("button", name="Show").click()
    expect(page.locator(".heat svg")).to_have_count(1)  # laboratories at the first point
    expect(page.get_by_text("1 incompatible pair", exact=True)).to_be_visible()
    shots(page, "coordinator-heatmap", publish=True)

    page.get_by_role("link", name="Assigned values").first.click()
    page.get_by_role("link", name="Publish results…").click()
    # the confirmation says why it cannot be done yet, and offers no button
    refused = page.get_by_role("alert").filter(has_text="cannot be published")
    expect(refused).to_contain_text("authorising")
    expect(page.get_by_role("button", name="Publish results")).to_have_count(0)
    shots(page, "coordinator-publish-refused")
    assert Comparison.objects.get(pk=comparison.pk).status == ComparisonStatus.ANALYSED

    page.get_by_role("link", name=CODE).first.click()  # breadcrumb: the comparison page
    notes = page.get_by_role("heading", name="Report comments and authorisation")
    expect(page.locator(".card", has=notes)).to_contain_text("needed before publication")
    page.locator(".card", has=notes).get_by_role("link", name="Edit").click()
    page.get_by_label("Authorised by (name)").fill("Dana Quality")
    page.get_by_label("Role", exact=True).fill("Quality manager")
    shots(page, "coordinator-report-notes")
    page.get_by_role("button", name="Save").click()
    expect(page.get_by_text("Dana Quality, Quality manager")).to_be_visible()
    page.get_by_role("link", name="Results", exact=True).click()
    page.get_by_role("link", name="Publish results…").click()
    expect(page.get_by_text("Publication is final: it cannot be undone.")).to_be_visible()
    shots(page, "coordinator-publish-confirm")
    page.get_by_role("button", name="Publish results").click()
    # the publication job's progress page, polled until the job has ended
    progress = page.locator("#publication-progress")
    expect(progress).to_have_attribute("data-status", "succeeded", timeout=60_000)
    expect(progress.get_by_text("the participants were told by e-mail")).to_be_visible()
    shots(page, "coordinator-published")
    assert Comparison.objects.get(pk=comparison.pk).status == ComparisonStatus.PUBLISHED
    own = labs["beta"]
    assert Report.objects.filter(participant=own).count() == 1

    lab_page = new_context().new_page()
    console_errors.watch(lab_page)
    _sign_in(lab_page, base, "beta", shots)
    lab_page.goto(f"{base}/reports/{CODE}/")
    listed = lab_page.locator("table tbody tr")
    expect(listed.filter(has_text=f"Participant report {own.code}")).to_have_count(1)
    for other in ("alpha", "gamma"):
        expect(lab_page.get_by_text(f"Participant report {labs[other].code}")).to_have_count(0)
    shots(lab_page, "lab-reports", publish=True)
    with lab_page.expect_download() as info:
        listed.filter(has_text=f"Participant report {own.code}").get_by_role("link").click()
    pdf = info.value
    assert pdf.suggested_filename.endswith(".pdf")
    data = open(pdf.path(), "rb").read()  # noqa: SIM115
    assert data.startswith(b"%PDF-")
    text = "\n".join(p.extract_text() for p in PdfReader(io.BytesIO(data)).pages)
    assert own.code in text
    assert "Lab Alpha" not in text and "Lab Gamma" not in text
    assert "● " in text or "●" in text  # the inclusion mark beside the codes

    # the lab's scores page: every result of the round entered the weighted mean (●)
    lab_page.goto(f"{base}/results/{CODE}/scores/")
    rows = lab_page.locator("table tbody tr")
    expect(rows).to_have_count(27)
    expect(lab_page.locator('span[title="in the assigned value"]')).to_have_count(27)
    expect(lab_page.get_by_text("the result entered its point's assigned value")).to_be_visible()
    expect(rows.filter(has_text=own.code).first).to_have_class(re.compile("own-row"))
    # every column is in view at 1280 px: the table does not scroll sideways
    scroll, width = lab_page.locator(".table-responsive").first.evaluate(
        "e => [e.scrollWidth, e.clientWidth]"
    )
    assert scroll <= width, f"the scores table scrolls sideways ({scroll} > {width} px)"
    shots(lab_page, "lab-scores-inclusion")
    assert console_errors == []
