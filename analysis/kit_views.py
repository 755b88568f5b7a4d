"""The page of a run's kits (docs/domain.md §13, §14): the drift judged per kit and point,
the reference each point was linked to with χ², and each participant's kit, date, drift
handling and degree of equivalence against that reference.

The coordinator reads every participant's row and the run's messages.  A participant
reads the round-level figures (the drift of each kit, the kit values, χ²) and its own
rows only: which kit another laboratory had and when is its circulation plan, shown to
no one else (§15), and the run's messages name laboratories and their kits."""

from __future__ import annotations

from typing import TYPE_CHECKING

from django.contrib.auth.decorators import login_required
from django.http import HttpResponse
from django.views.decorators.http import require_GET

from analysis.kit_results import kit_fits, kit_scores, kit_summary
from analysis.views import _page, _render, _viewer

if TYPE_CHECKING:
    from common.http import AuthenticatedHttpRequest


@login_required
@require_GET
def kits_page(request: AuthenticatedHttpRequest, code: str, audience: str) -> HttpResponse:
    viewer = _viewer(request, code, audience)
    if viewer.run is None:
        return _render(request, viewer, "kits", {})
    own = None if viewer.is_coordinator else viewer.own_code
    page, query = _page(request, kit_scores(viewer.run, own), 100)
    summary = kit_summary(viewer.run)
    if own is not None and summary is not None:
        summary.notes = []  # they name laboratories and their kits
    context = {"summary": summary, "fits": kit_fits(viewer.run), "page_obj": page, "query": query}
    return _render(request, viewer, "kits", context)
