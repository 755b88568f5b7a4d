"""Coordinator web pages: dashboard, comparison setup, invitations, review.

Thin views: find the comparison the user coordinates (404 for anyone else, also for the
coordinator of another comparison), call one service, render.  The analysis and results
pages live in ``analysis.views``.
"""

from __future__ import annotations

import statistics
from collections import Counter, defaultdict
from typing import TYPE_CHECKING, cast

from django import forms
from django.contrib import messages
from django.contrib.auth.decorators import login_required
from django.core.paginator import EmptyPage, Page, PageNotAnInteger, Paginator
from django.db.models import (
    Case,
    Count,
    OuterRef,
    Q,
    QuerySet,
    Subquery,
    When,
)
from django.http import Http404, HttpResponse, QueryDict
from django.shortcuts import get_object_or_404, redirect, render
from django.urls import reverse
from django.views.decorators.http import require_GET, require_http_methods, require_POST

from analysis.reports.services import report_notes_update
from common.errors import ApplicationError, NotVisible, refusal
from common.pagination import CountSparingPaginator
from common.points import format_number
from common.sizes import counted
from coordination.confirm import ACTIONS, confirmation
from coordination.forms import (
    ComparisonCreateForm,
    ComparisonForm,
    DecisionForm,
    DeclineForm,
    DeviceForm,
    InviteForm,
    PointGridForm,
    PointOverrideForm,
    ReportNotesForm,
    ReviewFilterForm,
    ScopeForm,
)
from labs import services as labs_services
from labs.access import coordinated, coordinated_application, coordinated_comparisons
from labs.enrolment import enrolment_accept, enrolment_decline, enrolment_scope
from labs.models import Enrolment, Participant, Result, Submission
from labs.notices import notices_of_comparison
from labs.raw_selectors import raw_record_figure, raw_records_of_comparison
from labs.review import submission_decide, submission_request_check, submissions_accept_complete
from labs.selectors import (
    ReviewRow,
    current_submissions,
    participant_points,
    review_rows,
    scope_text,
)
from labs.services import comparison_move, participant_set_reference
from proficiency import protocols, services
from proficiency.models import Comparison, ComparisonStatus, MeasurementPoint
from proficiency.selectors import POINT_ORDER
from proficiency.services import (
    comparison_allowed_transitions,
    comparison_apply_template,
    enrolment_check,
    measurement_points_generate,
)

if TYPE_CHECKING:
    from django.contrib.auth.models import User

    from common.http import AuthenticatedHttpRequest

St = Submission.Status


def _may_create(user: User) -> bool:
    return user.has_perm("proficiency.add_comparison")


def _latest_status(participants: QuerySet[Participant]) -> QuerySet[Participant]:
    latest = Submission.objects.filter(participant=OuterRef("pk")).order_by("-version")
    return participants.annotate(
        latest_status=Subquery(latest.values("status")[:1]),
        latest_version=Subquery(latest.values("version")[:1]),
        latest_results=Subquery(latest.annotate(n=Count("results")).values("n")[:1]),
    )


# --- dashboard and settings ---------------------------------------------------------------


@login_required
@require_GET
def dashboard(request: AuthenticatedHttpRequest) -> HttpResponse:
    comparisons = coordinated_comparisons(request.user).annotate(
        n_participants=Count("participants", distinct=True)
    )
    if not comparisons.exists() and not _may_create(request.user):
        raise Http404("You coordinate no comparison.")
    counts: dict[int, Counter[str]] = defaultdict(Counter)
    rows = _latest_status(Participant.objects.filter(comparison__in=comparisons))
    # latest_status: _latest_status's annotation, which its QuerySet[Participant] type drops
    for comparison_id, status in rows.values_list("comparison_id", "latest_status"):  # type: ignore[misc]
        counts[comparison_id][status or "none"] += 1
    items = [(c, dict(counts[c.pk])) for c in comparisons.order_by("-created_at", "code")]
    context = {"items": items, "may_create": _may_create(request.user), "statuses": St.choices}
    return render(request, "coordinator/dashboard.html", context)


@login_required
@require_http_methods(["GET", "POST"])
def comparison_create(request: AuthenticatedHttpRequest) -> HttpResponse:
    if not _may_create(request.user):
        raise Http404("You may not create comparisons.")
    form = ComparisonCreateForm(request.POST or None)
    if request.method == "POST" and form.is_valid():
        comparison = services.comparison_create(
            comparison=form.save(commit=False),
            template_key=form.cleaned_data["template"],
            user=request.user,
        )
        messages.success(request, f"Comparison {comparison.code} created. Add its devices next.")
        return redirect("coordinator:comparison", code=comparison.code)
    return render(request, "coordinator/comparison_form.html", {"form": form})


