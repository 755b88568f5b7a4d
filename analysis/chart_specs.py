"""The charts of a run's results pages and their downloads, named once (docs/domain.md §11,
docs/interfaces.md, the chart downloads): which data each chart is drawn from, its cache
key, its file name.  A chart is drawn only when the cache does not hold it (the data is
read inside the build), as inline SVG for the page, or as an SVG file or a PNG for the
download, each cached on its own (docs/architecture.md §3.1)."""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any
from urllib.parse import urlencode

from django.urls import reverse
from django.utils.text import slugify

from analysis import charts, graph_data
from analysis import standard_charts as std
from analysis.chart_cache import cached_chart
from analysis.graph_data import point_choice_label
from proficiency.models import MeasurementPoint

if TYPE_CHECKING:
    from matplotlib.figure import Figure

    from analysis.viewer import Viewer

#: the download formats: the page's inline SVG is a third, ``svg`` without its prologue
IMAGE_TYPES = {"svg": "image/svg+xml", "png": "image/png"}
POINT_CHARTS = ("point", "en", "z", "en-bars", "density", "doe")
MANDEL_CHARTS = ("mandel-h", "mandel-k")
NAMES = (*POINT_CHARTS, "youden", *MANDEL_CHARTS, "overview")


@dataclass(frozen=True)
class Spec:
    """One chart: its name, what it is drawn from besides the run and the reader (the key),
    the figure's builder (reads the data when called) and the query of its download."""

    name: str
    parts: tuple[Any, ...]
    build: Callable[[], Figure]
    query: dict[str, str]
    filename: str


def draw(viewer: Viewer, spec: Spec, fmt: str = "inline") -> str | bytes:
    """The chart as inline SVG (``inline``), an SVG file (``svg``) or a PNG (``png``)."""
    assert viewer.run is not None
    parts = (*spec.parts, viewer.own_code, fmt)
    return cached_chart(viewer.run, f"std:{spec.name}", parts,
                        lambda: charts.render(spec.build(), fmt))  # fmt: skip


def figure(viewer: Viewer, spec: Spec, svg: str | None = None) -> dict[str, Any]:
    """What a page shows of a chart: the SVG (``svg`` when already drawn), its caption and
    the two download links."""
    drawn = draw(viewer, spec) if svg is None else svg
    return {"name": spec.name, "svg": drawn, "caption": std.CAPTIONS[spec.name],
            "svg_url": download_url(viewer, spec, "svg"),
            "png_url": download_url(viewer, spec, "png")}  # fmt: skip


def download_url(viewer: Viewer, spec: Spec, ext: str) -> str:
    prefix = "" if viewer.is_coordinator else "lab_"
    url = reverse(f"coordinator:{prefix}chart_download",
                  args=[viewer.comparison.code, spec.name, ext])  # fmt: skip
    query = dict(spec.query)
    current = viewer.current
    if viewer.is_coordinator and viewer.run and current and viewer.run.pk != current.pk:
        query["run"] = str(viewer.run.pk)
    return f"{url}?{urlencode(query)}" if query else url


# --------------------------------------------------------------------------- one point


def point_specs(viewer: Viewer, point: MeasurementPoint) -> dict[str, Spec]:
    """The charts of one point: results, En (labs' order and sorted), z, density, DoE."""
    assert viewer.run is not None
    run, own, limit = viewer.run, viewer.own_code, viewer.comparison.en_limit
    data = functools.cache(lambda: graph_data.point_data(run, point))
    title, unit, kind = point_choice_label(point), point.value_unit, point.quantity
    builders: dict[str, Callable[[], Figure]] = {
        "point": lambda: charts.point_figure(**point_arguments(data(), title, unit, own, kind)),
        "en": lambda: charts.en_figure(data().labels, data().en, title=f"En · {title}",
                                       limit=limit, highlight=own),
        "z": lambda: std.z_figure(data().labels, data().z, title=f"{data().z_name} · {title}",
                                  name=data().z_name, highlight=own),
        "en-bars": lambda: std.en_bar_figure(data().labels, data().en, title=f"En · {title}",
                                             limit=limit, highlight=own),
        "density": lambda: _density(data(), title, unit, own, kind),
        "doe": lambda: _doe(data(), title, unit, own),
    }  # fmt: skip
    slug = slugify(point_choice_label(point))
    return {
        name: Spec(
            name,
            (point.pk, limit),
            build,
            {"point": str(point.pk)},
            f"{viewer.comparison.code}-{name}-{slug}",
        )
        for name, build in builders.items()
    }


