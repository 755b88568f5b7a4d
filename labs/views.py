"""Web pages of the laboratories: dashboard, comparison, results grid, upload,
template download, submission history and API keys.

Thin views: find what the user may see (404 otherwise, also for other labs' objects),
call one service or selector, render.  The results grid and the upload both go through
``labs.services`` — the same validation and storage path as the REST API.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, cast

from django.conf import settings
from django.contrib import messages
from django.contrib.auth.decorators import login_required
from django.core.paginator import Page, Paginator
from django.db.models import OuterRef, QuerySet, Subquery
from django.http import Http404, HttpRequest, HttpResponse, QueryDict
from django.shortcuts import redirect, render
from django.urls import reverse
from django.views.decorators.cache import never_cache
from django.views.decorators.csrf import csrf_exempt, csrf_protect
from django.views.decorators.http import require_GET, require_http_methods
from django_htmx.http import HttpResponseClientRedirect

from common.errors import (
    ApplicationError,
    NotVisible,
    RequestTooLarge,
    StateConflict,
    ValidationFailed,
    refusal,
)
from common.middleware import validates_own_text
from labs import services
from labs.access import (
    applications_visible_to,
    call_page,
    comparisons_visible_to,
    managed_application,
    managed_lab,
    managed_labs,
    participant_page,
)
from labs.enrolment import enrolment_apply, enrolment_apply_check, enrolment_withdraw
from labs.forms import APIKeyCreateForm, ApplicationForm, ResultGridForm, ResultUploadForm
from labs.importers.values import human_size
from labs.models import (
    Enrolment,
    LabAPIKey,
    Laboratory,
    Membership,
    Participant,
    RawRecord,
    Result,
    Submission,
)
from labs.notices import notice_mark_read, notices_for
from labs.raw import RawUploadLimit
from labs.raw_forms import RawUploadForm
from labs.raw_selectors import raw_point_choices, raw_record_figure, raw_record_get, raw_records_of
from labs.raw_services import human_limit, raw_declared_too_large, raw_upload_submit
from labs.selectors import (
    has_kits,
    participant_points,
    participant_submissions,
    scope_text,
    user_laboratories,
)
from labs.selectors import results_template as template_bytes
from proficiency import protocols
from proficiency.models import Comparison
from proficiency.selectors import call_levels, open_calls

if TYPE_CHECKING:
    from django.contrib.auth.models import User

    from common.http import AuthenticatedHttpRequest

CONTENT_TYPES = {
    "csv": "text/csv; charset=utf-8",
    "xlsx": "application/vnd.openxmlformats-officedocument.spreadsheetml.sheet",
}


# --- lookups (404 for anything that is not the user's) ------------------------------------


def _participations(request: HttpRequest) -> QuerySet[Participant]:
    """The user's labs' participations, each with its latest submission version and status."""
    latest = Submission.objects.filter(participant=OuterRef("pk")).order_by("-version")
    return (
        Participant.objects.filter(laboratory__in=user_laboratories(request.user))
        .select_related("comparison", "laboratory")
        .annotate(
            latest_status=Subquery(latest.values("status")[:1]),
            latest_version=Subquery(latest.values("version")[:1]),
        )
        .order_by("laboratory__name", "-comparison__created_at", "comparison__code")
    )


def _submission(participant: Participant, version: int) -> Submission:
    submission = participant_submissions(participant).filter(version=version).first()
    if submission is None:
        raise Http404(f"No version {version} of your submission.")
    return submission


def _grid_source(participant: Participant) -> Submission | None:
    """What the grid starts from: the open draft, else the latest version (a correction)."""
    versions = participant.submissions.order_by("-version")
    return versions.filter(status=Submission.Status.DRAFT).first() or versions.first()


def _closed_reason(comparison: Comparison) -> str | None:
    """Why results cannot be stored now, in the service's own words (None when open)."""
    return refusal(lambda: services.submission_window_check(comparison))


# --- dashboard and comparison --------------------------------------------------------------


@require_GET
def home(request: HttpRequest) -> HttpResponse:
    """``/``: a lab member's dashboard; the public landing page for everyone else."""
    if user_laboratories(request.user).exists():
        return dashboard(request)
    comparisons = comparisons_visible_to(request.user).order_by("code")
    return render(
        request,
        "home.html",
        {"comparisons": comparisons, "provider": settings.PT_PROVIDER_NAME},
    )


