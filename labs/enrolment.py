"""Enrolment: a laboratory applies to a round whose call is open, with the scope it asks
for; a coordinator accepts (the laboratory is invited as by ``participants_invite``: a
random code, the scope, the invitation notice) or declines with a reason; the laboratory
may withdraw a pending application (docs/lifecycles.md §7)."""

from __future__ import annotations

from django.contrib.auth.models import User
from django.db import IntegrityError, transaction
from django.utils import timezone

from common.errors import StateConflict, ValidationFailed
from labs.models import Enrolment, Laboratory, Participant
from labs.notices import notify_applied, notify_declined
from labs.selectors import scope_text
from labs.services import Scope, _scope_clean, _scope_store, participants_invite
from proficiency.models import Comparison, ComparisonStatus
from proficiency.services import enrolment_check

Es = Enrolment.Status
#: statuses that hold a laboratory's one live application to a round
LIVE = (Es.PENDING, Es.ACCEPTED)
#: the longest note a laboratory may add, and the longest reason for declining
NOTE_MAX_CHARS = 2_000


def enrolment_scope(enrolment: Enrolment) -> Scope:
    """The scope an application asks for, as :func:`participants_invite` takes it."""
    return Scope(
        devices=list(enrolment.scope_devices.all()),
        benches=list(enrolment.scope_benches),
        axes=list(enrolment.scope_axes),
        frequencies_hz=list(enrolment.scope_frequencies_hz),
    )


def _text(value: str, field: str, *, required: bool) -> str:
    text = value.strip()
    if required and not text:
        raise ValidationFailed(
            "Give the laboratory the reason for declining: it reads it.",
            errors=[{"field": field, "message": "is required"}],
        )
    if len(text) > NOTE_MAX_CHARS:
        raise ValidationFailed(
            f"The {field} is {len(text):,} characters long; at most {NOTE_MAX_CHARS:,}.",
            errors=[{"field": field, "message": f"at most {NOTE_MAX_CHARS:,} characters"}],
        )
    return text


def _already(laboratory: Laboratory, comparison: Comparison) -> None:
    """StateConflict when the laboratory takes part or has a live application already."""
    if Participant.objects.filter(comparison=comparison, laboratory=laboratory).exists():
        raise StateConflict(f"{laboratory.name} already takes part in {comparison.code}.")
    live = Enrolment.objects.filter(
        comparison=comparison, laboratory=laboratory, status__in=LIVE
    ).first()
    if live is not None:
        raise StateConflict(
            f"{laboratory.name} already applied to {comparison.code} on "
            f"{live.created_at:%Y-%m-%d}; that application is {live.status}."
        )


def enrolment_apply_check(comparison: Comparison, laboratory: Laboratory | None) -> None:
    """StateConflict (409) saying why ``laboratory`` cannot apply to ``comparison`` now: it
    takes part or applied already, or the call is not open (the page shows the same)."""
    if laboratory is not None:
        _already(laboratory, comparison)
    enrolment_check(comparison)


@transaction.atomic
def enrolment_apply(
    *,
    comparison: Comparison,
    laboratory: Laboratory,
    scope: Scope,
    note: str = "",
    user: User | None = None,
    notify: bool = True,
) -> Enrolment:
    """The laboratory's application to ``comparison`` with the ``scope`` it asks for (an
    empty one: every point), all or nothing: StateConflict (409) when the call is not open,
    the laboratory takes part already or has a pending or accepted application; the scope
    checked as an invitation's (ValidationFailed naming each bad value). The laboratory is
    sent a receipt (docs/lifecycles.md §6) unless ``notify`` is False (the demo's data)."""
    enrolment_apply_check(comparison, laboratory)
    text = _text(note, "note", required=False)
    clean = _scope_clean(comparison, scope)
    try:
        with transaction.atomic():  # a twin applying at the same moment
            enrolment = Enrolment.objects.create(
                comparison=comparison, laboratory=laboratory, note=text, applied_by=user
            )
    except IntegrityError:
        _already(laboratory, comparison)
        raise
    _scope_store(enrolment, clean)
    if notify:
        notify_applied(enrolment, scope_text(enrolment))
    return enrolment


def _pending(enrolment: Enrolment, verb: str) -> Enrolment:
    """The application under its row lock, if still pending; StateConflict otherwise."""
    locked = (
        Enrolment.objects.select_for_update(of=("self",))
        .select_related("laboratory", "comparison")
        .get(pk=enrolment.pk)
    )
    if locked.status != Es.PENDING:
        raise StateConflict(
            f"The application of {locked.laboratory.name} to {locked.comparison.code} is "
            f"{locked.status}: only a pending application can be {verb}."
        )
    return locked


def _decided(locked: Enrolment, status: str, user: User | None, **fields: object) -> Enrolment:
    locked.status = status
    locked.decided_by = user
    locked.decided_at = timezone.now()
    for name, value in fields.items():
        setattr(locked, name, value)
    locked.save(update_fields=["status", "decided_by", "decided_at", *fields])
    return locked


@transaction.atomic
def enrolment_accept(
    *, enrolment: Enrolment, user: User | None, scope: Scope | None = None
) -> Enrolment:
    """Accept a pending application: the laboratory is invited through
    :func:`participants_invite` (a random code, ``scope`` — the requested one when None —,
    the invitation notice), and the application keeps the participant. StateConflict when
    it is not pending, the round is published, or the laboratory was invited meanwhile;
    a scope that no longer fits the round is refused as an invitation's."""
    locked = _pending(enrolment, "accepted")
    comparison = locked.comparison
    if comparison.status == ComparisonStatus.PUBLISHED:
        raise StateConflict(f"{comparison.code} is published: it takes no new participant.")
    if Participant.objects.filter(comparison=comparison, laboratory=locked.laboratory).exists():
        raise StateConflict(
            f"{locked.laboratory.name} already takes part in {comparison.code} (invited "
            "meanwhile); decline the application or leave it."
        )
    chosen = scope if scope is not None else enrolment_scope(locked)
    (participant,) = participants_invite(
        comparison=comparison, laboratories=[locked.laboratory], scope=chosen
    )
    return _decided(locked, Es.ACCEPTED, user, participant=participant)


@transaction.atomic
def enrolment_decline(*, enrolment: Enrolment, user: User | None, reason: str) -> Enrolment:
    """Decline a pending application with a ``reason`` (required), which the laboratory is
    sent in a notice; no participant is made."""
    text = _text(reason, "reason", required=True)
    locked = _pending(enrolment, "declined")
    declined = _decided(locked, Es.DECLINED, user, reason=text)
    notify_declined(declined)
    return declined


@transaction.atomic
def enrolment_withdraw(*, enrolment: Enrolment, user: User | None) -> Enrolment:
    """The laboratory takes back its pending application (it may apply again later)."""
    return _decided(_pending(enrolment, "withdrawn"), Es.WITHDRAWN, user)
