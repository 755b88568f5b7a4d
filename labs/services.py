"""Services of the laboratory side: participation codes, submission life cycle."""

from __future__ import annotations

import secrets

from django.db import IntegrityError, transaction
from django.utils import timezone

from labs.models import Laboratory, Participant, Submission
from proficiency.errors import InvalidTransition, StateConflict
from proficiency.models import Comparison

CODE_PREFIX = "L"


def participant_code_new(*, comparison: Comparison) -> str:
    """A random code ``L`` + two digits not yet used in this comparison.

    Drawn with ``secrets`` so it carries nothing of the laboratory (not its name,
    id or join order) and differs between comparisons.  With more than 99
    participants the codes grow to three, then four digits.
    """
    used = set(comparison.participants.values_list("code", flat=True))
    for digits in (2, 3, 4):
        free = [f"{CODE_PREFIX}{n:0{digits}d}" for n in range(1, 10**digits)]
        free = [c for c in free if c not in used]
        if free:
            return secrets.choice(free)
    raise StateConflict(f"Comparison {comparison.code} has no participant codes left.")


def participant_add(
    *, comparison: Comparison, laboratory: Laboratory, is_reference: bool = False
) -> Participant:
    """Invite a laboratory (idempotent: an existing participation is returned unchanged)."""
    existing = Participant.objects.filter(comparison=comparison, laboratory=laboratory).first()
    if existing:
        return existing
    for _ in range(5):  # a concurrent invitation may take the same random code
        try:
            with transaction.atomic():
                return Participant.objects.create(
                    comparison=comparison,
                    laboratory=laboratory,
                    code=participant_code_new(comparison=comparison),
                    is_reference=is_reference,
                )
        except IntegrityError:
            existing = Participant.objects.filter(
                comparison=comparison, laboratory=laboratory
            ).first()
            if existing:
                return existing
    raise StateConflict(f"Could not allocate a participant code in {comparison.code}; retry.")


St = Submission.Status

# The one place where the submission life cycle is defined. Decided versions are
# never edited: a correction is a new version.
SUBMISSION_TRANSITIONS: dict[str, frozenset[str]] = {
    St.DRAFT: frozenset({St.SUBMITTED}),
    St.SUBMITTED: frozenset({St.ACCEPTED, St.REJECTED}),
    St.ACCEPTED: frozenset(),
    St.REJECTED: frozenset(),
}


@transaction.atomic
def submission_transition(*, submission: Submission, to: str, message: str = "") -> Submission:
    """Move a submission to ``to`` if its life cycle allows it, under a row lock."""
    locked = Submission.objects.select_for_update().get(pk=submission.pk)
    if to not in SUBMISSION_TRANSITIONS[locked.status]:
        allowed = ", ".join(sorted(SUBMISSION_TRANSITIONS[locked.status])) or "none (decided)"
        raise InvalidTransition(
            f"Submission version {locked.version} of {locked.participant.code} cannot go from "
            f"{locked.status} to {to}; allowed next status: {allowed}."
        )
    now = timezone.now()
    locked.status = to
    if to == St.SUBMITTED:
        locked.submitted_at = now
    else:
        locked.decided_at = now
        locked.message = message
    locked.save(update_fields=["status", "submitted_at", "decided_at", "message"])
    return locked


def submission_next_version(*, participant: Participant) -> int:
    last = participant.submissions.order_by("-version").values_list("version", flat=True).first()
    return (last or 0) + 1
