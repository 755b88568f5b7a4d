"""Who may see and change what (docs/architecture.md §2, §5): the one access module the web
pages, the API, the raw-data pages, report downloads (analysis.access) and the coordinator
pages ask. Plain functions and querysets.

A caller is either a laboratory (through one of its API keys) or a person
(session). Scope, per comparison:

* participant: a key of a participating laboratory, or a member (staff or
  manager) of one; sees the comparison, its points and its own submissions;
  the published results only once the comparison is published;
* coordinator: a user in ``comparison.coordinators``, or a superuser; sees the
  comparison and every participant's submissions, laboratories by code only;
* lab manager: a member with the manager role; manages the laboratory's API keys and
  applies to open calls for participation (so does a key of the laboratory, which only a
  manager can make);
* applicant: a laboratory that applied to a round sees that round's call and its own
  applications, every member of it (staff too); the round's coordinators see every
  application.

Anything outside the caller's scope is :class:`~common.errors.NotVisible` in the API
(404, never 403) and ``Http404`` on a page, so another laboratory's objects cannot even
be confirmed to exist. 403 is kept for a visible comparison on which the caller lacks the
role (a coordinator who is not a participant trying to submit).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, cast

from django.contrib.auth.models import AnonymousUser, User
from django.db.models import Count, Q, QuerySet
from django.http import Http404, HttpRequest
from rest_framework.exceptions import PermissionDenied
from rest_framework.request import Request

from common.errors import NotVisible, StateConflict, ValidationFailed
from labs.api.authentication import LabKeyPrincipal
from labs.models import Enrolment, Laboratory, Membership, Participant, Result, Submission
from labs.selectors import (
    lab_comparisons,
    participant_for_lab,
    participant_for_user,
    user_laboratories,
)
from proficiency.models import Comparison, ComparisonStatus, MeasurementPoint

if TYPE_CHECKING:
    from common.http import AuthenticatedHttpRequest

# --- people and comparisons ---------------------------------------------------------------


def comparisons_visible_to(user: User | AnonymousUser) -> QuerySet[Comparison]:
    """Comparisons a user may see: superusers all; coordinators theirs; lab members
    those their laboratory takes part in. Anonymous users see none."""
    if not user.is_authenticated:
        return Comparison.objects.none()
    if user.is_superuser:
        return Comparison.objects.all()
    return Comparison.objects.filter(
        Q(coordinators=user) | Q(participants__laboratory__members__user=user)
    ).distinct()


def coordinated_comparisons(user: User) -> QuerySet[Comparison]:
    """Comparisons the user coordinates; a superuser coordinates them all."""
    if user.is_superuser:
        return Comparison.objects.all()
    return Comparison.objects.filter(coordinators=user)


def coordinated(request: AuthenticatedHttpRequest, code: str) -> Comparison:
    """The comparison ``code`` if the user coordinates it; 404 otherwise (no existence leak)."""
    comparison = coordinated_comparisons(request.user).filter(code=code).first()
    if comparison is None:
        raise Http404(f"No comparison {code!r} that you coordinate.")
    return comparison


def participant_page(request: HttpRequest, code: str) -> Participant:
    """The user's participation in comparison ``code`` (a page); 404 otherwise."""
    try:
        return participant_for_user(code=code, user=request.user)
    except NotVisible as exc:
        raise Http404(exc.message) from None


def published_participation(request: HttpRequest, code: str) -> Participant:
    """The user's participation in ``code`` once its results are published (a page); 404
    before, as for a comparison the user does not take part in."""
    participant = participant_page(request, code)
    if participant.comparison.status != ComparisonStatus.PUBLISHED:
        raise Http404(f"The results of {code} are not published yet.")
    return participant


def managed_labs(user: User | AnonymousUser) -> QuerySet[Laboratory]:
    """The laboratories whose API keys the user manages (manager role); none when signed out."""
    if not user.is_authenticated:
        return Laboratory.objects.none()
    return Laboratory.objects.filter(members__user=user, members__role=Membership.Role.MANAGER)


def managed_lab(request: HttpRequest, lab_pk: int) -> Laboratory:
    """A laboratory the user manages; 404 for staff and outsiders (not visible to them)."""
    lab = managed_labs(request.user).filter(pk=lab_pk).first()
    if lab is None:
        raise Http404("No laboratory whose API keys you manage.")
    return lab


# --- API callers ---------------------------------------------------------------------------


@dataclass(frozen=True)
class Caller:
    """A laboratory acting through a key (``user`` is ``None``), or a signed-in person."""

    user: User | None = None
    laboratory: Laboratory | None = None


@dataclass(frozen=True)
class ComparisonAccess:
    comparison: Comparison
    participant: Participant | None
    is_coordinator: bool


