"""Issuing: storage under MEDIA_ROOT, versions, superseding, idempotent tasks."""

import hashlib
from pathlib import Path

import pytest

from analysis.models import Report
from analysis.reports.services import report_issue, report_issue_once, reports_issue_all
from analysis.reports.tasks import report_issue_task
from common.errors import StateConflict, ValidationFailed
from tests.analysis.reports.conftest import pdf_text

pytestmark = pytest.mark.django_db(transaction=True)


def test_issue_twice_gives_two_versions_with_equal_bytes(analysed, media_root):
    comparison = analysed.comparison
    first = report_issue(comparison=comparison, kind="summary")
    second = report_issue(comparison=comparison, kind="summary")
    first.refresh_from_db()
    assert (first.version, second.version) == (1, 2)
    assert first.superseded and not second.superseded
    assert first.sha256 == second.sha256 and first.token != second.token
    path = Path(second.file.path)
    assert path == Path(media_root) / "reports" / comparison.code / f"{second.token}.pdf"
    pdf = path.read_bytes()
    assert hashlib.sha256(pdf).hexdigest() == second.sha256 and len(pdf) == second.size
    assert second.run == analysed and second.software_version
    assert f"{comparison.code}-S-v1" in pdf_text(pdf)[0]  # same run: same edition


def test_participant_versions_are_counted_per_participant(analysed):
    a, b = analysed.comparison.participants.order_by("code")[:2]
    report_issue(comparison=analysed.comparison, kind="participant", participant=a)
    again = report_issue(comparison=analysed.comparison, kind="participant", participant=a)
    other = report_issue(comparison=analysed.comparison, kind="participant", participant=b)
    assert (again.version, other.version) == (2, 1)
    with pytest.raises(ValidationFailed):
        report_issue(comparison=analysed.comparison, kind="participant")


def test_tasks_are_idempotent(monkeypatch, analysed):
    monkeypatch.setattr("analysis.reports.services.render_report", lambda data: b"%PDF-1.4 x")
    first = report_issue_task(analysed.pk, "summary", None)
    assert report_issue_task(analysed.pk, "summary", None) == first
    again = report_issue_once(run_id=analysed.pk, kind="summary", participant_id=None)
    assert again is not None and again.pk == first
    assert Report.objects.count() == 1
    assert len(reports_issue_all(comparison=analysed.comparison)) == 13
    assert Report.objects.count() == 13


def test_no_report_before_analysis(demo):
    with pytest.raises(StateConflict):
        report_issue(comparison=demo, kind="summary")
