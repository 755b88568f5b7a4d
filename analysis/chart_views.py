"""The charts page of a run's results (both audiences, like ``analysis.views``) and the
chart downloads: for the chosen point its results, En (in the labs' order and sorted),
z or z′, kernel density and degrees of equivalence; a Youden plot of a chosen pair of
points; Mandel's h and k of the round; sensitivity against frequency per device
(docs/domain.md §11).  Every chart comes as SVG or PNG under
``<base>/charts/<name>.<svg|png>`` with the page's query (docs/interfaces.md)."""

from __future__ import annotations

from typing import TYPE_CHECKING

from django.contrib.auth.decorators import login_required
from django.http import Http404, HttpResponse, QueryDict
from django.views.decorators.http import require_GET

from analysis import chart_specs as specs
from analysis.chart_page import page_charts
from analysis.forms import PairForm, PointForm
from analysis.graph_data import point_pairs, run_points
from analysis.viewer import Viewer
from analysis.views import _render, _viewer

if TYPE_CHECKING:
    from common.http import AuthenticatedHttpRequest


@login_required
@require_GET
def charts_page(request: AuthenticatedHttpRequest, code: str, audience: str) -> HttpResponse:
    viewer = _viewer(request, code, audience)
    if viewer.run is None:
        return _render(request, viewer, "charts", {})
    points = run_points(viewer.run)
    form = PointForm(request.GET, points=points)
    point = form.chosen()
    pair_form = PairForm(request.GET, pairs=point_pairs(points))
    by_pk = {p.pk: p for p in points}
    pair_pks = pair_form.chosen(point.pk if point else None)
    pair = tuple(by_pk[pk] for pk in pair_pks) if pair_pks else None
    context = {"form": form, "point": point, "pair_form": pair_form}
    context |= page_charts(viewer, point, pair)
    return _render(request, viewer, "charts", context)


@login_required
@require_GET
def chart_download(
    request: AuthenticatedHttpRequest, code: str, chart: str, ext: str, audience: str
) -> HttpResponse:
    """One chart as an SVG file or a PNG, with the page's query (point, pair, run; lab for
    a coordinator's participant overview); the same access as the charts page."""
    if ext not in specs.IMAGE_TYPES or chart not in specs.NAMES:
        raise Http404("Charts come as .svg or .png, by the names of the charts page.")
    viewer = _viewer(request, code, audience)
    if viewer.run is None:
        raise Http404(f"{code} has no analysed results yet.")
    spec = _spec(viewer, chart, request.GET)
    response = HttpResponse(specs.draw(viewer, spec, ext), content_type=specs.IMAGE_TYPES[ext])
    response["Content-Disposition"] = f'attachment; filename="{spec.filename}.{ext}"'
    return response


def _spec(viewer: Viewer, chart: str, query: QueryDict) -> specs.Spec:
    assert viewer.run is not None
    if chart in specs.MANDEL_CHARTS:
        return specs.mandel_specs(viewer)[chart]
    if chart == "overview":
        return specs.overview_spec(viewer, _overview_lab(viewer, query))
    points = run_points(viewer.run)
    if chart == "youden":
        point = PointForm(query, points=points).chosen()
        pair = PairForm(query, pairs=point_pairs(points)).chosen(point.pk if point else None)
        if pair is None:
            raise Http404("This run has no pair of points for a Youden plot.")
        by_pk = {p.pk: p for p in points}
        return specs.youden_spec(viewer, by_pk[pair[0]], by_pk[pair[1]])
    point = PointForm(query, points=points).chosen()
    if point is None:
        raise Http404("This run has no measurement point.")
    return specs.point_specs(viewer, point)[chart]


def _overview_lab(viewer: Viewer, query: QueryDict) -> str:
    """The participant's own code; for a coordinator, the participant ``lab`` (404 if none)."""
    if viewer.own_code:
        return viewer.own_code
    lab = query.get("lab", "")
    if not lab or not viewer.comparison.participants.filter(code=lab).exists():
        raise Http404(f"{viewer.comparison.code} has no participant {lab!r}.")
    return lab
