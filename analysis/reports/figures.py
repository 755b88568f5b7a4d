"""The report's graphs as platypus flowables: data → :mod:`charts` raster → PDF image
(:class:`~analysis.reports.images.RasterImage`); the standard graphs of ISO 13528 §10
that the pages draw (density, DoE, Mandel) are :mod:`analysis.reports.standard`'s.
"""

from __future__ import annotations

import numpy as np
from reportlab.platypus import Flowable, KeepTogether, Paragraph

from analysis.charts import axis_unit
from analysis.core.graphs import sorted_scores, youden_data
from analysis.core.groups import CoreInputError
from analysis.core.scores import NEGLIGIBLE_FRACTION
from analysis.reports import charts, standard
from analysis.reports.data import AssignedRow, ReportData, ScoreRow
from analysis.reports.images import WIDTH, RasterImage, _xobject, caption
from analysis.reports.images import round_charts as _round_charts
from analysis.reports.styles import STYLES
from analysis.standard_charts import CAPTIONS
from common.points import point_label
from common.quantities import label_shown

__all__ = ["WIDTH", "RasterImage", "_round_charts", "_xobject", "figures"]


def figures(data: ReportData) -> list[Flowable]:
    """The participant's scores over its points; values vs x_pt and the sorted En and z
    of the chosen points; largest |En| per lab; x_pt vs frequency."""
    out: list[Flowable] = []
    if data.own_code:
        out += _overview(data)
        note = f"Your result ({data.own_code}) is drawn in pink; the others in blue."
        out.append(Paragraph(note, STYLES["small"]))
    out += _point_charts(data)
    out += _sorted_charts(data)
    out += standard.point_graphs(data)
    out += _en_chart(data)
    out += _youden(data)
    out += standard.mandel_graphs(data)
    out += _frequency_charts(data)
    if not out:
        out.append(Paragraph("No graphs: the run has no results.", STYLES["body"]))
    return out


def _point_chart(
    data: ReportData, index: int, assigned: dict[int, AssignedRow]
) -> charts.PointChart | None:
    """The shared chart of point ``index``; None when it has no assigned value or result."""
    p, a = data.points[index], assigned.get(index)
    if a is None:
        return None
    key = ("point", index, a.value, a.expanded_uncertainty, p.full_label, p.unit)
    found = _round_charts(data)
    chart = found.get(key)
    if chart is None:
        rows = data.round.point_values.get(index)
        if rows is None or not rows.labs:
            return None
        chart = found[key] = charts.point_chart(
            rows.labs,
            rows.values,
            rows.uncertainties,
            x_pt=a.value,
            u_x_pt_expanded=a.expanded_uncertainty,
            title=p.full_label,
            unit=p.unit,
            quantity=p.quantity,
        )
    assert isinstance(chart, charts.PointChart)
    return chart


def _point_charts(data: ReportData) -> list[Flowable]:
    out: list[Flowable] = []
    assigned = {a.point: a for a in data.assigned}
    for index in data.chart_points:
        chart = _point_chart(data, index, assigned)
        if chart is not None:
            out.append(RasterImage(chart.raster, chart.overlay(data.own_code)))
    if out:
        out.append(caption(POINT_CAPTION))
    return out


POINT_CAPTION = (
    "Each participant's result with its expanded uncertainty U (bars) at the points with "
    "the largest |En|, participants in code order; the dashed line is the assigned value "
    "x_pt and the band x_pt ± U(x_pt). A bar that does not reach the band is a result "
    "incompatible with x_pt."
)
SORTED_CAPTION = (
    "The same points' scores sorted from lowest to highest (ISO 13528:2022 10.3), one bar "
    "per participant{own}: En with its limits ±{limit:g} (red dashed lines), and {z} with "
    "±2 (orange) and ±3 (red). A bar beyond the lines is questionable (orange) or "
    "unsatisfactory (red); the sorted bars show whether a result is one of a few outlying "
    "ones or part of a general spread."
)
OVERVIEW_CAPTION = (
    "Your En{z} at each of your points, in the order of the results tables, grouped by "
    "device. Between the dashed lines a score is satisfactory (|En| ≤ {limit:g}{zlim}); "
    "orange bars are questionable, red ones unsatisfactory. A bar ending in a dot goes "
    "beyond the frame (|En| > {en_top:g}{ztop}). A pattern along a device, a bench or "
    "a frequency points to a systematic cause."
)
EN_TOP, Z_TOP = 3.0, 5.0  # the overview's frame: ±3·limit for En, ±5 for z


def _z_name(data: ReportData, index: int) -> str:
    """z or z′ at point ``index`` (ISO 13528:2022 9.5: z′ where u(x_pt) > 0.3·σ_pt)."""
    a = next((a for a in data.assigned if a.point == index), None)
    if a is None or a.sigma_pt is None:
        return "z"
    return "z" if a.standard_uncertainty <= NEGLIGIBLE_FRACTION * a.sigma_pt else "z′"


