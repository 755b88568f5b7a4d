"""Notices: the messages a laboratory is sent about a comparison (docs/lifecycles.md §6).

One service, :func:`notify`, makes the notice of an event for the addressed laboratory
(once: its ``dedupe_key`` is unique) and, after commit, e-mails the laboratory's members
(text and HTML, rendered from ``templates/notices/``; links made absolute with
``SITE_URL``). The e-mail is sent by a Celery task where a broker is configured
(in-process otherwise); the task claims the notice with a conditional update, so a task
delivered twice sends one e-mail. The inbox reads and marks notices through the
selectors and services here too.
"""

from __future__ import annotations

import datetime as dt
import logging
from collections.abc import Mapping
from typing import Any

from django.conf import settings
from django.contrib.auth.models import AnonymousUser, User
from django.core.mail import EmailMultiAlternatives
from django.db import IntegrityError, transaction
from django.db.models import QuerySet
from django.template.loader import render_to_string
from django.urls import reverse
from django.utils import timezone

from common.jobs import send
from labs.models import Enrolment, Laboratory, Membership, Notice, Participant, Submission
from labs.tasks import notice_email_task
from proficiency.models import Comparison, ComparisonStatus, reminder_days_parse

log = logging.getLogger(__name__)

K = Notice.Kind

#: a notice whose e-mail was not sent (broker unreachable) is sent again by the beat task
#: for this long after it was made; older ones stay in the inbox only
RESEND_WITHIN = dt.timedelta(days=1)
#: ... once it is this old (the after-commit send has had its chance)
RESEND_AFTER = dt.timedelta(minutes=10)


def absolute(path: str) -> str:
    """``SITE_URL`` + ``path``: the link an e-mail carries."""
    return f"{settings.SITE_URL}{path}" if path else ""


def lab_comparison_path(comparison: Comparison) -> str:
    return reverse("labs:comparison", args=[comparison.code])


def lab_submission_path(submission: Submission, comparison: Comparison) -> str:
    return reverse("labs:submission", args=[comparison.code, submission.version])


def notify(
    *,
    kind: str,
    participant: Participant,
    dedupe_key: str,
    link: str,
    context: Mapping[str, Any] | None = None,
) -> Notice | None:
    """The notice of one event to ``participant``'s laboratory; ``None`` when this event
    (``dedupe_key``) was already noticed, which changes nothing.

    The subject and body are rendered from ``notices/<kind>_subject.txt`` and
    ``notices/<kind>.txt`` with ``context`` plus the comparison, participant, laboratory,
    the absolute ``link_url`` and the provider's name. The e-mail goes after commit.
    """
    return notify_laboratory(
        kind=kind, laboratory=participant.laboratory, comparison=participant.comparison,
        participant=participant, dedupe_key=dedupe_key, link=link, context=context,
    )  # fmt: skip


def notify_laboratory(
    *,
    kind: str,
    laboratory: Laboratory,
    comparison: Comparison,
    dedupe_key: str,
    link: str,
    participant: Participant | None = None,
    context: Mapping[str, Any] | None = None,
) -> Notice | None:
    """:func:`notify` for a laboratory that need not take part (yet): an application's
    receipt or its refusal (``participant`` None)."""
    if kind not in K.values:
        raise ValueError(f"unknown notice kind {kind!r}")
    if Notice.objects.filter(dedupe_key=dedupe_key).exists():
        return None
    values = {
        "comparison": comparison,
        "participant": participant,
        "laboratory": laboratory,
        "link_url": absolute(link),
        "site_url": settings.SITE_URL,
        "provider": settings.PT_PROVIDER_NAME,
        **(context or {}),
    }
    subject = " ".join(render_to_string(f"notices/{kind}_subject.txt", values).split())
    body = render_to_string(f"notices/{kind}.txt", values).strip()
    try:
        with transaction.atomic():  # a savepoint: a concurrent twin leaves the caller intact
            notice = Notice.objects.create(
                laboratory=laboratory,
                comparison=comparison,
                participant=participant,
                kind=kind,
                subject=subject[:200],
                body=body,
                link=link,
                dedupe_key=dedupe_key,
            )
    except IntegrityError:
        if Notice.objects.filter(dedupe_key=dedupe_key).exists():
            return None
        raise
    pk = notice.pk
    # robust: a mail server or broker failing after commit never undoes the event
    transaction.on_commit(lambda: notice_email_enqueue(notice_id=pk), robust=True)
    return notice