@login_required
@require_http_methods(["GET", "POST"])
def comparison_edit(request: AuthenticatedHttpRequest, code: str) -> HttpResponse:
    comparison = coordinated(request, code)
    form = ComparisonForm(request.POST or None, instance=comparison)
    if comparison.status == ComparisonStatus.PUBLISHED:
        form.add_error(None, "A published comparison can no longer be changed.")
    elif request.method == "POST" and form.is_valid():
        form.save()
        messages.success(request, "Settings saved.")
        return redirect("coordinator:comparison", code=form.instance.code)
    context = {"form": form, "comparison": comparison}
    return render(request, "coordinator/comparison_form.html", context)


#: the coordinator's comparison page lists this many of the newest notices
NOTICES_SHOWN = 200
#: participants per page of the comparison page's participants table
PARTICIPANTS_PER_PAGE = 50


def _page(participants: QuerySet[Participant], number: str | None) -> Page:
    """One page of the participants table; the first page of a round of at most
    :data:`PARTICIPANTS_PER_PAGE` is read without counting (common.pagination)."""
    paginator = CountSparingPaginator(participants, PARTICIPANTS_PER_PAGE)
    try:
        return paginator.page(number or 1)
    except PageNotAnInteger:
        return paginator.page(1)
    except EmptyPage:
        return paginator.page(paginator.num_pages)


@login_required
@require_GET
def comparison_detail(request: AuthenticatedHttpRequest, code: str) -> HttpResponse:
    comparison = coordinated(request, code)
    participants = _latest_status(
        comparison.participants.select_related("laboratory").prefetch_related("scope_devices")
    )
    context = {
        "comparison": comparison,
        "devices": comparison.devices.all(),
        "points": comparison.measurement_points.select_related("device"),
        # every participant in a plain table, 50 to a page
        "participants": _page(participants.order_by("code"), request.GET.get("page")),
        "transitions": [t for t in comparison_allowed_transitions(comparison)
                        if t in (ComparisonStatus.OPEN, ComparisonStatus.CLOSED)],
        "template": protocols.TEMPLATES.get(comparison.protocol),
    }  # fmt: skip
    context["applications"] = comparison.enrolments.aggregate(
        total=Count("pk"), pending=Count("pk", filter=Q(status=Enrolment.Status.PENDING))
    )
    context["enrolment_refusal"] = refusal(lambda: enrolment_check(comparison))
    notices = list(notices_of_comparison(comparison)[:NOTICES_SHOWN])
    context["notices"] = notices
    # counted only when the list is cut (one query fewer on every other page view)
    short = len(notices) < NOTICES_SHOWN
    context["n_notices"] = len(notices) if short else notices_of_comparison(comparison).count()
    return render(request, "coordinator/comparison.html", context)


@login_required
@require_GET
def confirm(request: AuthenticatedHttpRequest, code: str, action: str) -> HttpResponse:
    """The confirmation page of open, close, run or publish: what will happen, then the
    button that does it (coordination.confirm)."""
    comparison = coordinated(request, code)
    if action not in ACTIONS:
        raise Http404(f"No action {action!r}.")
    try:
        c = confirmation(comparison, action, request.GET.get("report", ""))
    except NotVisible as exc:
        raise Http404(str(exc)) from None
    return render(request, "coordinator/confirm.html", {"comparison": comparison, "c": c})


@login_required
@require_POST
def comparison_status(request: AuthenticatedHttpRequest, code: str) -> HttpResponse:
    comparison = coordinated(request, code)
    target = request.POST.get("to", "")
    if target not in (ComparisonStatus.OPEN, ComparisonStatus.CLOSED):
        messages.error(request, "Use the open or close button; publication has its own button.")
    else:
        try:
            comparison_move(comparison=comparison, to=target)
        except ApplicationError as exc:
            messages.error(request, exc.message)
        else:
            messages.success(
                request, f"{comparison.code} is now {comparison.get_status_display()}."
            )
    return redirect("coordinator:comparison", code=code)


