"""A worker SIGKILLed while it renders a report of a batch, with the production
visibility timeout (an hour): the batch's row stays running, its heartbeat goes stale,
the beat sweep (``jobs_sweep_task``) sends the batch again to a new worker, which takes
the claim over and issues the reports left; every report exists once and every batch row
ends done (docs/lifecycles.md §4)."""

import os
import signal
import time
from io import StringIO

import pytest
from django.core.management import call_command

from analysis.models import AnalysisRun, Report, ReportBatch
from analysis.reports.tasks import reports_issue_all_task
from analysis.services import analysis_run_execute
from proficiency.models import Comparison
from tests.analysis.reports.conftest import published_missing_reports
from tests.faults.conftest import wait_until

pytestmark = [
    pytest.mark.services,
    pytest.mark.real_worker,
    pytest.mark.django_db(transaction=True),
]
HEARTBEAT, STALE, SWEEP = 0.5, 3.0, 1.0  # production: 30 s, 300 s, 60 s
ENV = {
    "CELERY_VISIBILITY_TIMEOUT": "3600",  # only the sweep can bring the batch back in time
    "JOB_HEARTBEAT_SECONDS": str(HEARTBEAT),
    "JOB_STALE_SECONDS": str(STALE),
    "JOB_SWEEP_SECONDS": str(SWEEP),
}


@pytest.fixture
def analysed(workers):  # after ``workers``: the demo's own tasks go to the test's queue
    call_command("load_demo", password="demo-password-1", stdout=StringIO())
    demo = Comparison.objects.get(code="IMU-2024-DEMO")
    run = AnalysisRun.objects.create(comparison=demo, parameters={"compare": ["device"]})
    assert analysis_run_execute(run_id=run.pk) == "succeeded"  # in-process: not the fault
    return run


def test_sigkill_mid_batch_is_re_queued_by_the_sweep_and_issues_each_report_once(
    workers, analysed, tmp_path
):
    demo = analysed.comparison
    codes = list(demo.participants.order_by("code").values_list("code", flat=True))
    hung = codes[2]  # two reports of the batch stored, then the worker hangs in the third
    marker = tmp_path / "hung"
    doomed = workers.start("w0", FAULT_HANG_REPORT=hung, FAULT_MARKER=str(marker), **ENV)
    # a published round missing its final reports: the fan-out goes to the test's queue
    reports_issue_all_task.delay(published_missing_reports(demo).pk)
    wait_until(marker.exists, f"the worker to hang in {hung}'s report", workers, timeout=120)
    batch = ReportBatch.objects.get(kind="participants")
    assert (batch.status, batch.attempts) == ("running", 1)
    lost_claim = batch.claimed_by
    os.kill(doomed.pid, signal.SIGKILL)  # the solo pool's worker is its main process
    assert doomed.wait(10) == -signal.SIGKILL
    before = set(Report.objects.filter(kind="participant").values_list("pk", flat=True))
    assert len(before) == 2  # the hung report's transaction was rolled back
    assert not Report.objects.filter(participant__code=hung).exists()

    ready = tmp_path / "ready"
    workers.start("w1", FAULT_READY=str(ready), **ENV)
    workers.start_beat(tmp_path / "beat-schedule", **ENV)
    wait_until(ready.exists, "the new worker to be ready", workers)
    t_ready = float(ready.read_text())

    def finished() -> bool:
        return not ReportBatch.objects.exclude(status__in=("done", "failed")).exists()

    wait_until(finished, "every batch row to end", workers, timeout=STALE + 120)
    elapsed = time.time() - t_ready
    time.sleep(1)  # a duplicate would show up now
    batch.refresh_from_db()
    assert (batch.status, batch.error, batch.attempts) == ("done", "", 2), batch.error
    assert batch.claimed_by not in ("", lost_claim)  # the task the sweep sent
    assert batch.finished_at is not None
    assert batch.finished_at.timestamp() - t_ready < STALE + 60, elapsed
    summary = ReportBatch.objects.get(kind="summary")
    assert (summary.status, summary.attempts) == ("done", 1)
    reports = Report.objects.filter(comparison=demo)
    assert reports.count() == 13 == reports.filter(status="final", superseded=False).count()
    assert sorted(
        reports.filter(kind="participant").values_list("participant__code", flat=True)
    ) == (sorted(codes))
    assert set(reports.values_list("version", flat=True)) == {1}
    assert before <= set(batch.report_ids) and len(batch.report_ids) == 12