def notice_email_enqueue(*, notice_id: int) -> bool:
    """Send the notice's e-mail through the Celery task (in-process without a broker);
    with the broker unreachable, the beat task sends it later."""
    return send(notice_email_task, (notice_id,), task_id=None, what=f"notice {notice_id}")


def addressees(laboratory: Laboratory) -> list[str]:
    """The e-mail addresses of the laboratory's active members, sorted, once each."""
    emails = Membership.objects.filter(
        laboratory=laboratory, user__is_active=True, user__email__gt=""
    ).values_list("user__email", flat=True)
    return sorted(set(emails))


def laboratories_with_addressees(laboratory_ids: list[int]) -> set[int]:
    """Which of these laboratories a notice is e-mailed to (:func:`addressees` is not
    empty); one query."""
    found = Membership.objects.filter(
        laboratory_id__in=laboratory_ids, user__is_active=True, user__email__gt=""
    ).values_list("laboratory_id", flat=True)
    return set(found)


def notice_email_send(*, notice_id: int) -> bool:
    """E-mail a notice to its laboratory's members, once: the notice is claimed by a
    conditional update of ``emailed_at`` (a second delivery finds it claimed and sends
    nothing), released again if sending fails. False when nothing was sent."""
    notice = (
        Notice.objects.select_related("laboratory", "comparison", "participant")
        .filter(pk=notice_id)
        .first()
    )
    if notice is None or notice.emailed_at is not None:
        return False
    emails = addressees(notice.laboratory)
    if not emails:
        log.warning("notice %s: laboratory %s has no member with an e-mail", notice.pk,
                    notice.laboratory_id)  # fmt: skip
        return False
    now = timezone.now()
    claimed = Notice.objects.filter(pk=notice.pk, emailed_at__isnull=True).update(
        emailed_at=now, emailed_to=", ".join(emails)
    )
    if not claimed:
        return False
    values = {
        "notice": notice,
        "comparison": notice.comparison,
        "participant": notice.participant,
        "laboratory": notice.laboratory,
        "link_url": absolute(notice.link),
        "inbox_url": absolute(reverse("labs:dashboard")),
        "provider": settings.PT_PROVIDER_NAME,
    }
    message = EmailMultiAlternatives(
        notice.subject, render_to_string("notices/email.txt", values), None, emails
    )
    message.attach_alternative(render_to_string("notices/email.html", values), "text/html")
    try:
        message.send()
    except Exception:
        Notice.objects.filter(pk=notice.pk, emailed_at=now).update(emailed_at=None, emailed_to="")
        raise
    return True


def notices_resend(*, now: dt.datetime | None = None) -> int:
    """Queue again the e-mails of recent notices that were never sent (e.g. the broker was
    down at commit); the number queued."""
    now = now or timezone.now()
    pending = Notice.objects.filter(
        emailed_at__isnull=True,
        created_at__gte=now - RESEND_WITHIN,
        created_at__lt=now - RESEND_AFTER,
        laboratory__members__user__email__gt="",
    ).distinct()
    return sum(notice_email_enqueue(notice_id=pk) for pk in pending.values_list("pk", flat=True))


# --- the events -----------------------------------------------------------------------------


def notify_invited(participant: Participant) -> Notice | None:
    return notify(
        kind=K.INVITATION,
        participant=participant,
        dedupe_key=f"invitation:{participant.pk}",
        link=lab_comparison_path(participant.comparison),
    )


def notify_opened(comparison: Comparison) -> int:
    """Every participant of an opened (or reopened) comparison; once per deadline, so a
    reopening with a new deadline is told again. The number of notices made."""
    deadline = comparison.submission_deadline
    stamp = deadline.isoformat() if deadline else "none"
    made = 0
    for participant in comparison.participants.select_related("laboratory", "comparison"):
        made += bool(
            notify(
                kind=K.OPENED,
                participant=participant,
                dedupe_key=f"opened:{participant.pk}:{stamp}",
                link=lab_comparison_path(comparison),
            )
        )
    return made


def _about(submission: Submission, kind: str, key: str, **context: object) -> Notice | None:
    """A notice about one submitted version, linking to the laboratory's page of it."""
    participant = submission.participant
    return notify(
        kind=kind,
        participant=participant,
        dedupe_key=key,
        link=lab_submission_path(submission, participant.comparison),
        context={"submission": submission, **context},
    )