@login_required
@require_http_methods(["GET", "POST"])
def report_notes(request: AuthenticatedHttpRequest, code: str) -> HttpResponse:
    """Comments, conclusions and the authoriser printed in the reports."""
    comparison = coordinated(request, code)
    initial = {
        "comments": comparison.report_comments,
        "conclusions": comparison.report_conclusions,
        "authorised_by_name": comparison.authorised_by_name,
        "authorised_by_role": comparison.authorised_by_role,
    }
    form = ReportNotesForm(request.POST or None, initial=initial)
    if request.method == "POST" and form.is_valid():
        try:
            report_notes_update(comparison=comparison, user=request.user, **form.cleaned_data)
        except ApplicationError as exc:
            form.add_error(None, exc.message)
            for error in exc.errors:
                field = error.get("field")
                form.add_error(field if field in form.fields else None, error["message"])
        else:
            messages.success(request, "Report comments and authorisation saved.")
            return redirect("coordinator:comparison", code=code)
    context = {"form": form, "comparison": comparison}
    return render(request, "coordinator/report_notes_form.html", context)


# --- devices and measurement points -------------------------------------------------------


@login_required
@require_http_methods(["GET", "POST"])
def device_add(request: AuthenticatedHttpRequest, code: str) -> HttpResponse:
    comparison = coordinated(request, code)
    form = DeviceForm(request.POST or None, comparison=comparison)
    if request.method == "POST" and form.is_valid():
        try:
            device = services.device_create(comparison=comparison, **form.values())
        except ApplicationError as exc:
            _add_errors(form, exc)
        else:
            messages.success(request, f"Device {device.name} added.")
            return redirect("coordinator:comparison", code=code)
    return render(request, "coordinator/device_form.html", {"form": form, "comparison": comparison})


def _add_errors(form: forms.BaseForm, exc: ApplicationError) -> None:
    """A service's refusal as the form's errors: each on its field, else on the form."""
    fields = [e for e in exc.errors if e["field"] in form.fields]
    for e in fields:
        form.add_error(e["field"], e["message"])
    if not fields:
        form.add_error(None, exc.message)


def _generate(comparison: Comparison, data: dict) -> list[MeasurementPoint]:
    devices = list(comparison.devices.all())
    if data.get("template"):
        return comparison_apply_template(
            comparison=comparison, template_key=data["template"], devices=devices
        )
    return measurement_points_generate(
        comparison=comparison,
        devices=devices,
        axes=data["axes"],
        frequencies_hz=data["frequencies_hz"],
        benches=data["benches"],
        directions=data["directions"] or None,
    )


@login_required
@require_http_methods(["GET", "POST"])
def points_generate(request: AuthenticatedHttpRequest, code: str) -> HttpResponse:
    comparison = coordinated(request, code)
    initial = {
        "template": comparison.protocol if comparison.protocol in protocols.TEMPLATES else ""
    }
    form = PointGridForm(request.POST or None, initial=initial)
    if request.method == "POST" and form.is_valid():
        try:
            created = _generate(comparison, form.cleaned_data)
        except ApplicationError as exc:
            form.add_error(None, exc.message)
        else:
            messages.success(
                request, f"{counted(len(created), 'new measurement point')} generated."
            )
            return redirect("coordinator:comparison", code=code)
    context = {"form": form, "comparison": comparison, "n_devices": comparison.devices.count()}
    return render(request, "coordinator/points_form.html", context)


@login_required
@require_http_methods(["GET", "POST"])
def point_edit(request: AuthenticatedHttpRequest, code: str, pk: int) -> HttpResponse:
    comparison = coordinated(request, code)
    point = get_object_or_404(comparison.measurement_points.select_related("device"), pk=pk)
    form = PointOverrideForm(request.POST or None, instance=point)
    if request.method == "POST" and form.is_valid():
        form.save()
        messages.success(request, f"Overrides of {point} saved.")
        return redirect("coordinator:comparison", code=code)
    context = {"form": form, "comparison": comparison, "point": point}
    return render(request, "coordinator/point_form.html", context)


# --- participants -------------------------------------------------------------------------


@login_required
@require_http_methods(["GET", "POST"])
def participants_invite(request: AuthenticatedHttpRequest, code: str) -> HttpResponse:
    comparison = coordinated(request, code)
    search = request.GET.get("q", "").strip()[:80]
    form = InviteForm(
        request.POST or None, comparison=comparison, search=search,
        select_all=request.GET.get("all") == "1",
    )  # fmt: skip
    if request.method == "POST" and form.is_valid():
        labs = list(form.cleaned_data["laboratories"])
        try:
            added = labs_services.participants_invite(
                comparison=comparison, laboratories=labs, scope=form.scope()
            )
        except ApplicationError as exc:
            _add_errors(form, exc)
        else:
            codes = ", ".join(sorted(p.code for p in added))
            messages.success(
                request, f"{counted(len(added), 'laboratory', 'laboratories')} invited: {codes}."
            )
            return redirect("coordinator:comparison", code=code)
    query = QueryDict(mutable=True)
    if search:
        query["q"] = search
    context = {"form": form, "comparison": comparison, "search": search, "query": query.urlencode()}
    return render(request, "coordinator/invite.html", context)