#: the inbox shows this many notices per page
NOTICES_PER_PAGE = 20


@login_required
@require_GET
def dashboard(request: HttpRequest) -> HttpResponse:
    """The lab's comparisons and its inbox (docs/lifecycles.md §6), newest notice first."""
    notices = Paginator(notices_for(request.user), NOTICES_PER_PAGE).get_page(
        request.GET.get("notices")
    )
    context = {"participations": _participations(request), "notices": notices}
    return render(request, "labs/dashboard.html", context)


@login_required
@require_http_methods(["POST"])
def notice_read(request: HttpRequest, pk: int) -> HttpResponse:
    """Mark one notice of the user's laboratories read; 404 for anyone else's."""
    notice = notices_for(request.user).filter(pk=pk).first()
    if notice is None:
        raise Http404("No such notice for your laboratory.")
    notice_mark_read(notice=notice)
    return redirect("labs:dashboard")


@login_required
@require_http_methods(["POST"])
def notices_read_all(request: HttpRequest) -> HttpResponse:
    """Mark every unread notice of the user's laboratories read."""
    for notice in notices_for(request.user).filter(read_at__isnull=True):
        notice_mark_read(notice=notice)
    messages.success(request, "All notices marked read.")
    return redirect("labs:dashboard")


@login_required
@require_GET
def comparison_detail(request: AuthenticatedHttpRequest, code: str) -> HttpResponse:
    participant = participant_page(request, code)
    comparison = participant.comparison
    context = {
        "participant": participant,
        "comparison": comparison,
        "template": protocols.TEMPLATES.get(comparison.protocol),
        "devices": comparison.devices.all(),
        "points": list(participant_points(participant)),
        "n_comparison_points": comparison.measurement_points.count(),
        "scope": scope_text(participant),
        "latest": participant_submissions(participant).first(),
        "closed_reason": _closed_reason(comparison),
        "has_kit": participant.kit_slots.exists(),
    }
    return render(request, "labs/comparison.html", context)


# --- results grid ----------------------------------------------------------------------------


def _grid_context(participant: Participant, form: ResultGridForm) -> dict[str, object]:
    return {
        "participant": participant,
        "comparison": participant.comparison,
        "form": form,
        "source": _grid_source(participant),
        "closed_reason": _closed_reason(participant.comparison),
    }


def _grid_form(participant: Participant, data: QueryDict | None = None) -> ResultGridForm:
    source = _grid_source(participant)
    results: dict[int, Result] = {}
    if source is not None:
        results = {r.measurement_point_id: r for r in source.results.all()}
    points = list(participant_points(participant))
    dated = has_kits(participant.comparison)
    return ResultGridForm(data, points=points, results=results, dated=dated)


def _grid_save(
    request: AuthenticatedHttpRequest, participant: Participant, form: ResultGridForm
) -> bool:
    submit = request.POST.get("action") == "submit"
    records = form.records()
    if not records:
        form.summary.append("Enter at least one result before saving.")
        return False
    try:
        services.submission_from_records(
            participant=participant,
            records=records,
            source=Submission.Source.WEB,
            user=request.user,
            submit=submit,
        )
    except ValidationFailed as exc:
        form.add_service_errors(exc.message, exc.errors, submit=submit)
        return False
    except StateConflict as exc:
        form.summary.append(exc.message)
        return False
    return True


@validates_own_text  # every cell is checked by the importer, named next to its input
@login_required
@require_http_methods(["GET", "POST"])
def results_grid(request: AuthenticatedHttpRequest, code: str) -> HttpResponse:
    participant = participant_page(request, code)
    form = _grid_form(participant, request.POST if request.method == "POST" else None)
    if request.method == "POST":
        if not form.is_valid():
            form.summary.append("Some entries are not valid; see the marked rows.")
        elif _grid_save(request, participant, form):
            return _grid_saved(request, participant)
    template = "labs/_grid_form.html" if request.htmx else "labs/grid.html"
    return render(request, template, _grid_context(participant, form))


def _grid_saved(request: AuthenticatedHttpRequest, participant: Participant) -> HttpResponse:
    code = participant.comparison.code
    if request.POST.get("action") == "submit":
        messages.success(request, "Your results were submitted. Thank you.")
        url = reverse("labs:comparison", args=[code])
        return HttpResponseClientRedirect(url) if request.htmx else redirect(url)
    if request.htmx:  # saved in place: a fresh grid from the stored draft
        form = _grid_form(participant)
        context = _grid_context(participant, form) | {"saved": True}
        return render(request, "labs/_grid_form.html", context)
    messages.success(request, "Draft saved. You can come back and submit it later.")
    return redirect("labs:grid", code=code)


