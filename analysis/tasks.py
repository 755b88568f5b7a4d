"""Celery tasks of the analysis side. Tasks take ids and re-check state (safe to run twice)."""

from celery import shared_task
from django.conf import settings

from analysis.reports.tasks import report_issue_task, reports_issue_all_task  # noqa: F401


@shared_task(
    acks_late=True,
    reject_on_worker_lost=True,
    soft_time_limit=settings.CELERY_TASK_SOFT_TIME_LIMIT,
    time_limit=settings.CELERY_TASK_TIME_LIMIT,
)
def analysis_run_task(run_id: int) -> str:
    """Execute analysis run ``run_id`` (claimed with a conditional update)."""
    from analysis.services import analysis_run_execute

    return analysis_run_execute(run_id=run_id)