def notify_receipt(submission: Submission, n_results: int) -> Notice | None:
    """The receipt of a submitted version: what was stored (count, version, checksum)."""
    return _about(submission, K.RECEIPT, f"receipt:{submission.pk}", n_results=n_results)


def notify_decided(submission: Submission) -> Notice | None:
    kind = K.ACCEPTED if submission.status == Submission.Status.ACCEPTED else K.REJECTED
    return _about(submission, kind, f"decision:{submission.pk}")


def notify_check(submission: Submission, result_id: int, where: str) -> Notice | None:
    """A request to check one result, naming only its point (never the deviation); once
    per result."""
    return _about(submission, K.CHECK, f"check:{result_id}", where=where)


def _about_application(enrolment: Enrolment, kind: str, **context: object) -> Notice | None:
    """A notice about an application, linking to the laboratory's Open calls page (which
    lists its applications)."""
    return notify_laboratory(
        kind=kind,
        laboratory=enrolment.laboratory,
        comparison=enrolment.comparison,
        dedupe_key=f"{kind}:{enrolment.pk}",
        link=reverse("labs:calls"),
        context={"enrolment": enrolment, **context},
    )


def notify_applied(enrolment: Enrolment, scope: str) -> Notice | None:
    """The receipt of an application: what was asked for (``scope`` in words) and what
    happens next."""
    return _about_application(enrolment, K.APPLIED, scope=scope)


def notify_declined(enrolment: Enrolment) -> Notice | None:
    """An application declined, with the coordinator's reason."""
    return _about_application(enrolment, K.DECLINED)


def reminders_send(*, now: dt.datetime | None = None) -> int:
    """Remind every participant of an open comparison that has not submitted yet, N days
    before the deadline for each N of ``reminder_days``: once per participant, N and
    deadline (a moved deadline has reminders of its own). When several N are due at once
    (e.g. a comparison opened late) only the nearest is sent. The number sent."""
    now = now or timezone.now()
    made = 0
    comparisons = Comparison.objects.filter(
        status=ComparisonStatus.OPEN, submission_deadline__gt=now
    ).exclude(reminder_days="")
    for comparison in comparisons:
        deadline = comparison.submission_deadline
        assert deadline is not None
        try:
            days = reminder_days_parse(comparison.reminder_days)
        except ValueError as exc:  # only the admin can store a bad list (the form checks)
            log.warning("reminders of %s skipped: %s", comparison.code, exc)
            continue
        due = [n for n in days if now >= deadline - dt.timedelta(days=n)]
        if not due:
            continue
        n = due[0]
        waiting = comparison.participants.exclude(
            submissions__submitted_at__isnull=False
        ).select_related("laboratory", "comparison")
        for participant in waiting:
            made += bool(
                notify(
                    kind=K.REMINDER,
                    participant=participant,
                    dedupe_key=f"reminder:{participant.pk}:{n}:{deadline.isoformat()}",
                    link=lab_comparison_path(comparison),
                    context={"days": n, "deadline": deadline},
                )
            )
    return made


# --- the inbox --------------------------------------------------------------------------------


def notices_for(user: User | AnonymousUser) -> QuerySet[Notice]:
    """The notices of the user's laboratories, newest first; none when signed out."""
    if not user.is_authenticated:
        return Notice.objects.none()
    return (
        Notice.objects.filter(laboratory__members__user=user)
        .select_related("laboratory", "comparison", "participant")
        .order_by("-created_at", "-id")
    )


def notices_unread_count(user: User | AnonymousUser) -> int:
    return notices_for(user).filter(read_at__isnull=True).count()


def notice_mark_read(*, notice: Notice) -> Notice:
    """Mark a notice read (idempotent: the first reading time is kept)."""
    if notice.read_at is None:
        now = timezone.now()
        Notice.objects.filter(pk=notice.pk, read_at__isnull=True).update(read_at=now)
        notice.read_at = now
    return notice


def notices_of_comparison(comparison: Comparison) -> QuerySet[Notice]:
    """What was sent to whom about a comparison (the coordinator's list), newest first."""
    return Notice.objects.filter(comparison=comparison).select_related("laboratory", "participant")
