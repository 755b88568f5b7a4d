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
from analysis import charts
from analysis.chart_cache import cached_chart
from analysis.forms import PairForm, PointForm, point_choice_label
from analysis.graph_data import point_data, point_pairs, run_points
from analysis.selectors import run_matrices
from analysis.views import Viewer, _render, _viewer
from proficiency.models import MeasurementPoint

if TYPE_CHECKING:
    from common.http import AuthenticatedHttpRequest


def _point_charts(viewer: Viewer, point: MeasurementPoint) -> dict[str, str]:
    assert viewer.run is not None
    parts = (point.pk, viewer.own_code, viewer.comparison.en_limit)
    return cached_chart(viewer.run, "point", parts, lambda: _draw_point_charts(viewer, point))


def _draw_point_charts(viewer: Viewer, point: MeasurementPoint) -> dict[str, str]:
    assert viewer.run is not None
    data = point_data(viewer.run, point)
    title = point_choice_label(point)
    return {
        "point": charts.point_chart(
            **specs.point_arguments(data, title, point.device.unit, viewer.own_code)
        ),
        "en": charts.en_chart(data.labels, data.en, title=f"En · {title}",
                              limit=viewer.comparison.en_limit, highlight=viewer.own_code),
    }  # fmt: skip


def _frequency_charts(viewer: Viewer) -> list[str]:
    """Per device, sensitivity vs frequency per axis: the run's frequency matrices (§3 means)."""
    assert viewer.run is not None
    devices = tuple(viewer.comparison.devices.order_by("pk").values_list(
        "name", "unit", "nominal_sensitivity", "tolerance", "tolerance_relative"))  # fmt: skip
    return cached_chart(viewer.run, "frequency", devices, lambda: _draw_frequency_charts(viewer))


def _draw_frequency_charts(viewer: Viewer) -> list[str]:
    assert viewer.run is not None
    by_device: dict[str, list[charts.Series]] = {}
    for m in run_matrices(viewer.run, "frequency", {}):
        series = charts.Series(str(m.group.get("axis", "")), [float(f) for f in m.levels],
                               m.values, m.expanded_uncertainties)  # fmt: skip
        by_device.setdefault(str(m.group.get("device", "")), []).append(series)
    devices = {d.name: d for d in viewer.comparison.devices.all()}
    out = []
    for name, curves in sorted(by_device.items()):
        d = devices.get(name)
        nominal = d.nominal_sensitivity if d else None
        half = None
        if d and nominal and d.tolerance:
            half = nominal * d.tolerance / 100 if d.tolerance_relative else d.tolerance
        out.append(charts.frequency_chart(
            curves, title=f"{name}: mean of all labs per frequency", unit=d.unit if d else "",
            nominal=nominal, nominal_half_width=half,
        ))  # fmt: skip
    return out


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
    pair = pair_form.chosen(point.pk if point else None)
    context = {
        "form": form,
        "point": point,
        "figures": _point_figures(viewer, point) if point else [],
        "pair_form": pair_form,
        "youden": specs.figure(viewer, specs.youden_spec(viewer, by_pk[pair[0]], by_pk[pair[1]]))
        if pair else None,
        "mandel": [specs.figure(viewer, s) for s in specs.mandel_specs(viewer).values()],
        "frequency_charts": _frequency_charts(viewer),
    }  # fmt: skip
    return _render(request, viewer, "charts", context)


def _point_figures(viewer: Viewer, point: MeasurementPoint) -> list[dict]:
    """The point's charts, the first two (results, En) drawn together by ``_point_charts``."""
    both = _point_charts(viewer, point)
    found = specs.point_specs(viewer, point).items()
    return [specs.figure(viewer, spec, both.get(name)) for name, spec in found]


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
