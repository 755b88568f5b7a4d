"""Celery tasks of the laboratory side. Tasks take ids and re-check state (safe to run twice)."""

from celery import shared_task
from django.conf import settings


@shared_task(
    bind=True,
    acks_late=True,
    reject_on_worker_lost=True,
    soft_time_limit=settings.CELERY_TASK_SOFT_TIME_LIMIT,
    time_limit=settings.CELERY_TASK_TIME_LIMIT,
)
def raw_recompute_task(self, record_id: int) -> str:
    """Recompute the sensitivity of raw record ``record_id`` (claimed with a conditional
    update: a second delivery finds it done and changes nothing)."""
    from labs.raw_services import raw_recompute_execute

    return raw_recompute_execute(record_id=record_id, delivery=self.request.id or "")