@login_required
@require_http_methods(["GET", "POST"])
def participant_scope(
    request: AuthenticatedHttpRequest, code: str, participant: str
) -> HttpResponse:
    """What one participant measures (docs/domain.md §10), changeable until the deadline."""
    comparison = coordinated(request, code)
    participants = comparison.participants.select_related("laboratory")
    chosen = get_object_or_404(participants, code=participant)
    form = ScopeForm(request.POST or None, comparison=comparison, participant=chosen)
    if request.method == "POST" and form.is_valid():
        try:
            labs_services.participant_scope_set(participant=chosen, scope=form.scope())
        except ApplicationError as exc:
            _add_errors(form, exc)
        else:
            messages.success(request, f"Scope of {chosen.code} saved: {scope_text(chosen)}.")
            return redirect("coordinator:comparison", code=code)
    context = {
        "form": form,
        "comparison": comparison,
        "participant": chosen,
        "scope": scope_text(chosen),
        "n_points": participant_points(chosen).count(),
        "n_comparison_points": comparison.measurement_points.count(),
        "closed_reason": _scope_closed_reason(comparison),
    }
    return render(request, "coordinator/scope_form.html", context)


def _scope_closed_reason(comparison: Comparison) -> str | None:
    return refusal(lambda: labs_services.scope_change_check(comparison))


@login_required
@require_POST
def participant_reference(
    request: AuthenticatedHttpRequest, code: str, participant: str
) -> HttpResponse:
    """Mark one participant as the reference (pilot) laboratory; the others lose the mark."""
    comparison = coordinated(request, code)
    chosen = get_object_or_404(comparison.participants, code=participant)
    participant_set_reference(participant=chosen)
    messages.success(request, f"{chosen.code} is now the reference laboratory.")
    return redirect("coordinator:comparison", code=code)


# --- applications (docs/lifecycles.md §7) --------------------------------------------------


@login_required
@require_GET
def applications(request: AuthenticatedHttpRequest, code: str) -> HttpResponse:
    """The round's applications, pending first, with Accept and Decline for each pending one."""
    comparison = coordinated(request, code)
    found = (
        comparison.enrolments.select_related("laboratory", "participant", "applied_by",
                                             "decided_by")
        .prefetch_related("scope_devices")
        .order_by(Case(When(status=Enrolment.Status.PENDING, then=0), default=1),
                  "-created_at", "-id")
    )  # fmt: skip
    context = {
        "comparison": comparison,
        "applications": found,
        "enrolment_refusal": refusal(lambda: enrolment_check(comparison)),
    }
    return render(request, "coordinator/applications.html", context)


def _scope_initial(application: Enrolment) -> dict[str, object]:
    scope = enrolment_scope(application)
    return {
        "devices": list(scope.devices),
        "benches": list(scope.benches),
        "axes": list(scope.axes),
        "frequencies_hz": ", ".join(format_number(f) for f in scope.frequencies_hz),
    }


@login_required
@require_http_methods(["GET", "POST"])
def application_accept(request: AuthenticatedHttpRequest, code: str, pk: int) -> HttpResponse:
    """What accepting does, the scope to grant (the one asked for, editable), then Accept."""
    application = coordinated_application(request, code, pk)
    comparison = application.comparison
    form = ScopeForm(
        request.POST or None, comparison=comparison, initial=_scope_initial(application)
    )
    if request.method == "POST" and form.is_valid():
        try:
            accepted = enrolment_accept(
                enrolment=application, user=request.user, scope=form.scope()
            )
        except ApplicationError as exc:
            _add_errors(form, exc)
        else:
            participant = accepted.participant
            assert participant is not None
            messages.success(
                request,
                f"{application.laboratory.name} accepted: it takes part as {participant.code} "
                f"({scope_text(participant)}) and was sent the invitation.",
            )
            return redirect("coordinator:applications", code=code)
    context = {
        "comparison": comparison,
        "application": application,
        "form": form,
        "pending": application.status == Enrolment.Status.PENDING,
    }
    return render(request, "coordinator/application_accept.html", context)


