"""Coordinator review of submissions: accept, reject, ask a lab to check a result.

Every decision is recorded by the audit log (Submission is registered) and in the
submission's message; the lab is told by a notice (labs.notices: its inbox and an e-mail).
"""

from __future__ import annotations

from auditlog.models import LogEntry
from django.contrib.auth.models import User
from django.db import transaction

from common.errors import ValidationFailed
from labs.models import Participant, Result, Submission
from labs.notices import notify_check, notify_decided
from labs.selectors import acceptable_submissions
from labs.services import submission_transition
from proficiency.models import Comparison

DECISIONS = {"accept": Submission.Status.ACCEPTED, "reject": Submission.Status.REJECTED}


@transaction.atomic
def submission_decide(
    *, submission: Submission, decision: str, message: str, user: User | None
) -> Submission:
    """Accept or reject a submitted version; a rejection must say why."""
    if decision not in DECISIONS:
        raise ValidationFailed(f"Unknown decision {decision!r}; use accept or reject.")
    if decision == "reject" and not message.strip():
        raise ValidationFailed("Say why the submission is rejected: the laboratory reads it.")
    decided = submission_transition(submission=submission, to=DECISIONS[decision], message=message)
    notify_decided(decided)
    return decided


@transaction.atomic
def submissions_accept_complete(*, comparison: Comparison, user: User | None) -> list[Submission]:
    """Accept, in one transaction, every submission that is its participant's latest
    version, submitted and undecided, complete for the participant's scope and not asked
    to check (``labs.selectors.ReviewRow.acceptable``); the accepted versions, by code.

    The set is decided here, not taken from the caller: the comparison's participant rows
    are locked first (in pk order), so a new version or a scope change waits
    (``submission_save`` and ``participant_scope_set`` lock the participant), and each
    version is accepted by :func:`submission_decide`, as one at a time would be, with its
    notice. A version decided meanwhile by someone else is left out, not an error."""
    locked = Participant.objects.select_for_update().filter(comparison=comparison)
    list(locked.order_by("pk").values_list("pk", flat=True))
    ids = [row.submission_id for row in acceptable_submissions(comparison)]
    submissions = (
        Submission.objects.select_for_update(of=("self",))
        .select_related("participant__laboratory", "participant__comparison")
        .filter(pk__in=ids, status=Submission.Status.SUBMITTED)
        .order_by("participant__code")
    )
    return [
        submission_decide(submission=s, decision="accept", message="", user=user)
        for s in submissions
    ]


@transaction.atomic
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
    notify_check(submission, result.pk, where)
