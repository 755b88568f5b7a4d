"""Celery tasks issuing reports. They take ids and re-check state, so they are safe twice.

The fan-out makes one ``ReportBatch`` row per task it sends (the summary, and each batch
of participants) and passes the row's id: the task claims that row, beats while the
reports render and ends it done or failed (docs/lifecycles.md §4).  A message without a
row id (sent before the rows existed) issues its reports as before, without a row.

Imported by :mod:`analysis.tasks` so that Celery's autodiscovery registers them.
"""

from __future__ import annotations

from celery import shared_task
from django.conf import settings

from proficiency.models import Comparison

LIMITS = {
    "soft_time_limit": settings.CELERY_TASK_SOFT_TIME_LIMIT,
    "time_limit": settings.CELERY_TASK_TIME_LIMIT,
}


@shared_task(bind=True, acks_late=True, reject_on_worker_lost=True, **LIMITS)
def report_issue_task(
    self, run_id: int, kind: str, participant_id: int | None, batch_id: int | None = None
) -> int | None:
    """Issue one report of run ``run_id`` unless a current one exists; its id.  With
    ``batch_id`` (the fan-out's summary) under the claim of that batch row."""
    # in the body: the service module imports this one to enqueue the task (a cycle)
    from analysis.reports.services import report_batch_execute, report_issue_once

    if batch_id is not None:
        ids = report_batch_execute(batch_id=batch_id, delivery=self.request.id or "")
        return ids[0] if ids else None
    report = report_issue_once(run_id=run_id, kind=kind, participant_id=participant_id)
    return report.pk if report else None


@shared_task(bind=True, acks_late=True, reject_on_worker_lost=True, **LIMITS)
def report_issue_batch_task(
    self, run_id: int, participant_ids: list[int], batch_id: int | None = None
) -> list[int]:
    """Issue the participant reports of a batch of participants (those not issued yet);
    the ids of their reports.  With ``batch_id`` under the claim of that batch row.
    Acknowledged late: a batch lost with its worker is delivered again, takes its own
    claim over and skips the reports already stored."""
    # in the body: the service module imports this one to enqueue the task (a cycle)
    from analysis.reports.services import report_batch_execute, report_issue_batch

    if batch_id is not None:
        return report_batch_execute(batch_id=batch_id, delivery=self.request.id or "")
    return report_issue_batch(run_id=run_id, participant_ids=participant_ids)


@shared_task(**LIMITS)
def reports_issue_all_task(comparison_id: int) -> int:
    """Fan out: the current run's batch rows, made once (the summary, then one per batch
    of ``settings.REPORTS_BATCH_SIZE`` participants: one task per report spent more time
    on the broker and on re-reading the round's shared data than on the report itself),
    and a ``report_issue_task`` / ``report_issue_batch_task`` for each row still to do.
    The number of reports."""
    # in the body: the service module imports this one to enqueue the task (a cycle)
    from analysis.reports.services import report_batches_send

    return report_batches_send(comparison=Comparison.objects.get(pk=comparison_id))