@login_required
@require_http_methods(["GET", "POST"])
def application_decline(request: AuthenticatedHttpRequest, code: str, pk: int) -> HttpResponse:
    """Decline an application with a reason the laboratory reads."""
    application = coordinated_application(request, code, pk)
    form = DeclineForm(request.POST or None)
    if request.method == "POST" and form.is_valid():
        try:
            enrolment_decline(
                enrolment=application, user=request.user, reason=form.cleaned_data["reason"]
            )
        except ApplicationError as exc:
            _add_errors(form, exc)
        else:
            messages.success(
                request,
                f"The application of {application.laboratory.name} was declined; the "
                "laboratory was sent your reason.",
            )
            return redirect("coordinator:applications", code=code)
    context = {
        "comparison": application.comparison,
        "application": application,
        "form": form,
        "pending": application.status == Enrolment.Status.PENDING,
    }
    return render(request, "coordinator/application_decline.html", context)


# --- review -------------------------------------------------------------------------------


#: participants per page of the review list
REVIEW_PER_PAGE = 50


def _review_filters(request: AuthenticatedHttpRequest) -> tuple[dict[str, str], str]:
    """The review list's filters from the query string, and the query string that keeps
    them (for the pages' links: the next and previous submission, back to the list)."""
    filters = ReviewFilterForm(request.GET).filters()
    query = QueryDict(mutable=True)
    query.update(filters)
    return filters, query.urlencode()


def _matches(row: ReviewRow, filters: dict[str, str], *, without: str = "") -> bool:
    status, complete = filters.get("status"), filters.get("complete")
    if status and without != "status" and row.status != status:
        return False
    return not (complete and without != "complete" and row.complete != (complete == "complete"))


@login_required
@require_GET
def review(request: AuthenticatedHttpRequest, code: str) -> HttpResponse:
    comparison = coordinated(request, code)
    rows = review_rows(comparison)
    filters, query = _review_filters(request)
    shown = [r for r in rows if _matches(r, filters)]
    page_obj = Paginator(shown, REVIEW_PER_PAGE).get_page(request.GET.get("page"))
    # each choice counted with the other filter applied: the rows choosing it would show
    by_status = Counter(r.status for r in rows if _matches(r, filters, without="status"))
    by_complete = Counter(
        "complete" if r.complete else "incomplete"
        for r in rows
        if _matches(r, filters, without="complete")
    )
    form = ReviewFilterForm(request.GET)
    form.filters()
    for name, counts in (("status", by_status), ("complete", by_complete)):
        field = cast(forms.ChoiceField, form.fields[name])
        offered = cast(list[tuple[str, str]], field.choices)
        field.choices = [
            (value, f"{label} ({counts[value] if value else sum(counts.values())})")
            for value, label in offered
        ]
    context = {
        "comparison": comparison,
        "rows": page_obj,
        "page_obj": page_obj,
        "form": form,
        "filters": filters,
        "query": query,
        "n_shown": len(shown),
        "n_participants": len(rows),
        "n_acceptable": sum(r.acceptable for r in rows),
    }
    return render(request, "coordinator/review.html", context)


@login_required
@require_POST
def accept_complete(request: AuthenticatedHttpRequest, code: str) -> HttpResponse:
    """Accept every complete submission waiting for a decision (the confirmation page,
    ``confirm/accept-complete/``, lists them); the set is decided again here."""
    comparison = coordinated(request, code)
    expected = {c for c in request.POST.get("expected", "").split(",") if c}
    accepted = submissions_accept_complete(comparison=comparison, user=request.user)
    codes = [s.participant.code for s in accepted]
    if codes:
        messages.success(
            request, f"Accepted {counted(len(codes), 'submission')}: {', '.join(codes)}."
        )
    else:
        messages.warning(request, "No submission is complete and waiting for a decision: "
                         "nothing was accepted.")  # fmt: skip
    added, gone = sorted(set(codes) - expected), sorted(expected - set(codes))
    if "expected" in request.POST and (added or gone):  # what the confirmation page listed
        changed = []
        if added:
            were = "was" if len(added) == 1 else "were"
            changed.append(
                f"{', '.join(added)} {were} accepted too (complete and waiting since then)"
            )
        if gone:
            were = "was" if len(gone) == 1 else "were"
            changed.append(
                f"{', '.join(gone)} {were} not accepted: no longer complete and waiting (a new "
                "version arrived, it was decided, its scope changed or it was asked to check a "
                "result)"
            )
        messages.info(request, "The list changed since the confirmation page: "
                      + "; ".join(changed) + ".")  # fmt: skip
    return redirect("coordinator:review", code=code)


