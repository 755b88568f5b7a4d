"""The broker unreachable when a task is sent: one handler (``common.jobs.send``), and each
caller's outcome: a new analysis run fails with a clear error; a later step of a run, or a
sweep's resend, is left for the next sweep; a new publication fails with a clear error and
publishes nothing; a published round's missing reports are sent later by Celery beat's
``reports_pending_task`` (eager Celery; SQLite or PostgreSQL).

The broker's failure is ``apply_async`` raising what kombu raises for a refused
connection; tests/faults/test_broker_down.py cuts a real one."""

import datetime as dt
import logging

import pytest
from django.utils import timezone
from kombu.exceptions import OperationalError

from analysis import services
from analysis.models import AnalysisRun, Report, ReportBatch
from analysis.publication import BROKER_UNREACHABLE, publication_start
from analysis.reports.services import reports_missing, reports_pending_enqueue
from analysis.services import analysis_run_start, analysis_sweep
from common import jobs
from labs.models import Notice
from tests.analysis.reports.conftest import published_missing_reports
from tests.conftest import use_stand_in_pdf

pytestmark = pytest.mark.django_db(transaction=True)
REFUSED = "Error 111 connecting to 127.0.0.1:6399. Connection refused."
NOTHING = {"runs": 0, "chunks": 0, "finish": 0}


def broker_down(monkeypatch, task_path: str) -> list[tuple]:
    """``apply_async`` of the task at ``task_path`` raises as with the broker down; the
    attempts, recorded."""
    attempts: list[tuple] = []

    def refused(args, kwargs=None, **options):  # delay() calls apply_async(args, kwargs)
        attempts.append(tuple(args))
        raise OperationalError(REFUSED)

    monkeypatch.setattr(f"{task_path}.apply_async", refused)
    return attempts


class Task:
    name = "tests.a_task"

    def __init__(self, error: BaseException | None = None) -> None:
        self.error = error
        self.sent: list[tuple] = []

    def apply_async(self, args, **options):
        if self.error is not None:
            raise self.error
        self.sent.append((args, options))

    def delay(self, *args):
        self.apply_async(args)


@pytest.mark.parametrize("error", [OperationalError(REFUSED), ConnectionRefusedError(111, "x")])
def test_send_logs_calls_back_and_returns_false_with_the_broker_unreachable(error, caplog):
    called = []
    with caplog.at_level(logging.ERROR, logger="common.jobs"):
        sent = jobs.send(Task(error), (7,), what="job 7", on_unreachable=lambda: called.append(1))
    assert sent is False and called == [1]
    assert "job 7: tests.a_task not queued, broker unreachable" in caplog.text


def test_send_passes_its_options_and_raises_every_other_error():
    task = Task()
    assert jobs.send(task, (1, 2), what="job", on_unreachable=pytest.fail)
    assert jobs.send(task, (3,), task_id="t-1", queue="q", what="job")
    assert task.sent == [((1, 2), {}), ((3,), {"task_id": "t-1", "queue": "q"})]
    with pytest.raises(ValueError, match="not the broker"):
        jobs.send(Task(ValueError("not the broker")), (1,), what="job", on_unreachable=pytest.fail)


def test_a_new_run_fails_with_a_clear_error_when_its_task_cannot_be_sent(demo, monkeypatch):
    attempts = broker_down(monkeypatch, "analysis.tasks.analysis_run_task")
    run = analysis_run_start(comparison=demo, user=None)
    run.refresh_from_db()
    assert attempts == [(run.pk,)]
    assert (run.status, run.error) == (
        "failed",
        "The task queue (broker) could not be reached; start the run again.",
    )
    assert run.finished_at is not None
    monkeypatch.undo()  # the broker is back: a new start is a new run, and succeeds
    again = analysis_run_start(comparison=demo, user=None)
    again.refresh_from_db()
    assert again.pk != run.pk and again.status == "succeeded"