def caller_of(request: Request) -> Caller:
    if isinstance(request.user, LabKeyPrincipal):
        return Caller(laboratory=request.user.laboratory)
    return Caller(user=cast(User, request.user))  # IsAuthenticated: a person, if not a key


def comparisons_for(caller: Caller) -> QuerySet[Comparison]:
    """Keys: their laboratory's participations; people: ``comparisons_visible_to``."""
    if caller.laboratory is not None:
        return lab_comparisons(caller.laboratory)
    assert caller.user is not None
    return comparisons_visible_to(caller.user)


def comparison_access(caller: Caller, code: str) -> ComparisonAccess:
    """The caller's roles in comparison ``code``; NotVisible (404) when it has none."""
    if caller.laboratory is not None:
        own = participant_for_lab(code=code, laboratory=caller.laboratory)
        return ComparisonAccess(own.comparison, own, is_coordinator=False)
    user = caller.user
    assert user is not None
    comparison = comparisons_visible_to(user).filter(code=code).first()
    if comparison is None:
        raise NotVisible(f"No comparison {code!r} is visible to you.")
    try:
        participant: Participant | None = participant_for_user(code=code, user=user)
    except NotVisible:
        participant = None
    coordinator = (
        getattr(user, "is_superuser", False) or comparison.coordinators.filter(pk=user.pk).exists()
    )
    return ComparisonAccess(comparison, participant, is_coordinator=coordinator)


def require_participant(access: ComparisonAccess) -> Participant:
    if access.participant is None:
        raise PermissionDenied(
            f"Only a participating laboratory can submit results to {access.comparison.code}; "
            "you coordinate it but your account belongs to no participating laboratory."
        )
    return access.participant


def require_coordinator(access: ComparisonAccess) -> None:
    if not access.is_coordinator:
        raise PermissionDenied(f"Only a coordinator of {access.comparison.code} can do this.")


def published_or_coordinator(access: ComparisonAccess) -> None:
    if access.is_coordinator:
        return
    if access.comparison.status != ComparisonStatus.PUBLISHED:
        raise StateConflict(f"The results of {access.comparison.code} are not published yet.")


def measurement_points(comparison: Comparison) -> QuerySet[MeasurementPoint]:
    return comparison.measurement_points.select_related("device").order_by(
        "device__name", "bench", "direction", "axis", "frequency_hz", "amplitude_m_s2", "pk"
    )


def submissions_in_scope(access: ComparisonAccess, *, counted: bool = True) -> QuerySet[Submission]:
    """Coordinators: every participant's versions; participants: their own; with their
    result count (``n_results``) unless ``counted`` is false."""
    if access.is_coordinator:
        found = Submission.objects.filter(participant__comparison=access.comparison)
    elif access.participant is not None:
        found = Submission.objects.filter(participant=access.participant)
    else:  # pragma: no cover - comparison_access never grants neither role
        found = Submission.objects.none()
    found = found.select_related("participant").order_by("participant__code", "-version")
    return found.annotate(n_results=Count("results")) if counted else found


def submission_in_scope(
    access: ComparisonAccess, *, version: int, participant_code: str | None
) -> Submission:
    """One version: a participant's own, or (coordinators) any participant's by ``?participant``."""
    if participant_code is None:
        if access.participant is None:
            raise ValidationFailed(
                "Say whose submission: add ?participant=<participant code>.",
                errors=[{"row": None, "field": "participant", "message": "is required"}],
            )
        participant_code = access.participant.code
    # not counted: the version's detail lists its results, whose number is n_results
    found = submissions_in_scope(access, counted=False)
    submission = found.filter(participant__code=participant_code, version=version).first()
    if submission is None:
        # The participant code is not echoed: the answer is the same whether it exists or not.
        raise NotVisible(f"No submission version {version} of that participant is visible to you.")
    return submission


def submission_results(submission: Submission) -> QuerySet[Result]:
    return submission.results.select_related("measurement_point__device").order_by(
        "measurement_point__device__name",
        "measurement_point__bench",
        "measurement_point__direction",
        "measurement_point__axis",
        "measurement_point__frequency_hz",
        "pk",
    )


# --- calls for participation and applications (docs/lifecycles.md §7) ----------------------


def member_labs(caller: Caller) -> QuerySet[Laboratory]:
    """The laboratories the caller acts for: a key's own, a person's (staff or manager)."""
    if caller.laboratory is not None:
        return Laboratory.objects.filter(pk=caller.laboratory.pk)
    assert caller.user is not None
    return user_laboratories(caller.user)


def applicant_labs(caller: Caller) -> QuerySet[Laboratory]:
    """The laboratories for which the caller may apply: a key's own (keys are made by the
    laboratory's managers), the ones a person manages."""
    if caller.laboratory is not None:
        return Laboratory.objects.filter(pk=caller.laboratory.pk)
    assert caller.user is not None
    return managed_labs(caller.user)