# --- upload and template download -----------------------------------------------------------


@login_required
@require_http_methods(["GET", "POST"])
def results_upload(request: AuthenticatedHttpRequest, code: str) -> HttpResponse:
    participant = participant_page(request, code)
    form = ResultUploadForm(request.POST or None, request.FILES or None)
    report: ValidationFailed | None = None
    if request.method == "POST" and form.is_valid():
        submit = request.POST.get("action") == "submit"
        try:
            services.submission_from_file(
                participant=participant,
                data=form.content(),
                filename=form.cleaned_data["file"].name,
                user=request.user,
                submit=submit,
            )
        except ValidationFailed as exc:
            report = exc
        except StateConflict as exc:
            form.add_error(None, exc.message)
        else:
            done = "submitted" if submit else "saved as a draft"
            messages.success(request, f"The file was read and your results were {done}.")
            return redirect("labs:comparison", code=code)
    context = {
        "participant": participant,
        "comparison": participant.comparison,
        "form": form,
        "report": report,
        "closed_reason": _closed_reason(participant.comparison),
        "max_upload": human_size(settings.MAX_UPLOAD_BYTES),
    }
    return render(request, "labs/upload.html", context)


@login_required
@require_GET
def results_template(request: AuthenticatedHttpRequest, code: str, fmt: str) -> HttpResponse:
    """The participant's measurement points (its scope) as a results table with empty values
    to fill in."""
    if fmt not in CONTENT_TYPES:
        raise Http404("The template comes as .csv or .xlsx.")
    participant = participant_page(request, code)
    comparison = participant.comparison
    data = template_bytes(comparison, format=fmt, participant=participant)
    response = HttpResponse(data, content_type=CONTENT_TYPES[fmt])
    filename = f"{comparison.code}-results-template.{fmt}"
    response["Content-Disposition"] = f'attachment; filename="{filename}"'
    return response


# --- history ---------------------------------------------------------------------------------


@login_required
@require_GET
def submission_history(request: AuthenticatedHttpRequest, code: str) -> HttpResponse:
    participant = participant_page(request, code)
    context = {
        "participant": participant,
        "comparison": participant.comparison,
        "submissions": (page := _page(request, participant_submissions(participant))),
        "page_obj": page,
    }
    return render(request, "labs/history.html", context)


#: rows per page of the history and raw-record lists (they grow with every upload)
LIST_PER_PAGE = 25


def _page(request: HttpRequest, items: QuerySet) -> Page:
    return Paginator(items, LIST_PER_PAGE).get_page(request.GET.get("page"))


@login_required
@require_GET
def submission_detail(request: AuthenticatedHttpRequest, code: str, version: int) -> HttpResponse:
    participant = participant_page(request, code)
    submission = _submission(participant, version)
    context = {
        "participant": participant,
        "comparison": participant.comparison,
        "submission": submission,
        "results": submission.results.select_related("measurement_point__device"),
        "is_draft": submission.status == Submission.Status.DRAFT,
        "dated": submission.results.filter(measured_on__isnull=False).exists(),
    }
    return render(request, "labs/submission.html", context)


# --- API keys (laboratory managers only) ---------------------------------------------------


@login_required
@require_GET
def api_keys_index(request: AuthenticatedHttpRequest) -> HttpResponse:
    """``/lab/api-keys/``: the key page of the (first) laboratory the user manages."""
    lab = managed_labs(request.user).order_by("name").first()
    if lab is None:
        raise Http404("No laboratory whose API keys you manage.")
    return redirect("labs:api_keys", lab_pk=lab.pk)


def _keys_page(request: HttpRequest, lab: Laboratory, form: APIKeyCreateForm) -> HttpResponse:
    keys = lab.api_keys.select_related("created_by").order_by("-created")
    return render(request, "labs/api_keys.html", {"lab": lab, "keys": keys, "form": form})


