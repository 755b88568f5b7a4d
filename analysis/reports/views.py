"""The reports page: participants and coordinators list the reports they may download;
coordinators preview the reports before publication."""

from __future__ import annotations

from typing import TYPE_CHECKING

from django.contrib import messages
from django.contrib.auth.decorators import login_required
from django.core.paginator import Paginator
from django.http import Http404, HttpResponse
from django.shortcuts import get_object_or_404, redirect, render
from django.urls import path
from django.views.decorators.http import require_GET, require_POST

from analysis.access import reports_visible
from analysis.models import Report
from analysis.reports.preview import report_preview
from analysis.reports.services import report_issue
from analysis.selectors import current_run
from common.errors import ApplicationError, NotVisible
from labs.access import Caller, comparison_access, coordinated

if TYPE_CHECKING:
    from common.http import AuthenticatedHttpRequest

#: every version of every report is kept, so the list grows with each issue
REPORTS_PER_PAGE = 50


@login_required
def reports_page(request: AuthenticatedHttpRequest, code: str) -> HttpResponse:
    try:
        access = comparison_access(Caller(user=request.user), code)
    except NotVisible:
        raise Http404(f"No comparison {code!r} is visible to you.") from None
    context = {
        "comparison": access.comparison,
        "reports": (
            page := Paginator(reports_visible(access), REPORTS_PER_PAGE).get_page(
                request.GET.get("page")
            )
        ),
        "page_obj": page,
        "is_coordinator": access.is_coordinator,
    }
    return render(request, "reports/list.html", context)


@login_required
@require_GET
def preview_page(request: AuthenticatedHttpRequest, code: str) -> HttpResponse:
    """The coordinator's list of report previews: the summary and one per participant."""
    comparison = coordinated(request, code)
    context = {
        "comparison": comparison,
        "run": current_run(comparison),
        "participants": comparison.participants.select_related("laboratory").order_by("code"),
    }
    return render(request, "reports/preview.html", context)


@login_required
@require_GET
def preview_pdf(request: AuthenticatedHttpRequest, code: str, which: str) -> HttpResponse:
    """One report rendered now from the current run (``which``: ``summary`` or a
    participant code); 404 for anyone but the round's coordinators, 409 without a run."""
    comparison = coordinated(request, code)
    participant = (
        None if which == "summary" else get_object_or_404(comparison.participants, code=which)
    )
    if current_run(comparison) is None:
        return HttpResponse(f"{code} has no successful analysis run to preview.", status=409)
    pdf = report_preview(comparison=comparison, participant=participant)
    response = HttpResponse(pdf, content_type="application/pdf")
    response["Content-Disposition"] = f'inline; filename="{code}-{which}-preview.pdf"'
    response["Cache-Control"] = "no-store"
    return response


@login_required
@require_POST
def reissue(request: AuthenticatedHttpRequest, code: str) -> HttpResponse:
    """A new version of one report now (``report``: ``summary`` or a participant's code),
    after the confirmation page ``/coordinator/<code>/confirm/reissue/?report=...``; the
    API's "issue now" (docs/lifecycles.md §4)."""
    comparison = coordinated(request, code)
    which = request.POST.get("report", "summary")
    participant = (
        None if which == "summary" else get_object_or_404(comparison.participants, code=which)
    )
    kind = Report.Kind.SUMMARY if participant is None else Report.Kind.PARTICIPANT
    try:
        report = report_issue(comparison=comparison, kind=kind, participant=participant)
    except ApplicationError as exc:
        messages.error(request, exc.message)
    else:
        name = "Summary report" if participant is None else f"Participant report {which}"
        messages.success(request, f"{name} issued as version {report.version}.")
    return redirect("reports", code)


urlpatterns = [
    path("coordinator/<slug:code>/reports/reissue/", reissue, name="reports_reissue"),
    path("reports/<slug:code>/", reports_page, name="reports"),
    path("coordinator/<slug:code>/reports/preview/", preview_page, name="reports_preview"),
    path(
        "coordinator/<slug:code>/reports/preview/<slug:which>.pdf",
        preview_pdf,
        name="report_preview_pdf",
    ),
]
