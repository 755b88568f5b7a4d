"""Celery tasks issuing reports. They take ids and re-check state, so they are safe twice.

Imported by :mod:`analysis.tasks` so that Celery's autodiscovery registers them.
"""

from __future__ import annotations

from celery import group, shared_task
from django.conf import settings

from proficiency.models import Comparison

LIMITS = {
    "soft_time_limit": settings.CELERY_TASK_SOFT_TIME_LIMIT,
    "time_limit": settings.CELERY_TASK_TIME_LIMIT,
}


@shared_task(acks_late=True, reject_on_worker_lost=True, **LIMITS)
def report_issue_task(run_id: int, kind: str, participant_id: int | None) -> int | None:
    """Issue one report of run ``run_id`` unless a current one exists; its id."""
    # in the body: the service module imports this one to enqueue the task (a cycle)
    from analysis.reports.services import report_issue_once

    report = report_issue_once(run_id=run_id, kind=kind, participant_id=participant_id)
    return report.pk if report else None


@shared_task(acks_late=True, reject_on_worker_lost=True, **LIMITS)
def report_issue_batch_task(run_id: int, participant_ids: list[int]) -> list[int]:
    """Issue the participant reports of a batch of participants (those not issued yet);
    the ids of their reports.  Acknowledged late: a batch lost with its worker is
    delivered again and skips the reports already stored."""
    # in the body: the service module imports this one to enqueue the task (a cycle)
    from analysis.reports.services import report_issue_batch

    return report_issue_batch(run_id=run_id, participant_ids=participant_ids)


@shared_task(**LIMITS)
def reports_issue_all_task(comparison_id: int) -> int:
    """Fan out, as one group: the summary's ``report_issue_task``, then one
    ``report_issue_batch_task`` per batch of ``settings.REPORTS_BATCH_SIZE`` participants
    (one task per report spent more time on the broker and on re-reading the round's
    shared data than on the report itself).  The number of reports."""
    # in the body: the service module imports this one to enqueue the task (a cycle)
    from analysis.reports.services import report_batches

    run_id, batches = report_batches(Comparison.objects.get(pk=comparison_id))
    summary = report_issue_task.s(run_id, "summary", None)
    group([summary, *(report_issue_batch_task.s(run_id, b) for b in batches)]).apply_async()
    return 1 + sum(len(b) for b in batches)
