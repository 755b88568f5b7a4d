"""The broker goes down while a coordinator publishes: the publication job fails at once
with the reason (202, the job failed), the lost enqueue is logged and nothing is
published; when the broker is back, publishing again sends the job to a real worker, which
issues every final report (summary + one per participant) once and publishes."""

import logging
import time
from io import StringIO

import pytest
from django.contrib.auth import get_user_model
from django.core.management import call_command
from rest_framework.test import APIClient

from analysis.models import AnalysisRun, Publication, Report
from analysis.publication import BROKER_UNREACHABLE
from analysis.reports.services import reports_missing, reports_pending_enqueue
from analysis.services import analysis_run_execute
from labs.models import Notice
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


def test_publish_with_broker_down_publishes_nothing_then_a_worker_publishes(
    workers, analysed, broker_proxy, caplog
):
    workers.start("w0")  # the worker reaches Redis directly; this process only via the proxy
    broker_proxy.cut()
    t0 = time.monotonic()
    with caplog.at_level(logging.ERROR, logger="common.jobs"):
        response = coordinator().post(f"/api/v1/comparisons/{CODE}/publish/")
    assert response.status_code == 202, response.content
    assert time.monotonic() - t0 < 15  # the request does not hang on the dead broker
    body = response.json()
    assert body["status"] == "analysed"
    assert (body["publication"]["status"], body["publication"]["error"]) == (
        "failed", BROKER_UNREACHABLE,
    )  # fmt: skip
    assert "publication_task not queued, broker unreachable" in caplog.text
    demo = Comparison.objects.get(code=CODE)
    assert demo.status == "analysed" and not Report.objects.exists()
    assert not Notice.objects.filter(kind="published").exists()

    broker_proxy.restore()
    again = coordinator().post(f"/api/v1/comparisons/{CODE}/publish/")
    assert again.status_code == 202 and again.json()["publication"]["status"] == "pending"
    job = Publication.objects.get(pk=again.json()["publication"]["id"])

    def ended() -> bool:
        job.refresh_from_db()
        return job.status in ("succeeded", "failed")

    wait_until(ended, "the publication to end", workers, timeout=90)
    assert (job.status, job.error, job.progress) == ("succeeded", "", 100)
    time.sleep(1)  # a duplicate would show up now
    demo.refresh_from_db()
    assert demo.status == "published"
    reports = Report.objects.filter(comparison=demo)
    assert reports.count() == 13 and sorted(job.report_ids) == sorted(reports.values_list(
        "pk", flat=True))  # fmt: skip
    assert reports.filter(kind="summary", participant=None).count() == 1
    by_participant = reports.filter(kind="participant")
    assert sorted(by_participant.values_list("participant_id", flat=True)) == sorted(
        demo.participants.values_list("pk", flat=True)
    )
    assert set(reports.values_list("run_id", "version", "superseded", "status")) == {
        (analysed.pk, 1, False, "final")
    }
    assert Notice.objects.filter(kind="published", comparison=demo).count() == 12
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