def _sorted_chart(data: ReportData, index: int, score: str) -> charts.SortedChart | None:
    """The shared sorted chart of ``score`` ("en" or "z") at point ``index``."""
    found = _round_charts(data)
    key = ("sorted", score, index, data.en_limit)
    chart = found.get(key)
    if chart is None:
        rows = data.round.point_scores.get(index)
        if rows is None:
            return None
        ranked = sorted_scores(rows.labs, rows.en if score == "en" else rows.z)
        if not ranked.labels:
            return None
        name = "En" if score == "en" else _z_name(data, index)
        chart = found[key] = charts.sorted_chart(
            ranked.labels,
            tuple(ranked.values.tolist()),
            limits=(data.en_limit,) if score == "en" else charts.Z_LIMITS,
            title=f"{data.points[index].full_label}: {name} sorted",
            ylabel=name,
        )
    assert isinstance(chart, charts.SortedChart)
    return chart


def _sorted_charts(data: ReportData) -> list[Flowable]:
    out: list[Flowable] = []
    names = set()
    for index in data.chart_points:
        for score in ("en", "z"):
            chart = _sorted_chart(data, index, score)
            if chart is not None:
                out.append(RasterImage(chart.raster, chart.overlay(data.own_code)))
                names.add(_z_name(data, index) if score == "z" else "En")
    if not out:
        return []
    z = " or ".join(sorted(names - {"En"})) or "z"
    own = f", yours ({data.own_code}) in pink" if data.own_code else ""
    return [*out, caption(SORTED_CAPTION.format(own=own, limit=data.en_limit, z=z))]


def _device_groups(data: ReportData) -> tuple[tuple[str, int, int], ...]:
    """(device, first point, stop) of the report's points (ordered by device)."""
    groups: list[tuple[str, int, int]] = []
    for p in data.points:
        if groups and groups[-1][0] == p.device:
            groups[-1] = (p.device, groups[-1][1], p.index + 1)
        else:
            groups.append((p.device, p.index, p.index + 1))
    return tuple(groups)


def _bars_over(
    frame: charts.OverviewFrame,
    rows: list[ScoreRow],
    values: list[float],
    limits: tuple[float, ...],
) -> RasterImage:
    colours = charts.verdict_colours(np.array(values, dtype=float), limits)
    return RasterImage(frame.raster, frame.bars([s.point for s in rows], values, colours))


def _overview(data: ReportData) -> list[Flowable]:
    """The participant's En and z at each of its points: a frame shared by every report of
    the run, its bars drawn over it."""
    own = [s for s in data.scores if s.lab == data.own_code]
    if not own:
        return []
    groups, n, limit = _device_groups(data), len(data.points), data.en_limit
    frame = charts.overview_frame(groups, n, limits=(limit,), top=EN_TOP * limit,
                                  title="Your En at each point", ylabel="En")  # fmt: skip
    out: list[Flowable] = [_bars_over(frame, own, [s.en for s in own], (limit,))]
    with_z = [s for s in own if s.z is not None]
    if with_z:
        title = "Your z (or z′) at each point"
        frame = charts.overview_frame(groups, n, limits=charts.Z_LIMITS, top=Z_TOP,
                                      title=title, ylabel="z, z′")  # fmt: skip
        out.append(_bars_over(frame, with_z, [s.z or 0.0 for s in with_z], charts.Z_LIMITS))
    text = OVERVIEW_CAPTION.format(
        z=" (above) and z or z′ (below)" if with_z else "", limit=limit,
        zlim="; |z| ≤ 2" if with_z else "", en_top=EN_TOP * limit,
        ztop=f", |z| > {Z_TOP:g}" if with_z else "",
    )  # fmt: skip
    return [*out, caption(text)]


def point_charts_build(data: ReportData) -> int:
    """Build the chart of every point of ``data``'s round now, with its sorted En and z
    charts; the number of point charts built.  In a large round each point is among some
    participant's worst, so every report process needs them all: built together with the
    round's shared data (the batch's first report), not one by one in whichever later
    reports need them."""
    assigned = {a.point: a for a in data.assigned}
    for p in data.points:
        for score in ("en", "z"):
            _sorted_chart(data, p.index, score)
    return sum(_point_chart(data, p.index, assigned) is not None for p in data.points)


def _en_chart(data: ReportData) -> list[Flowable]:
    largest = data.round.largest_en
    if not largest:
        return []
    found = _round_charts(data)
    chart = found.get(("en", data.en_limit))
    if chart is None:
        labs = tuple(lab for lab, _ in largest)
        chart = charts.en_chart(labs, tuple(en for _, en in largest), limit=data.en_limit)
        found[("en", data.en_limit)] = chart
    assert isinstance(chart, charts.EnChart)
    return [RasterImage(chart.raster, chart.overlay(data.own_code))]