def test_a_later_step_that_cannot_be_sent_is_left_to_the_sweep(demo, settings, monkeypatch):
    """The last chunk stored cannot send the final step: the run is not failed, it waits
    (running, every chunk stored) until the sweep sends the step."""
    settings.ANALYSIS_CHUNK_RESULTS = 300  # 3 chunks
    attempts = broker_down(monkeypatch, "analysis.tasks.analysis_finish_task")
    run = analysis_run_start(comparison=demo, user=None)
    run.refresh_from_db()
    assert attempts == [(run.pk,)]
    assert (run.status, run.chunks_done, run.error) == ("running", 3, "")
    AnalysisRun.objects.filter(pk=run.pk).update(heartbeat_at=timezone.now() - dt.timedelta(1))
    assert analysis_sweep() == NOTHING  # the sweep's own send fails too: sent none
    assert len(attempts) == 2
    monkeypatch.undo()
    assert analysis_sweep() == NOTHING  # its lease moved the heartbeat: not silent yet
    AnalysisRun.objects.filter(pk=run.pk).update(heartbeat_at=timezone.now() - dt.timedelta(1))
    assert analysis_sweep() == NOTHING | {"finish": 1}
    run.refresh_from_db()
    assert run.status == "succeeded"


def test_a_lost_pending_run_is_not_failed_by_the_sweep_with_the_broker_down(
    demo, settings, monkeypatch
):
    """The sweep sends through ``common.jobs.send`` without a fallback: the pending run
    stays pending for the next sweep (only a new run's own start fails it)."""
    settings.ANALYSIS_CHUNK_RESULTS = 10**9
    long_ago = timezone.now() - dt.timedelta(hours=2)
    run = AnalysisRun.objects.create(
        comparison=demo, parameters=services._parameters(demo), heartbeat_at=long_ago
    )
    attempts = broker_down(monkeypatch, "analysis.tasks.analysis_run_task")
    assert analysis_sweep() == NOTHING and len(attempts) == 1
    run.refresh_from_db()
    assert (run.status, run.error) == ("pending", "")
    monkeypatch.undo()
    AnalysisRun.objects.filter(pk=run.pk).update(heartbeat_at=long_ago)
    assert analysis_sweep() == NOTHING | {"runs": 1}
    run.refresh_from_db()
    assert run.status == "succeeded"


def test_a_publication_whose_task_cannot_be_sent_fails_and_publishes_nothing(
    demo, monkeypatch, caplog
):
    """The job fails at once with the reason (never pending for ever, blocking the next
    request); the round stays analysed, nobody is told; publishing again works."""
    use_stand_in_pdf(monkeypatch)
    analysis_run_start(comparison=demo, user=None)
    attempts = broker_down(monkeypatch, "analysis.tasks.publication_task")
    with caplog.at_level(logging.ERROR, logger="common.jobs"):
        job = publication_start(comparison=demo)
    job.refresh_from_db()
    assert attempts == [(job.pk,)]
    assert (job.status, job.error) == ("failed", BROKER_UNREACHABLE)
    assert f"publication {job.pk}: analysis.tasks.publication_task not queued" in caplog.text
    demo.refresh_from_db()
    assert demo.status == "analysed"
    assert not Report.objects.exists() and not Notice.objects.filter(kind="published").exists()
    monkeypatch.undo()  # the broker is back
    use_stand_in_pdf(monkeypatch)
    again = publication_start(comparison=demo)
    again.refresh_from_db()
    assert again.status == "succeeded" and again.pk != job.pk


def test_a_published_rounds_missing_reports_wait_for_the_broker(demo, monkeypatch, caplog):
    """The published comparison still missing reports is the outbox: the beat task sends
    the fan-out once the broker is back, and the fan-out makes the batch rows then."""
    use_stand_in_pdf(monkeypatch)
    analysis_run_start(comparison=demo, user=None)
    published = published_missing_reports(demo)
    attempts = broker_down(monkeypatch, "analysis.reports.tasks.reports_issue_all_task")
    with caplog.at_level(logging.ERROR, logger="common.jobs"):
        assert reports_pending_enqueue() == 0
    assert attempts == [(demo.pk,)]
    assert f"reports of comparison {demo.pk}: " in caplog.text
    assert "reports_issue_all_task not queued, broker unreachable" in caplog.text
    assert not Report.objects.exists() and not ReportBatch.objects.exists()
    assert reports_missing(published) == 13
    assert reports_pending_enqueue() == 0  # still down: nothing sent, nothing lost
    monkeypatch.undo()  # the broker is back
    use_stand_in_pdf(monkeypatch)
    assert reports_pending_enqueue() == 1
    assert reports_missing(published) == 0
    assert Report.objects.filter(status="final", superseded=False).count() == 13
    assert set(ReportBatch.objects.values_list("status", flat=True)) == {"done"}
