"""Hostile files, a stuck run and publication in real Chromium, as lab staff, this round's
coordinator and the laboratory reading its reports afterwards.

1. Lab staff upload a CSV whose one data row is 20,000 cells wide and then a file of 1,500
   bad rows: one error for the wide row, 1,000 listed problems and a count of the rest.
2. The coordinator starts a run that no worker takes, cancels it on the run page and
   starts a new one, which succeeds.
3. A preliminary report issued before publication is no longer what the laboratory reads
   afterwards: its list holds the final report, whose PDF does not say "Preliminary".

Screenshots in test-artifacts/browser/<test>/.
"""

from __future__ import annotations

import datetime as dt
import io
import re

import pytest
from django.utils import timezone
from playwright.sync_api import Page, expect
from pypdf import PdfReader

from analysis.models import AnalysisRun, Report
from analysis.reports.services import report_issue
from labs.models import Submission
from proficiency.models import Comparison, ComparisonStatus
from tests.browser import test_flows
from tests.browser.test_flows import (
    CODE,
    TEMPLATE_HEADER,
    _comparison,
    _lab_member,
    _sign_in,
    _upload,
)

pytestmark = [pytest.mark.browser, pytest.mark.django_db(transaction=True)]
analysable = test_flows.analysable  # the closed three-lab round of the publication flow


def test_lab_meets_bounded_error_listings(page: Page, live_server, shots, console_errors):
    comparison = _comparison(
        ComparisonStatus.OPEN, submission_deadline=timezone.now() + dt.timedelta(days=30)
    )
    participant = _lab_member(comparison, "Lab Alpha", "alpha")
    _sign_in(page, live_server.url, "alpha", shots)
    page.goto(f"{live_server.url}/lab/comparisons/{CODE}/upload/")

    header = ",".join(TEMPLATE_HEADER)
    wide = f"{header}\nMEMS 1,X,5,linear,vertical,,420,,8,2,,{',x' * 20_000}\n".encode()
    _upload(page, "wide.csv", wide)
    report = page.get_by_role("alert").filter(has_text="nothing was stored")
    expect(report).to_be_visible()
    rows = report.locator("table.error-report tbody tr")
    expect(rows).to_have_count(1)
    expect(rows.first).to_contain_text("row 2")
    shots(page, "lab-upload-wide-row")

    bad = "\n".join([header] + ["MEMS 1,X,5,linear,vertical,,-1,,8,2,,"] * 1_500).encode()
    _upload(page, "many-bad-rows.csv", bad)
    expect(report).to_be_visible()
    expect(report).to_contain_text("500 more")
    assert report.locator("table.error-report tbody tr").count() <= 1_001
    shots(page, "lab-upload-many-problems")
    assert not Submission.objects.filter(participant=participant).exists()
    assert console_errors == []


def test_coordinator_cancels_a_stuck_run_and_publishes(
    page: Page,
    new_context,
    live_server,
    shots,
    console_errors,
    analysable,
    monkeypatch,
):
    from analysis.tasks import analysis_run_task

    comparison, labs = analysable
    queued: list[int] = []  # no worker takes the first run: it stays pending
    monkeypatch.setattr(analysis_run_task, "delay", queued.append)
    base = live_server.url
    _sign_in(page, base, "carla", shots)
    page.goto(f"{base}/coordinator/{CODE}/")
    page.get_by_role("link", name="Run analysis…").click()  # its confirmation page
    page.get_by_role("button", name="Run analysis").click()
    expect(page.get_by_role("button", name="Cancel this run")).to_be_visible()
    shots(page, "coordinator-run-stuck")
    page.get_by_role("button", name="Cancel this run").click()
    expect(page.locator("#run-progress .badge")).to_have_text("Cancelled")
    shots(page, "coordinator-run-cancelled")
    stuck = AnalysisRun.objects.get(pk=queued[0])
    assert stuck.status == AnalysisRun.Status.CANCELLED

    monkeypatch.undo()  # the next run is done at once (eager)
    page.goto(f"{base}/coordinator/{CODE}/")
    page.get_by_role("link", name="Run analysis…").click()  # its confirmation page
    page.get_by_role("button", name="Run analysis").click()
    expect(page.locator("#run-progress .badge")).to_have_text("Succeeded", timeout=15_000)
    shots(page, "coordinator-run-after-cancel")

    own = labs["beta"]
    comparison.refresh_from_db()
    preliminary = report_issue(comparison=comparison, kind=Report.Kind.PARTICIPANT, participant=own)
    assert preliminary.status == "preliminary"
    Comparison.objects.filter(pk=comparison.pk).update(
        authorised_by_name="Dana Quality", authorised_by_role="Quality manager"
    )
    page.goto(f"{base}/coordinator/{CODE}/results/")
    page.get_by_role("link", name="Publish results…").click()
    expect(page.get_by_text("1 preliminary report is superseded by them")).to_be_visible()
    page.get_by_role("button", name="Publish results").click()
    # the publication job's progress page, polled until the job has ended
    progress = page.locator("#publication-progress")
    expect(progress).to_have_attribute("data-status", "succeeded", timeout=60_000)
    expect(progress.get_by_text("the participants were told by e-mail")).to_be_visible()
    preliminary.refresh_from_db()
    assert preliminary.superseded

    lab_page = new_context().new_page()
    console_errors.watch(lab_page)
    _sign_in(lab_page, base, "beta", shots)
    lab_page.goto(f"{base}/reports/{CODE}/")
    listed = lab_page.locator("table tbody tr").filter(has_text=f"Participant report {own.code}")
    expect(listed).to_have_count(1)
    expect(listed).to_contain_text(re.compile("final", re.I))
    shots(lab_page, "lab-reports-after-publication")
    with lab_page.expect_download() as info:
        listed.get_by_role("link").first.click()
    data = open(info.value.path(), "rb").read()  # noqa: SIM115
    text = "\n".join(p.extract_text() for p in PdfReader(io.BytesIO(data)).pages)
    assert own.code in text and "Preliminary" not in text
    assert console_errors == []
