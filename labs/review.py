"""Coordinator review of submissions: accept, reject, ask a lab to check a result.

Every decision is recorded by the audit log (Submission is registered) and in the
submission's message; the lab is told by e-mail.
"""

from __future__ import annotations

from auditlog.models import LogEntry
from django.contrib.auth.models import User
from django.core.mail import send_mail

from common.errors import ValidationFailed
from labs.models import Membership, Result, Submission
from labs.services import submission_transition

DECISIONS = {"accept": Submission.Status.ACCEPTED, "reject": Submission.Status.REJECTED}


def _notify(submission: Submission, subject: str, body: str) -> None:
    emails = list(
        Membership.objects.filter(laboratory=submission.participant.laboratory, user__email__gt="")
        .values_list("user__email", flat=True)
        .distinct()
    )
    if emails:
        send_mail(subject, body, None, emails)


def submission_decide(
    *, submission: Submission, decision: str, message: str, user: User | None
) -> Submission:
    """Accept or reject a submitted version; a rejection must say why."""
    if decision not in DECISIONS:
        raise ValidationFailed(f"Unknown decision {decision!r}; use accept or reject.")
    if decision == "reject" and not message.strip():
        raise ValidationFailed("Say why the submission is rejected: the laboratory reads it.")
    decided = submission_transition(submission=submission, to=DECISIONS[decision], message=message)
    code = decided.participant.comparison.code
    _notify(
        decided,
        f"[{code}] submission version {decided.version} {decided.status}",
        message or f"Your submission version {decided.version} was {decided.status}.",
    )
    return decided


def submission_request_check(*, result: Result, user: User | None) -> None:
    """Ask the laboratory to check one result, without telling the size or sign of its
    deviation (CIPM practice): the message names only the measurement point."""
    p = result.measurement_point
    where = f"{p.device.name}, {p.axis}, {p.frequency_hz:g} Hz, {p.bench} {p.direction}"
    submission = result.submission
    LogEntry.objects.log_create(
        submission,
        force_log=True,
        action=LogEntry.Action.ACCESS,
        changes={"check_requested": [None, f"result {result.pk}: {where}"]},
        actor=user if getattr(user, "pk", None) else None,
    )
    _notify(
        submission,
        f"[{submission.participant.comparison.code}] please check a result",
        f"Please check your result for {where} (submission version {submission.version}) "
        "for transcription, unit or calculation errors. If it needs a correction, submit a "
        "new version before the deadline; otherwise no action is needed.",
    )