@never_cache
@login_required
@require_http_methods(["GET", "POST"])
def api_keys(request: AuthenticatedHttpRequest, lab_pk: int) -> HttpResponse:
    """List the laboratory's keys; POST creates one and shows it once (never again)."""
    lab = managed_lab(request, lab_pk)
    form = APIKeyCreateForm(request.POST or None)
    if request.method == "POST" and form.is_valid():
        try:
            key_obj, key = services.api_key_create(
                laboratory=lab, name=form.cleaned_data["name"], user=request.user
            )
        except ValidationFailed as exc:
            form.add_error("name", exc.message)
        else:
            context = {"lab": lab, "key_obj": key_obj, "key": key}
            return render(request, "labs/api_key_created.html", context)
    return _keys_page(request, lab, form)


@login_required
@require_http_methods(["GET", "POST"])
def api_key_revoke(request: AuthenticatedHttpRequest, lab_pk: int, prefix: str) -> HttpResponse:
    """GET asks for confirmation; POST revokes (the key stays listed, marked revoked)."""
    lab = managed_lab(request, lab_pk)
    key = LabAPIKey.objects.filter(laboratory=lab, prefix=prefix).first()
    if key is None:
        raise Http404("No such API key in your laboratory.")
    if request.method == "POST":
        services.api_key_revoke(key=key)
        messages.success(request, f"The key “{key.name}” ({key.prefix}…) was revoked.")
        return redirect("labs:api_keys", lab_pk=lab.pk)
    return render(request, "labs/api_key_revoke.html", {"lab": lab, "key": key})


# --- raw records behind a result ------------------------------------------


def _raw_page(
    request: HttpRequest, participant: Participant, form: object, error: str = ""
) -> HttpResponse:
    context = {
        "participant": participant,
        "comparison": participant.comparison,
        "form": form,
        "records": (page := _page(request, raw_records_of(participant))),
        "page_obj": page,
        "max_upload": human_limit(),
        "error": error,
    }
    return render(request, "labs/raw_list.html", context, status=413 if error else 200)


@csrf_exempt  # CSRF is checked below, once the size-limiting upload handler is in place
@login_required
@require_http_methods(["GET", "POST"])
def raw_data(request: AuthenticatedHttpRequest, code: str) -> HttpResponse:
    """The laboratory's raw records for ``code`` and the form to attach one."""
    too_large = raw_declared_too_large(request.META) if request.method == "POST" else None
    if too_large:  # refused on the declared size, before anything reads the body
        participant = participant_page(request, code)
        form = RawUploadForm(points=raw_point_choices(participant))
        return _raw_page(request, participant, form, too_large)
    if request.method == "POST":
        # a plain list until the body is read; RawUploadLimit is duck-typed
        cast(list[Any], request.upload_handlers).insert(
            0, RawUploadLimit(request, limit=settings.RAW_UPLOAD_MAX_BYTES)
        )
    return _raw_data(request, code)


def _raw_submit(form: RawUploadForm, participant: Participant, user: User) -> RawRecord | None:
    """The form's cleaned values to the upload service; its refusal onto the form (None)."""
    data = form.cleaned_data
    try:
        return raw_upload_submit(
            participant=participant,
            point_fields=form.point_fields(),
            file=data["file"],
            sidecar=data.get("sidecar"),
            meta_fields=form.meta_fields(),
            reference_file=data.get("reference_file"),
            reference_sidecar=data.get("reference_sidecar"),
            reference_fields=form.reference_fields(),
            user=user,
        )
    except ValidationFailed as exc:
        field = (exc.errors[0].get("field") if exc.errors else None) or None
        form.add_error(field if field in form.fields else None, exc.message)
        return None


@csrf_protect
def _raw_data(request: AuthenticatedHttpRequest, code: str) -> HttpResponse:
    participant = participant_page(request, code)
    points = raw_point_choices(participant)
    try:
        form = RawUploadForm(request.POST or None, request.FILES or None, points=points)
        if request.method == "POST" and form.is_valid():
            record = _raw_submit(form, participant, request.user)
            if record is not None:
                messages.success(request, "The raw record was stored; its recomputation runs now.")
                return redirect("labs:raw_record", code=code, pk=record.pk)
    except RequestTooLarge as exc:  # raised while the body is read: nothing was stored
        return _raw_page(request, participant, RawUploadForm(points=points), exc.message)
    return _raw_page(request, participant, form)