def _frequency_charts(data: ReportData) -> list[Flowable]:
    """Median of the participants' results against frequency, one line per bench,
    direction and axis (the same in every report of a run, so the raster is cached)."""
    out: list[Flowable] = []
    for device, quantity, unit, series in data.round.frequency:
        title = f"{device}: median {label_shown(quantity) or 'sensitivity'} against frequency"
        out.append(RasterImage(charts.frequency_chart(series, title=title, unit=unit,
                                                      quantity=quantity)))  # fmt: skip
    return out


YOUDEN_FEW = 3  # an ellipse needs at least three participants with both results


def _pair_rank(data: ReportData, a: int, b: int) -> int | None:
    """How worth drawing the pair of points ``a``, ``b`` is, as ``analysis.graph_data.
    point_pairs`` ranks the web's pairs: 0 the same device, axis and frequency on the two
    benches, 1 in two directions, 2 two devices at one axis, frequency, bench and
    direction; None: not a pair (also two points of different quantity kinds)."""
    p, q = data.points[a], data.points[b]
    if p.quantity != q.quantity:
        return None
    if (p.device, p.axis, p.frequency_hz) == (q.device, q.axis, q.frequency_hz):
        return int(p.bench == q.bench)
    if (p.axis, p.frequency_hz, p.bench, p.direction) == (q.axis, q.frequency_hz, q.bench,
                                                          q.direction):  # fmt: skip
        return 2
    return None


def youden_pair(data: ReportData) -> tuple[int, int] | None:
    """The pair of the reader's points for its Youden plot: the best ranked, then the first
    in the points' order, among those where at least three participants have both results."""
    mine = sorted({r.point for r in data.results if r.lab == data.own_code})
    values = data.round.point_values
    best: tuple[int, int, int] | None = None
    for i, a in enumerate(mine):
        for b in mine[i + 1 :]:
            rank = _pair_rank(data, a, b)
            if rank is None or (best is not None and (rank, a, b) >= best):
                continue
            at_a, at_b = values.get(a), values.get(b)
            if at_a and at_b and len(set(at_a.labs) & set(at_b.labs)) >= YOUDEN_FEW:
                best = (rank, a, b)
    return None if best is None else (best[1], best[2])


def _ellipse(
    x: tuple[float, ...], y: tuple[float, ...], assigned: tuple[float, float]
) -> tuple[tuple[float, float] | None, tuple[tuple[float, float], ...]]:
    """Centre and vertices of the 95 % ellipse (robust; classical where MADe is 0), as
    ``analysis.standard_charts`` draws it; (None, ()) where neither can be drawn."""
    for method in ("robust", "classical"):
        try:
            found = youden_data(x, y, *assigned, method=method)
        except CoreInputError:
            continue
        cx, cy = found.ellipse.centre
        ring = tuple((float(u), float(v)) for u, v in found.ellipse.vertices)
        return (float(cx), float(cy)), ring
    return None, ()


def _youden(data: ReportData) -> list[Flowable]:
    """The reader's Youden plot of :func:`youden_pair`: shared by every report of the run
    with the same pair, the reader's point an overlay."""
    pair = youden_pair(data) if data.own_code else None
    assigned = {a.point: a.value for a in data.assigned}
    if pair is None or not all(i in assigned for i in pair):
        return []
    a, b = pair
    found = _round_charts(data)
    key = ("youden", a, b)
    chart = found.get(key)
    if chart is None:
        at_a, at_b = data.round.point_values[a], data.round.point_values[b]
        y_of = dict(zip(at_b.labs, at_b.values, strict=True))
        both = [(lab, v) for lab, v in zip(at_a.labs, at_a.values, strict=True) if lab in y_of]
        labels = tuple(lab for lab, _ in both)
        x, y = tuple(v for _, v in both), tuple(y_of[lab] for lab in labels)
        centre, ring = _ellipse(x, y, (assigned[a], assigned[b]))
        pa, pb = data.points[a], data.points[b]
        chart = found[key] = charts.youden_chart(
            labels, x, y, assigned=(assigned[a], assigned[b]), centre=centre, ring=ring,
            x_label=f"{point_label(pa.key)} ({axis_unit(pa.unit)})",
            y_label=f"{point_label(pb.key)} ({axis_unit(pb.unit)})",
            title="Youden plot",
        )  # fmt: skip
    assert isinstance(chart, charts.YoudenChart)
    text = f"{CAPTIONS['youden']} Your result ({data.own_code}) is the pink dot."
    return [KeepTogether([RasterImage(chart.raster, chart.overlay(data.own_code)), caption(text)])]
