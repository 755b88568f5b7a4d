"""The coordinator's page of a run's kits (docs/domain.md §13, §14): the drift judged per
kit and point, the reference each point was linked to with χ², and every participant's
kit, date, drift handling and degree of equivalence against that reference."""

from __future__ import annotations

from typing import TYPE_CHECKING

from django.contrib.auth.decorators import login_required
from django.http import Http404, HttpResponse
from django.views.decorators.http import require_GET

from analysis.kit_results import kit_fits, kit_scores, kit_summary
from analysis.views import _page, _render, _viewer

if TYPE_CHECKING:
    from common.http import AuthenticatedHttpRequest


@login_required
@require_GET
def kits_page(request: AuthenticatedHttpRequest, code: str, audience: str) -> HttpResponse:
    """Coordinators only (a participant reads its own numbers in its report)."""
    viewer = _viewer(request, code, audience)
    if not viewer.is_coordinator:
        raise Http404("No such page.")
    if viewer.run is None:
        return _render(request, viewer, "kits", {})
    page, query = _page(request, kit_scores(viewer.run), 100)
    context = {"summary": kit_summary(viewer.run), "fits": kit_fits(viewer.run),
               "page_obj": page, "query": query}  # fmt: skip
    return _render(request, viewer, "kits", context)
