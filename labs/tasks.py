"""Celery tasks of the laboratory side. Tasks take ids and re-check state (safe to run twice)."""

import datetime as dt

from axes.models import AccessLog
from celery import shared_task
from django.conf import settings
from django.contrib.sessions.models import Session
from django.utils import timezone

from labs.models import SubmissionKey


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
    # in the body: the service module imports this one to enqueue the task (a cycle)
    from labs.raw_services import raw_recompute_execute

    return raw_recompute_execute(record_id=record_id, delivery=self.request.id or "")


# Periodic housekeeping, run by Celery beat (``CELERY_BEAT_SCHEDULE`` in settings).
# Idempotent: it deletes only what is already expired, so a second run (or two beats by
# mistake) removes nothing more. Here, not in proficiency: it deletes labs' rows.
# The name it had in proficiency.tasks: the beat schedule and queued messages keep working.
@shared_task(name="proficiency.tasks.housekeeping", soft_time_limit=300, time_limit=360)
def housekeeping() -> dict[str, int]:
    """Delete expired sessions, sign-in records older than ``LOGIN_LOG_RETENTION_DAYS`` and
    submission Idempotency-Keys older than ``IDEMPOTENCY_KEY_HOURS``."""
    now = timezone.now()
    sessions, _ = Session.objects.filter(expire_date__lt=now).delete()
    keep = dt.timedelta(days=settings.LOGIN_LOG_RETENTION_DAYS)
    logins, _ = AccessLog.objects.filter(attempt_time__lt=now - keep).delete()
    key_age = dt.timedelta(hours=settings.IDEMPOTENCY_KEY_HOURS)
    keys, _ = SubmissionKey.objects.filter(created_at__lt=now - key_age).delete()
    return {"sessions": sessions, "login_records": logins, "submission_keys": keys}


@shared_task(bind=True, acks_late=True, reject_on_worker_lost=True, soft_time_limit=60,
             time_limit=90)  # fmt: skip
def notice_email_task(self, notice_id: int) -> bool:
    """E-mail notice ``notice_id`` to its laboratory's members; a second delivery finds the
    notice claimed and sends nothing (docs/lifecycles.md §6)."""
    # in the body: the service module imports this one to enqueue the task (a cycle)
    from labs.notices import notice_email_send

    return notice_email_send(notice_id=notice_id)


# Run by Celery beat (``CELERY_BEAT_SCHEDULE``): each reminder and each notice is made once
# (its dedupe key), so a second run, or two beats, send nothing more.
@shared_task(soft_time_limit=300, time_limit=360)
def notices_reminders_task() -> dict[str, int]:
    """Deadline reminders due now, and notices whose e-mail was never sent, queued again."""
    from labs.notices import notices_resend, reminders_send  # as above: a cycle

    return {"reminders": reminders_send(), "resent": notices_resend()}
