"""Reports follow the comparison's status: publication supersedes every preliminary report
and issues final ones, idempotently; a preliminary issue racing the publication never ends
up current; participants never read a preliminary report."""

import threading

import pytest
from django.contrib.auth import get_user_model
from django.db import connections
from rest_framework.test import APIClient

from analysis.models import Report
from analysis.publication import comparison_publish
from analysis.reports.services import (
    report_issue,
    report_issue_batch,
    reports_missing,
    reports_pending_enqueue,
)
from analysis.reports.tasks import reports_issue_all_task
from proficiency.models import ComparisonStatus
from tests.analysis.reports.conftest import CODE, pdf_text, published_missing_reports

pytestmark = pytest.mark.django_db(transaction=True)

PRELIMINARY = "Preliminary (not the final report; results may still change)"


def current(comparison):
    """(kind, participant code) → the current report, every report checked to be alone."""
    found = {}
    for r in Report.objects.filter(comparison=comparison, superseded=False):
        key = (r.kind, r.participant.code if r.participant else None)
        assert key not in found, f"two current reports for {key}"
        found[key] = r
    return found


def first_page(report):
    with report.file.open("rb") as f:
        return pdf_text(f.read())[0]


def test_publication_supersedes_preliminary_reports_with_final_ones(analysed):
    comparison = analysed.comparison
    participants = list(comparison.participants.order_by("code"))
    one = participants[0]
    early = report_issue(comparison=comparison, kind="participant", participant=one)
    early_summary = report_issue(comparison=comparison, kind="summary")
    before = current(comparison)
    assert set(before) == {("participant", one.code), ("summary", None)}
    assert before[("participant", one.code)] == early and early.status == "preliminary"
    assert early_summary.status == "preliminary"
    assert PRELIMINARY in first_page(early) and PRELIMINARY in first_page(early_summary)

    comparison_publish(comparison=comparison)  # eager Celery: the reports are issued now

    after = current(comparison)
    assert set(after) == {("summary", None)} | {("participant", p.code) for p in participants}
    assert PRELIMINARY not in first_page(after[("participant", one.code)])
    assert PRELIMINARY not in first_page(after[("summary", None)])
    for key, report in after.items():
        text = first_page(report)
        assert "Preliminary" not in text and "Final" in text, key
        assert report.status == "final", key
    assert after[("participant", one.code)].version == 2
    assert after[("summary", None)].version == 2
    early.refresh_from_db()
    early_summary.refresh_from_db()
    assert early.superseded and early_summary.superseded
    assert set(Report.objects.filter(superseded=False).values_list("status", flat=True)) == {
        "final"
    }
    assert not Report.objects.filter(status="preliminary", superseded=False).exists()
    assert Report.objects.filter(status="preliminary").count() == 2
    assert reports_missing(comparison) == 0


@pytest.fixture
def stand_in(monkeypatch):
    """A stand-in PDF naming the status the report was rendered for."""
    monkeypatch.setattr(
        "analysis.reports.services.render_report",
        lambda data: f"%PDF-1.4 {data.report_number} {data.status}".encode(),
    )


def test_publication_task_delivered_twice_gives_the_same_reports(stand_in, analysed):
    comparison = analysed.comparison
    report_issue(comparison=comparison, kind="summary")
    comparison_publish(comparison=comparison)
    first = {k: r.pk for k, r in current(comparison).items()}
    n_reports = Report.objects.count()
    assert len(first) == 13 and n_reports == 14  # + the superseded preliminary summary

    assert reports_issue_all_task(comparison.pk) == 13  # a second delivery
    assert reports_issue_all_task.delay(comparison.pk).get() == 13  # and a third, via Celery
    assert {k: r.pk for k, r in current(comparison).items()} == first
    assert Report.objects.count() == n_reports
    assert reports_missing(comparison) == 0 and reports_pending_enqueue() == 0


def test_pending_task_resends_a_published_round_that_still_has_a_preliminary_report(
    stand_in, analysed
):
    """A round published without its final reports (before publication rendered them
    itself): the beat task sees the missing finals."""
    comparison = analysed.comparison
    report_issue(comparison=comparison, kind="summary")
    comparison = published_missing_reports(comparison)
    assert current(comparison) == {}  # the preliminary summary is no longer current
    assert reports_missing(comparison) == 13
    assert reports_pending_enqueue() == 1
    assert len(current(comparison)) == 13 and reports_missing(comparison) == 0
    assert {r.status for r in current(comparison).values()} == {"final"}


def test_participants_never_read_a_preliminary_report(stand_in, analysed):
    comparison = analysed.comparison
    one = comparison.participants.get(laboratory__members__user__username="lab03")
    early = report_issue(comparison=comparison, kind="participant", participant=one)
    comparison_publish(comparison=comparison)
    lab = APIClient()
    lab.force_authenticate(get_user_model().objects.get(username="lab03"))
    listed = lab.get(f"/api/v1/comparisons/{CODE}/reports/").json()
    assert {(r["kind"], r["status"], r["version"]) for r in listed} == {
        ("summary", "final", 1),
        ("participant", "final", 2),
    }
    assert lab.get(f"/api/v1/reports/{early.token}/pdf").status_code == 404
    final = current(comparison)[("participant", one.code)]
    assert lab.get(f"/api/v1/reports/{final.token}/pdf").status_code == 200
    coordinator = APIClient()
    coordinator.force_authenticate(get_user_model().objects.get(username="coordinator"))
    assert coordinator.get(f"/api/v1/reports/{early.token}/pdf").status_code == 200