@login_required
@require_GET
def raw_record(request: AuthenticatedHttpRequest, code: str, pk: int) -> HttpResponse:
    """One raw record: reported vs recomputed sensitivity, En, fs found, record with fit."""
    participant = participant_page(request, code)
    try:
        record = raw_record_get(raw_records_of(participant), pk)
    except NotVisible as exc:
        raise Http404(exc.message) from None
    context = {
        "participant": participant,
        "comparison": participant.comparison,
        "record": record,
        "figure": raw_record_figure(record),
    }
    return render(request, "labs/raw_record.html", context)


# --- open calls and applications (docs/lifecycles.md §7) -------------------------


def _who_applies(request: HttpRequest) -> str:
    """Who can apply for the user's laboratories, when the user manages none of them."""
    managers = (
        Membership.objects.filter(
            laboratory__in=user_laboratories(request.user), role=Membership.Role.MANAGER
        )
        .select_related("user", "laboratory")
        .order_by("laboratory__name", "user__username")
    )
    names = ", ".join(f"{m.user.get_username()} ({m.laboratory.name})" for m in managers)
    who = f": {names}" if names else ""
    return (
        "Only a manager of a laboratory can apply for it (or the laboratory's software with "
        f"an API key){who}. You can see the calls and your laboratory's applications here."
    )


@login_required
@require_GET
def calls(request: AuthenticatedHttpRequest) -> HttpResponse:
    """The rounds taking applications now, and the applications of the user's laboratories."""
    found = list(open_calls())
    levels = call_levels(found)
    applications = list(applications_visible_to(request.user))
    taking_part = set(
        Participant.objects.filter(
            laboratory__in=user_laboratories(request.user), comparison__in=found
        ).values_list("comparison_id", flat=True)
    )
    live = {
        a.comparison_id
        for a in applications
        if a.status in (Enrolment.Status.PENDING, Enrolment.Status.ACCEPTED)
    }
    may_apply = managed_labs(request.user).exists()
    rows = [
        {"call": c, "levels": levels[c.pk], "taking_part": c.pk in taking_part,
         "applied": c.pk in live}
        for c in found
    ]  # fmt: skip
    context = {
        "rows": rows,
        "applications": applications,
        "may_apply": may_apply,
        "who_applies": None if may_apply else _who_applies(request),
    }
    return render(request, "labs/calls.html", context)


@login_required
@require_http_methods(["GET", "POST"])
def call_apply(request: AuthenticatedHttpRequest, code: str) -> HttpResponse:
    """Apply to a round with a scope and a note: lab managers only (404 for staff)."""
    comparison = call_page(request, code).comparison
    laboratories = managed_labs(request.user).order_by("name")
    if not laboratories.exists():
        raise Http404("Only a manager of a laboratory can apply for it.")
    levels = call_levels([comparison])[comparison.pk]
    form = ApplicationForm(
        request.POST or None, comparison=comparison, levels=levels, laboratories=laboratories
    )
    only = laboratories[0] if len(laboratories) == 1 else None
    closed_reason = refusal(lambda: enrolment_apply_check(comparison, only))
    if request.method == "POST" and form.is_valid():
        lab = form.cleaned_data["laboratory"]
        try:
            enrolment_apply(
                comparison=comparison, laboratory=lab, scope=form.scope(),
                note=form.cleaned_data["note"], user=request.user,
            )  # fmt: skip
        except ApplicationError as exc:
            fields = [e for e in exc.errors if e["field"] in form.fields]
            for e in fields:
                form.add_error(e["field"], e["message"])
            if not fields:
                form.add_error(None, exc.message)
        else:
            messages.success(
                request,
                f"The application of {lab.name} to {comparison.code} was sent; the coordinator "
                "accepts or declines it, and your laboratory is told either way.",
            )
            return redirect("labs:calls")
    context = {
        "comparison": comparison,
        "levels": levels,
        "form": form,
        "closed_reason": closed_reason,
        "devices": comparison.devices.order_by("name"),
    }
    return render(request, "labs/call_apply.html", context)


@login_required
@require_http_methods(["POST"])
def application_withdraw(request: AuthenticatedHttpRequest, pk: int) -> HttpResponse:
    """Take back a pending application of a laboratory the user manages; 404 otherwise."""
    application = managed_application(request, pk)
    try:
        enrolment_withdraw(enrolment=application, user=request.user)
    except StateConflict as exc:
        messages.error(request, exc.message)
    else:
        messages.success(
            request, f"The application to {application.comparison.code} was withdrawn."
        )
    return redirect("labs:calls")
