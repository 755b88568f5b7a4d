"""The reports page: participants and coordinators list the reports they may download."""

from __future__ import annotations

from typing import TYPE_CHECKING

from django.contrib.auth.decorators import login_required
from django.core.paginator import Paginator
from django.http import Http404, HttpResponse
from django.shortcuts import render
from django.urls import path

from analysis.access import reports_visible
from common.errors import NotVisible
from labs.access import Caller, comparison_access

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


urlpatterns = [path("reports/<slug:code>/", reports_page, name="reports")]