def point_arguments(
    data: graph_data.PointData, title: str, unit: str, own: str | None,
    quantity: str | None = None,
) -> dict[str, Any]:  # fmt: skip
    """``charts.point_chart``'s arguments: the page's chart and its download are the same
    (the value axis names the point's ``quantity`` and unit)."""
    a = data.assigned
    return {"labels": data.labels, "values": data.values,
            "expanded_uncertainties": data.expanded, "assigned_value": a.value,
            "assigned_expanded_uncertainty": a.expanded_uncertainty, "title": title,
            "unit": unit, "quantity": quantity, "highlight": own}  # fmt: skip


def _density(data: graph_data.PointData, title: str, unit: str, own: str | None,
             quantity: str | None = None) -> Figure:  # fmt: skip
    mine = [v for lab, v in zip(data.labels, data.values, strict=True) if lab == own]
    return std.density_figure(
        data.values, assigned_value=data.assigned.value,
        assigned_expanded_uncertainty=data.assigned.expanded_uncertainty,
        title=f"Kernel density · {title}", unit=unit, quantity=quantity,
        own_value=mine[0] if mine else None,
    )  # fmt: skip


def _doe(data: graph_data.PointData, title: str, unit: str, own: str | None) -> Figure:
    doe = data.doe() if data.labels else None
    d = list(doe.d) if doe else []
    big_u = list(doe.U_d) if doe else []
    return std.doe_figure(data.labels, d, big_u, title=f"Degrees of equivalence · {title}",
                          unit=unit, highlight=own)  # fmt: skip


# --------------------------------------------------------------------------- the round


def youden_spec(viewer: Viewer, a: MeasurementPoint, b: MeasurementPoint) -> Spec:
    assert viewer.run is not None
    run, own = viewer.run, viewer.own_code

    def build() -> Figure:
        d = graph_data.pair_data(run, a, b)
        return std.youden_figure(
            d.labels,
            d.x,
            d.y,
            assigned_x=d.assigned_x,
            assigned_y=d.assigned_y,
            x_label=point_choice_label(a),
            y_label=point_choice_label(b),
            unit=a.value_unit,
            highlight=own,
        )

    pair = f"{a.pk}-{b.pk}"
    slug = f"{slugify(point_choice_label(a))}-vs-{slugify(point_choice_label(b))}"
    return Spec("youden", (pair,), build, {"pair": pair},
                f"{viewer.comparison.code}-youden-{slug}")  # fmt: skip


def mandel_specs(viewer: Viewer) -> dict[str, Spec]:
    """Mandel's h and k of every participant at every point of the run."""
    assert viewer.run is not None
    run, own = viewer.run, viewer.own_code
    data = functools.cache(lambda: graph_data.mandel_data(run))

    def build(statistic: str) -> Figure:
        d = data()
        g = d.graph
        if g is None:
            return std.mandel_figure([], [], [], [], [], statistic=statistic)
        values, reasons = (g.h, g.h_reason) if statistic == "h" else (g.k, g.k_reason)
        crit = (g.h_critical_5, g.h_critical_1) if statistic == "h" else (
            g.k_critical_5, g.k_critical_1)  # fmt: skip
        return std.mandel_figure(d.labs, d.points, values, *crit, statistic=statistic,
                                 reasons=reasons, groups=d.devices, highlight=own)  # fmt: skip

    code = viewer.comparison.code
    return {
        f"mandel-{s}": Spec(
            f"mandel-{s}", (), functools.partial(build, s), {}, f"{code}-mandel-{s}"
        )
        for s in ("h", "k")
    }


def overview_spec(viewer: Viewer, lab: str) -> Spec:
    """One participant's En and z at all its points (the reader's own, or the coordinator's
    chosen participant)."""
    assert viewer.run is not None
    run, limit = viewer.run, viewer.comparison.en_limit

    def build() -> Figure:
        d = graph_data.lab_overview(run, lab)
        return std.lab_overview_figure(d.points, d.groups, d.en, d.z, code=lab, limit=limit,
                                       z_name=d.z_name)  # fmt: skip

    query = {} if viewer.own_code == lab else {"lab": lab}
    return Spec("overview", (lab, limit), build, query,
                f"{viewer.comparison.code}-overview-{slugify(lab)}")  # fmt: skip