@dataclass(frozen=True)
class CallAccess:
    comparison: Comparison
    is_coordinator: bool
    #: the laboratories the caller acts for (none for a coordinator alone)
    laboratories: QuerySet[Laboratory]


def call_access(caller: Caller, code: str) -> CallAccess:
    """Comparison ``code`` as a call for participation: visible to its coordinators, to
    everyone while ``enrolment_open`` is set (a closed call then answers 409, not 404), and
    to a laboratory that takes part or applied; NotVisible (404) otherwise."""
    comparison = Comparison.objects.filter(code=code).first()
    labs = member_labs(caller)
    user = caller.user
    coordinator = (
        comparison is not None
        and user is not None
        and (user.is_superuser or comparison.coordinators.filter(pk=user.pk).exists())
    )
    visible = comparison is not None and (
        coordinator
        or comparison.enrolment_open
        or comparison.enrolments.filter(laboratory__in=labs).exists()
        or comparison.participants.filter(laboratory__in=labs).exists()
    )
    if not visible:
        raise NotVisible(f"No comparison {code!r} is visible to you.")
    assert comparison is not None
    return CallAccess(comparison, is_coordinator=coordinator, laboratories=labs)


def applications_in_scope(access: CallAccess) -> QuerySet[Enrolment]:
    """Coordinators: every application to the round; laboratories: their own; newest first."""
    found = access.comparison.enrolments.all()
    if not access.is_coordinator:
        found = found.filter(laboratory__in=access.laboratories)
    return (
        found.select_related("laboratory", "comparison", "participant", "applied_by",
                             "decided_by")
        .prefetch_related("scope_devices")
        .order_by("-created_at", "-id")
    )  # fmt: skip


def application_in_scope(access: CallAccess, pk: int) -> Enrolment:
    application = applications_in_scope(access).filter(pk=pk).first()
    if application is None:
        raise NotVisible(f"No application {pk} to {access.comparison.code} is visible to you.")
    return application


def applying_laboratory(caller: Caller, laboratory_id: int | None = None) -> Laboratory:
    """The laboratory the caller applies for: a key's own; the one a person manages, or the
    one named by ``laboratory_id`` among several. 403 for a member who is no manager (and a
    person in no laboratory); 404 for a laboratory the caller is not a member of."""
    labs = applicant_labs(caller)
    if laboratory_id is not None:
        lab = labs.filter(pk=laboratory_id).first()
        if lab is not None:
            return lab
        if not member_labs(caller).filter(pk=laboratory_id).exists():
            raise NotVisible(f"No laboratory {laboratory_id} is visible to you.")
        labs = labs.none()
    managed = list(labs.order_by("name")[:2])
    if not managed:
        raise PermissionDenied(
            "Only a manager of a laboratory (or one of its API keys) can apply for it; ask "
            "your laboratory's manager."
        )
    if len(managed) > 1:
        raise ValidationFailed(
            "You manage several laboratories: say which one applies.",
            errors=[{"field": "laboratory", "message": "required: the laboratory's id"}],
        )
    return managed[0]


def call_page(request: HttpRequest, code: str) -> CallAccess:
    """:func:`call_access` for a signed-in person's page; 404 otherwise."""
    try:
        return call_access(Caller(user=cast(User, request.user)), code)
    except NotVisible as exc:
        raise Http404(exc.message) from None


def applications_visible_to(user: User | AnonymousUser) -> QuerySet[Enrolment]:
    """The applications of the user's laboratories (every member sees them), newest first."""
    return (
        Enrolment.objects.filter(laboratory__in=user_laboratories(user))
        .select_related("laboratory", "comparison", "participant")
        .prefetch_related("scope_devices")
        .order_by("-created_at", "-id")
    )


def managed_application(request: HttpRequest, pk: int) -> Enrolment:
    """An application of a laboratory the user manages (to withdraw it); 404 otherwise,
    for staff too, as :func:`managed_lab`."""
    application = (
        Enrolment.objects.filter(laboratory__in=managed_labs(request.user), pk=pk)
        .select_related("laboratory", "comparison")
        .first()
    )
    if application is None:
        raise Http404("No application of a laboratory you manage.")
    return application


def coordinated_application(request: AuthenticatedHttpRequest, code: str, pk: int) -> Enrolment:
    """An application to a comparison the user coordinates; 404 otherwise."""
    comparison = coordinated(request, code)
    application = (
        applications_in_scope(
            CallAccess(comparison, is_coordinator=True, laboratories=Laboratory.objects.none())
        )
        .filter(pk=pk)
        .first()
    )
    if application is None:
        raise Http404(f"No application {pk} to {code}.")
    return application