def _in_thread(target, errors):
    def run():
        try:
            target()
        except BaseException as exc:
            errors.append(exc)
        finally:
            connections.close_all()

    thread = threading.Thread(target=run)
    thread.start()
    return thread


def test_preliminary_issue_in_flight_during_publication_never_ends_up_current(
    needs_postgres, analysed, monkeypatch
):
    """A coordinator's preliminary report is rendering when the round is published: the
    publication waits for it and supersedes it; its final version is issued."""
    comparison = analysed.comparison
    one = comparison.participants.order_by("code").first()
    rendering, release = threading.Event(), threading.Event()
    statuses = []

    def render(data):
        statuses.append((data.own_code, data.status))
        if data.own_code == one.code and data.status == "preliminary":
            rendering.set()
            assert release.wait(30)
        return f"%PDF-1.4 {data.report_number} {data.status}".encode()

    monkeypatch.setattr("analysis.reports.services.render_report", render)
    errors: list[BaseException] = []
    issuing = _in_thread(
        lambda: report_issue(comparison=comparison, kind="participant", participant=one), errors
    )
    publishing = None
    try:
        assert rendering.wait(30)
        publishing = _in_thread(lambda: comparison_publish(comparison=comparison), errors)
        publishing.join(1)
        waited = publishing.is_alive()  # waits for the preliminary report to be stored
        comparison.refresh_from_db()
        status_meanwhile = comparison.status
    finally:
        release.set()
        issuing.join(30)
        if publishing is not None:
            publishing.join(60)
    assert not errors and not issuing.is_alive() and not publishing.is_alive()
    assert waited and status_meanwhile == ComparisonStatus.ANALYSED

    preliminary = Report.objects.get(participant=one, status="preliminary")
    assert preliminary.superseded and preliminary.version == 1
    now = current(comparison)
    assert len(now) == 13 and {r.status for r in now.values()} == {"final"}
    assert now[("participant", one.code)].version == 2
    assert statuses[0] == (one.code, "preliminary")
    assert statuses.count((one.code, "final")) == 1


def test_batch_started_before_publication_issues_final_reports_after_it(
    needs_postgres, analysed, monkeypatch
):
    """A batch of reports running while the round is analysed (the first report rendering
    when the publication comes): the reports stored after the publication are final, the
    preliminary one is superseded, and every participant ends with one current final one."""
    comparison = analysed.comparison
    ids = list(comparison.participants.order_by("code").values_list("pk", flat=True)[:3])
    first_code = comparison.participants.get(pk=ids[0]).code
    rendering, release = threading.Event(), threading.Event()

    def render(data):
        if data.own_code == first_code and data.status == "preliminary":
            rendering.set()
            assert release.wait(30)
        return f"%PDF-1.4 {data.report_number} {data.status}".encode()

    monkeypatch.setattr("analysis.reports.services.render_report", render)
    errors: list[BaseException] = []
    batch = _in_thread(lambda: report_issue_batch(run_id=analysed.pk, participant_ids=ids), errors)
    publishing = None
    try:
        assert rendering.wait(30)
        publishing = _in_thread(lambda: comparison_publish(comparison=comparison), errors)
        publishing.join(1)
        waited = publishing.is_alive()
    finally:
        release.set()
        batch.join(60)
        if publishing is not None:
            publishing.join(60)
    assert not errors and not batch.is_alive() and not publishing.is_alive()
    assert waited

    now = current(comparison)
    assert len(now) == 13 and {r.status for r in now.values()} == {"final"}
    assert list(Report.objects.filter(status="preliminary").values_list("participant", flat=True))
    assert not Report.objects.filter(status="preliminary", superseded=False).exists()
    for pk in ids:
        assert Report.objects.filter(participant_id=pk, superseded=False).count() == 1


def test_migration_marks_old_reports_by_the_audit_logs_publication_time(stand_in, analysed):
    """Rows from before ``Report.status``: final if issued after the logged publication,
    else preliminary and, on a published comparison, superseded (beat issues the final)."""
    import importlib

    from django.apps import apps

    migration = importlib.import_module("analysis.migrations.0007_report_status")
    comparison = analysed.comparison
    early = report_issue(comparison=comparison, kind="summary")
    comparison_publish(comparison=comparison)
    later = set(Report.objects.exclude(pk=early.pk).values_list("pk", flat=True))
    assert len(later) == 13
    Report.objects.update(status="preliminary", superseded=False)  # as before the field
    migration.forwards(apps, None)
    assert set(Report.objects.filter(status="final").values_list("pk", flat=True)) == later
    early.refresh_from_db()
    assert (early.status, early.superseded) == ("preliminary", True)
