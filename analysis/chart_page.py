"""The charts of a run's charts page, drawn for one reader (docs/domain.md §11): the chosen
point's charts, the Youden plot of the chosen pair, Mandel's h and k, and sensitivity
against frequency per device, each through the chart cache (docs/architecture.md §3.1).

``page_charts`` is what the page shows; ``charts_warm`` draws the same charts for a
coordinator's first view of a new run (its default point and pair) in the background, so
that the view finds them in the cache."""

from __future__ import annotations

from typing import Any

from analysis import chart_specs as specs
from analysis import charts
from analysis.chart_cache import cached_chart
from analysis.graph_data import (
    default_pair,
    point_choice_label,
    point_data,
    point_pairs,
    run_points,
)
from analysis.models import AnalysisRun
from analysis.selectors import run_matrices
from analysis.viewer import COORDINATOR, Viewer
from common import quantities
from proficiency.models import MeasurementPoint


def page_charts(
    viewer: Viewer, point: MeasurementPoint | None, pair: tuple[MeasurementPoint, ...] | None
) -> dict[str, Any]:
    """The page's figures: the point's (none without a point), the pair's Youden plot (None
    without a pair), Mandel's h and k, the frequency charts."""
    return {
        "figures": _point_figures(viewer, point) if point else [],
        "youden": specs.figure(viewer, specs.youden_spec(viewer, *pair)) if pair else None,
        "mandel": [specs.figure(viewer, s) for s in specs.mandel_specs(viewer).values()],
        "frequency_charts": _frequency_charts(viewer),
    }


def charts_warm(*, run_id: int) -> bool:
    """Draw into the cache the charts of a coordinator's first view of run ``run_id``'s
    charts page (the first point, its first pair): whether the run was there to draw.
    Safe to run twice: a chart already cached is not drawn again."""
    run = (
        AnalysisRun.objects.select_related("comparison")
        .filter(pk=run_id, status=AnalysisRun.Status.SUCCEEDED)
        .first()
    )
    if run is None:  # deleted meanwhile (or never succeeded): nothing to show
        return False
    viewer = Viewer(run.comparison, run, COORDINATOR)
    points = run_points(run)
    point = points[0] if points else None
    key = default_pair(point_pairs(points), point.pk if point else None)
    by_pk = {p.pk: p for p in points}
    pair = tuple(by_pk[int(i)] for i in key.split("-")) if key else None
    page_charts(viewer, point, pair)
    return True


def _point_figures(viewer: Viewer, point: MeasurementPoint) -> list[dict]:
    """The point's charts, the first two (results, En) drawn together by ``_point_charts``."""
    both = _point_charts(viewer, point)
    found = specs.point_specs(viewer, point).items()
    return [specs.figure(viewer, spec, both.get(name)) for name, spec in found]


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
            **specs.point_arguments(data, title, point.value_unit, viewer.own_code,
                                    point.quantity)
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
    """One chart per device and quantity kind: a phase or an angular rate is not drawn on
    its device's magnitude axis (nor against the magnitude's nominal value)."""
    assert viewer.run is not None
    by_device: dict[tuple[str, str], list[charts.Series]] = {}
    for m in run_matrices(viewer.run, "frequency", {}):
        series = charts.Series(str(m.group.get("axis", "")), [float(f) for f in m.levels],
                               m.values, m.expanded_uncertainties)  # fmt: skip
        kind = str(m.group.get("quantity") or quantities.DEFAULT)
        by_device.setdefault((str(m.group.get("device", "")), kind), []).append(series)
    devices = {d.name: d for d in viewer.comparison.devices.all()}
    out = []
    for (name, kind), curves in sorted(by_device.items()):
        d = devices.get(name)
        nominal = d.nominal_sensitivity if d and kind == quantities.DEFAULT else None
        half = None
        if d and nominal and d.tolerance:
            half = nominal * d.tolerance / 100 if d.tolerance_relative else d.tolerance
        shown = quantities.label_shown(kind)
        out.append(charts.frequency_chart(
            curves, title=f"{name}{', ' + shown if shown else ''}: mean of all labs per frequency",
            unit=quantities.point_unit(kind, d.unit) if d else "",
            nominal=nominal, nominal_half_width=half, quantity=kind,
        ))  # fmt: skip
    return out
