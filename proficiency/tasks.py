"""Periodic housekeeping, run by Celery beat (``CELERY_BEAT_SCHEDULE`` in settings).

Idempotent: it deletes only what is already expired, so a second run (or two beats
by mistake) removes nothing more.
"""

from __future__ import annotations

import datetime as dt

from celery import shared_task
from django.conf import settings
from django.utils import timezone


@shared_task(soft_time_limit=300, time_limit=360)
def housekeeping() -> dict[str, int]:
    """Delete expired sessions, sign-in records older than ``LOGIN_LOG_RETENTION_DAYS`` and
    submission Idempotency-Keys older than ``IDEMPOTENCY_KEY_HOURS``."""
    from axes.models import AccessLog
    from django.contrib.sessions.models import Session

    from labs.models import SubmissionKey

    now = timezone.now()
    sessions, _ = Session.objects.filter(expire_date__lt=now).delete()
    keep = dt.timedelta(days=settings.LOGIN_LOG_RETENTION_DAYS)
    logins, _ = AccessLog.objects.filter(attempt_time__lt=now - keep).delete()
    key_age = dt.timedelta(hours=settings.IDEMPOTENCY_KEY_HOURS)
    keys, _ = SubmissionKey.objects.filter(created_at__lt=now - key_age).delete()
    return {"sessions": sessions, "login_records": logins, "submission_keys": keys}
