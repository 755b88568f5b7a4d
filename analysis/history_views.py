"""The laboratory's history page (``/lab/history/``, docs/domain.md §4.1) and the trend chart
both history views draw (this page and the coordinator's view of one participant).

A member of a laboratory reads its own history only: the published rounds it took part in,
its own code in each; any other laboratory is 404, as is a user who belongs to none.
"""

from __future__ import annotations

import hashlib
from pathlib import Path
from typing import TYPE_CHECKING

from django.contrib.auth.decorators import login_required
from django.core.cache import cache
from django.http import Http404, HttpResponse
from django.shortcuts import render
from django.views.decorators.http import require_GET

from analysis import history_chart as drawing
from analysis.chart_cache import TIMEOUT
from analysis.chart_cache import VERSION as CHARTS_VERSION
from analysis.history import LabHistory, lab_history, trend_series
from labs.models import Laboratory
from labs.selectors import user_laboratories

if TYPE_CHECKING:
    from common.http import AuthenticatedHttpRequest

#: the drawing code's digest in the cache key, as the results pages' charts have
VERSION = hashlib.sha256(Path(drawing.__file__).read_bytes()).hexdigest()[:12] + CHARTS_VERSION


def _chosen(labs: list[Laboratory], wanted: str) -> Laboratory:
    """The laboratory ``?lab=<pk>`` names among the user's, else the first by name."""
    if not labs:
        raise Http404("You are not a member of a laboratory: there is no history to show.")
    if not wanted:
        return labs[0]
    found = next((lab for lab in labs if str(lab.pk) == wanted), None)
    if found is None:
        raise Http404("No laboratory of yours with that number.")
    return found


def trend_chart(history: LabHistory) -> str:
    """The En and z of every point per round, drawn once per set of numbers (cached by
    their digest: a published run never changes)."""
    if not history.rounds:
        return ""
    data = trend_series(history.rounds, history.points)
    key = hashlib.sha256(repr((VERSION, data)).encode()).hexdigest()[:32]
    svg = cache.get(f"pt:chart:history:{key}")
    if svg is None:
        svg = drawing.history_chart(*data)
        cache.set(f"pt:chart:history:{key}", svg, TIMEOUT)
    return svg


@login_required
@require_GET
def lab_history_page(request: AuthenticatedHttpRequest) -> HttpResponse:
    labs = list(user_laboratories(request.user).order_by("name"))
    lab = _chosen(labs, request.GET.get("lab", ""))
    history = lab_history(lab)
    context = {"labs": labs, "lab": lab, "history": history, "chart": trend_chart(history),
               "chart_caption": drawing.CAPTION}  # fmt: skip
    return render(request, "labs/lab_history.html", context)
