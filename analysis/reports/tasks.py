"""Celery tasks issuing reports. They take ids and re-check state, so they are safe twice.

Imported by :mod:`analysis.tasks` so that Celery's autodiscovery registers them.
"""

from __future__ import annotations

from celery import group, shared_task
from django.conf import settings

LIMITS = {
    "soft_time_limit": settings.CELERY_TASK_SOFT_TIME_LIMIT,
    "time_limit": settings.CELERY_TASK_TIME_LIMIT,
}


@shared_task(acks_late=True, reject_on_worker_lost=True, **LIMITS)
def report_issue_task(run_id: int, kind: str, participant_id: int | None) -> int | None:
    """Issue one report of run ``run_id`` unless a current one exists; its id."""
    from analysis.reports.services import report_issue_once

    report = report_issue_once(run_id=run_id, kind=kind, participant_id=participant_id)
    return report.pk if report else None


@shared_task(**LIMITS)
def reports_issue_all_task(comparison_id: int) -> int:
    """Fan out: one ``report_issue_task`` per report of the comparison (a group)."""
    from analysis.reports.services import report_jobs
    from proficiency.models import Comparison

    jobs = report_jobs(Comparison.objects.get(pk=comparison_id))
    group(report_issue_task.s(*job) for job in jobs).apply_async()
    return len(jobs)
