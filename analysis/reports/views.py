"""The reports page: participants and coordinators list the reports they may download;
coordinators preview the reports before publication."""

from __future__ import annotations

from typing import TYPE_CHECKING

from django.contrib.auth.decorators import login_required
from django.core.paginator import Paginator
from django.http import Http404, HttpResponse
from django.shortcuts import get_object_or_404, render
from django.urls import path
from django.views.decorators.http import require_GET

from analysis.access import reports_visible
from analysis.reports.preview import report_preview
from analysis.selectors import current_run
from common.errors import NotVisible
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


urlpatterns = [
    path("reports/<slug:code>/", reports_page, name="reports"),
    path("coordinator/<slug:code>/reports/preview/", preview_page, name="reports_preview"),
    path(
        "coordinator/<slug:code>/reports/preview/<slug:which>.pdf",
        preview_pdf,
        name="report_preview_pdf",
    ),
]
