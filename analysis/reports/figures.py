"""The report's graphs as platypus images: data → PNG (``charts``) → ``Image``."""

from __future__ import annotations

import io
from collections import defaultdict
from statistics import median

from reportlab.lib.units import mm
from reportlab.platypus import Flowable, Image, Paragraph

from analysis.reports import charts
from analysis.reports.data import ReportData
from analysis.reports.styles import STYLES

WIDTH = 170 * mm


def _image(png: bytes, width_in: float, height_in: float) -> Image:
    height = WIDTH * height_in / width_in
    return Image(io.BytesIO(png), width=WIDTH, height=height)


def figures(data: ReportData) -> list[Flowable]:
    """Values vs x_pt for the chosen points, largest |En| per lab, x_pt vs frequency."""
    out: list[Flowable] = []
    assigned = {a.point: a for a in data.assigned}
    for index in data.chart_points:
        p, a = data.points[index], assigned.get(index)
        rows = [r for r in data.results if r.point == index]
        if a is None or not rows:
            continue
        png = charts.point_png(
            [r.lab for r in rows],
            [r.value for r in rows],
            [r.expanded_uncertainty for r in rows],
            x_pt=a.value,
            u_x_pt_expanded=2 * a.standard_uncertainty,
            title=p.full_label,
            unit=p.unit,
            highlight=data.own_code,
        )
        out.append(_image(png, 6.4, 2.6))
    out += _en_chart(data)
    out += _frequency_charts(data)
    if not out:
        out.append(Paragraph("No graphs: the run has no results.", STYLES["body"]))
    return out


def _en_chart(data: ReportData) -> list[Flowable]:
    largest: dict[str, float] = {}
    for s in data.scores:
        largest[s.lab] = max(largest.get(s.lab, 0.0), abs(s.en))
    if not largest:
        return []
    labs = sorted(largest)
    png = charts.en_png(
        labs, [largest[c] for c in labs], limit=data.en_limit, highlight=data.own_code
    )
    return [_image(png, 6.4, 2.4)]


def _frequency_charts(data: ReportData) -> list[Flowable]:
    """Median of the participants' results against frequency, one line per bench,
    direction and axis (the same in every report of a run, so the PNG is cached)."""
    values: dict[str, dict[str, dict[float, list[float]]]] = defaultdict(dict)
    for r in data.results:
        p = data.points[r.point]
        line = values[p.device].setdefault(f"{p.bench} {p.direction} {p.axis}", {})
        line.setdefault(p.frequency_hz, []).append(r.value)
    out: list[Flowable] = []
    for device in sorted(values):
        series = tuple(
            (label, tuple(sorted(by_f)), tuple(float(median(by_f[f])) for f in sorted(by_f)))
            for label, by_f in sorted(values[device].items())
        )
        unit = next(p.unit for p in data.points if p.device == device)
        title = f"{device}: median sensitivity against frequency"
        out.append(_image(charts.frequency_png(series, title=title, unit=unit), 6.4, 2.8))
    return out
