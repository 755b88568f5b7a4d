"""The broker goes down while a coordinator publishes: the publication stands (200), the
lost enqueue is logged, and when the broker is back the beat sweep sends the report task
and a real worker issues every report (summary + one per participant), once."""

import logging
import time
from io import StringIO

import pytest
from django.contrib.auth import get_user_model
from django.core.management import call_command
from rest_framework.test import APIClient

from analysis.models import AnalysisRun, Report
from analysis.reports.services import reports_missing, reports_pending_enqueue
from analysis.services import analysis_run_execute
from analysis.tasks import reports_pending_task
from proficiency.models import Comparison
from tests.faults.conftest import wait_until

pytestmark = [
    pytest.mark.services,
    pytest.mark.real_worker,
    pytest.mark.django_db(transaction=True),
]
CODE = "IMU-2024-DEMO"


@pytest.fixture
def analysed(workers):  # after ``workers``: the demo's own tasks go to the test's queue
    call_command("load_demo", password="demo-password-1", stdout=StringIO())
    demo = Comparison.objects.get(code=CODE)
    run = AnalysisRun.objects.create(comparison=demo, parameters={"compare": ["device"]})
    assert analysis_run_execute(run_id=run.pk) == "succeeded"  # in-process: not the fault
    Comparison.objects.filter(pk=demo.pk).update(
        authorised_by_name="A. Coordinator", authorised_by_role="PT coordinator"
    )
    return run


def coordinator() -> APIClient:
    client = APIClient()
    client.force_authenticate(get_user_model().objects.get(username="coordinator"))
    return client


def test_publish_with_broker_down_loses_no_report(workers, analysed, broker_proxy, caplog):
    workers.start("w0")  # the worker reaches Redis directly; this process only via the proxy
    broker_proxy.cut()
    t0 = time.monotonic()
    with caplog.at_level(logging.ERROR, logger="common.jobs"):
        response = coordinator().post(f"/api/v1/comparisons/{CODE}/publish/")
    assert response.status_code == 200, response.content
    assert time.monotonic() - t0 < 15  # the request does not hang on the dead broker
    assert response.json()["status"] == "published"
    assert "reports_issue_all_task not queued, broker unreachable" in caplog.text
    demo = Comparison.objects.get(code=CODE)
    assert demo.status == "published"
    participants = demo.participants.count()
    assert participants == 12 and reports_missing(demo) == 13
    assert not Report.objects.exists()
    assert reports_pending_enqueue() == 0  # broker still down: nothing sent, nothing lost

    broker_proxy.restore()
    reports_pending_task.delay()  # what Celery beat sends every 5 minutes

    def issued() -> int:
        return Report.objects.filter(comparison=demo).count() >= 13

    wait_until(issued, "the 13 reports", workers, timeout=90)
    time.sleep(1)  # a duplicate would show up now
    reports = Report.objects.filter(comparison=demo)
    assert reports.count() == 13
    assert reports.filter(kind="summary", participant=None).count() == 1
    by_participant = reports.filter(kind="participant")
    assert sorted(by_participant.values_list("participant_id", flat=True)) == sorted(
        demo.participants.values_list("pk", flat=True)
    )
    assert set(reports.values_list("run_id", "version", "superseded")) == {(analysed.pk, 1, False)}
    assert reports_missing(demo) == 0 and reports_pending_enqueue() == 0


def test_run_start_with_broker_down_fails_cleanly(workers, analysed, broker_proxy):
    """Not a run pending for ever: it fails with a clear error, and a later start works."""
    Comparison.objects.filter(code=CODE).update(status="closed")
    broker_proxy.cut()
    response = coordinator().post(f"/api/v1/comparisons/{CODE}/analysis-runs/")
    assert response.status_code == 202, response.content
    body = response.json()
    assert body["status"] == "failed" and "broker" in body["error"]
    broker_proxy.restore()
    workers.start("w0")
    again = coordinator().post(f"/api/v1/comparisons/{CODE}/analysis-runs/").json()
    assert again["id"] != body["id"] and again["status"] == "pending"
    run = AnalysisRun.objects.get(pk=again["id"])

    def finished() -> bool:
        run.refresh_from_db()
        return run.status in ("succeeded", "failed")

    wait_until(finished, "the second run", workers, timeout=60)
    assert run.status == "succeeded", run.error