def _others(comparison: Comparison, participant: Participant) -> dict[int, list[tuple]]:
    """The other participants' current submitted/accepted results by point, labs by code."""
    current = current_submissions(comparison, (St.SUBMITTED, St.ACCEPTED))
    rows = (
        Result.objects.filter(submission__in=current)
        .exclude(submission__participant=participant)
        .order_by("submission__participant__code")
        .values_list(
            "measurement_point_id", "submission__participant__code", "value",
            "expanded_uncertainty",
        )
    )  # fmt: skip
    by_point: dict[int, list[tuple]] = defaultdict(list)
    for point_id, lab, value, big_u in rows:
        by_point[point_id].append((lab, value, big_u))
    return by_point


def _review_rows(submission: Submission) -> list[dict]:
    """Each result of ``submission`` beside the others' at the same point and their median."""
    others = _others(submission.participant.comparison, submission.participant)
    results = submission.results.select_related("measurement_point__device").order_by(*POINT_ORDER)
    rows = []
    for r in results:
        near = others.get(r.measurement_point_id, [])
        median = statistics.median(v for _, v, _ in near) if near else None
        deviation = 100 * (r.value - median) / median if median else None
        rows.append({"result": r, "others": near, "median": median, "deviation": deviation})
    return rows


@login_required
@require_http_methods(["GET", "POST"])
def submission_review(
    request: AuthenticatedHttpRequest, code: str, participant: str, version: int
) -> HttpResponse:
    comparison = coordinated(request, code)
    submission = get_object_or_404(
        Submission.objects.select_related("participant__laboratory", "participant__comparison"),
        participant__comparison=comparison, participant__code=participant, version=version,
    )  # fmt: skip
    form = DecisionForm(request.POST or None)
    if request.method == "POST" and form.is_valid():
        try:
            decided = submission_decide(
                submission=submission,
                decision=form.cleaned_data["decision"],
                message=form.cleaned_data["message"],
                user=request.user,
            )
        except ApplicationError as exc:
            form.add_error(None, exc.message)
        else:
            messages.success(
                request, f"Version {decided.version} of {participant} {decided.status}."
            )
            back = reverse("coordinator:review", args=[code])
            return redirect(f"{back}?{query}" if (query := _review_filters(request)[1]) else back)
    filters, query = _review_filters(request)
    listed = [r for r in review_rows(comparison) if r.version and _matches(r, filters)]
    before = [r for r in listed if r.participant.code < participant]
    after = [r for r in listed if r.participant.code > participant]
    context = {
        "comparison": comparison,
        "submission": submission,
        "form": form,
        "rows": _review_rows(submission),
        "may_decide": submission.status == St.SUBMITTED,
        "previous": before[-1] if before else None,
        "next": after[0] if after else None,
        "query": query,
        "position": len(before) + 1,
        "n_listed": len(listed),
        "listed": any(r.participant.code == participant for r in listed),
    }
    return render(request, "coordinator/submission.html", context)


@login_required
@require_POST
def result_check(request: AuthenticatedHttpRequest, code: str, pk: int) -> HttpResponse:
    comparison = coordinated(request, code)
    result = get_object_or_404(
        Result.objects.select_related("measurement_point__device", "submission__participant"),
        pk=pk, submission__participant__comparison=comparison,
    )  # fmt: skip
    submission_request_check(result=result, user=request.user)
    s = result.submission
    messages.success(
        request,
        f"{s.participant.code} was asked to check its result for {result.measurement_point} "
        "(nothing about the size or sign of the deviation was said).",
    )
    return redirect("coordinator:submission", code=code, participant=s.participant.code,
                    version=s.version)  # fmt: skip


# --- raw records ----------------------------------------------------------

RAW_PER_PAGE = 10


@login_required
@require_GET
def raw_review(request: AuthenticatedHttpRequest, code: str) -> HttpResponse:
    """Every participant's raw records (by code): reported vs recomputed, En, fs, fit."""
    comparison = coordinated(request, code)
    page = Paginator(raw_records_of_comparison(comparison.pk), RAW_PER_PAGE).get_page(
        request.GET.get("page")
    )
    cards = [(record, raw_record_figure(record)) for record in page]
    context = {"comparison": comparison, "page": page, "cards": cards}
    return render(request, "coordinator/raw_review.html", context)
