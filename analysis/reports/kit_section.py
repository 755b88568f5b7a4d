"""The "Linking and drift" part of a report, drawn (docs/domain.md §9, §13, §14): no Django,
as every drawing module of the reports (the data comes from ``analysis.reports.kits``)."""

from __future__ import annotations

from html import escape

from reportlab.lib.units import mm
from reportlab.platypus import Flowable, Spacer

from analysis.reports.data import KitCorrelations, KitLink, KitSection, ReportData
from analysis.reports.sections import by_unc, intro, para, table, unc
from common.quantities import per_day, unit_text, with_unit


def kits_section(data: ReportData) -> list[Flowable]:
    k = data.kits
    if k is None:
        return []
    flow: list[Flowable] = [para("<b>Linking and drift</b>"), para(escape(k.text))]
    flow += [para(escape(n), "bullet") for n in k.notes[:20]]
    if k.drift:
        flow += [Spacer(1, 2 * mm), _drift_table(data, k)]
    if k.links and data.is_participant:
        flow += [Spacer(1, 2 * mm), _links_table(data, k)]
    elif k.links and k.linked_round:
        flow += [Spacer(1, 2 * mm), _labs_table(data, k)]
    if k.correlations and not data.is_participant:
        flow += [Spacer(1, 2 * mm), para(k.correlation_text)]
        for c in k.correlations:
            flow += _correlations(data, c)
    return flow


def _drift_table(data: ReportData, k: KitSection) -> Flowable:
    """The drift per kit and point; a slope in its point's unit per day, in the headings
    where the table has one unit, else in each cell (docs/domain.md §3.1)."""
    units = {per_day(data.points[d.point].unit) for d in k.drift}
    one = units.pop() if len(units) == 1 else None
    heading = f" ({unit_text(one)})" if one else ""
    rows = [["Device", "Point", "Kit", "n", "Model", f"Slope{heading}", f"u(slope){heading}", "p"]]
    for d in k.drift:
        p = data.points[d.point]
        unit = "" if one else per_day(p.unit)  # with_unit(x, "") is x
        rows.append(
            [
                p.device,
                p.label,
                d.kit,
                str(d.n),
                d.model,
                with_unit(by_unc(d.slope, d.u_slope), unit),
                with_unit(unc(d.u_slope), unit),
                "–" if d.p_value is None else f"{d.p_value:.3f}",
            ]
        )
    widths = [16 * mm, 46 * mm, 14 * mm, 8 * mm, 16 * mm, 30 * mm, 28 * mm, 14 * mm]
    return table(rows, widths, wrap=(0, 1, 2, 5, 6))


def _correlations(data: ReportData, c: KitCorrelations) -> list[Flowable]:
    """One point's correlations between degrees of equivalence: the matrix of r (two
    decimals) or its largest pairs."""
    p = data.points[c.point]
    head = f"Correlations r between the degrees of equivalence at {p.device}, {p.label}"
    if c.matrix:
        rows = [["r", *c.codes]]
        rows += [[a, *("–" if x is None else f"{x:.2f}" for x in row)]
                 for a, row in zip(c.codes, c.matrix, strict=True)]  # fmt: skip
        widths = [12 * mm] + [min(11.0, 150.0 / max(len(c.codes), 1)) * mm] * len(c.codes)
        return [Spacer(1, 2 * mm), intro(escape(head) + f" ({c.n} participants):"),
                table(rows, widths)]  # fmt: skip
    rows = [["Lab", "Lab", "r"], *([a, b, f"{r:.2f}"] for a, b, r in c.pairs)]
    return [Spacer(1, 2 * mm),
            intro(escape(head) + f": the {len(c.pairs)} largest |r| of {c.n} participants"),
            table(rows, [14 * mm, 14 * mm, 14 * mm])]  # fmt: skip


def _labs_table(data: ReportData, k: KitSection) -> Flowable:
    """The summary: per participant (by code) its kit, its points linked and not, the
    largest |d|/U(d) and the largest u_link over its points (one per unit, named, where the
    round's points have several: a magnitude's and an angular rate's are not compared, and
    a laboratory of one bench has its one number named too)."""
    by_code: dict[str, list[KitLink]] = {}
    for link in k.links:
        by_code.setdefault(link.code, []).append(link)
    named = len({data.points[x.point].unit for x in k.links}) > 1
    rows = [["Lab", "Kit", "Points linked", "not linked", "largest |d|/U(d)", "largest u_link"]]
    for code, links in sorted(by_code.items()):
        done = [x for x in links if x.d is not None and x.big_u is not None]
        ratio = max((abs(x.d) / x.big_u for x in done if x.big_u and x.d is not None), default=None)
        kits = ", ".join(sorted({x.kit for x in links}))
        shown = "–" if ratio is None else f"{ratio:.2f}"
        u_link = _largest_u_link(data, done, named)
        if done and all(x.d == 0 and x.big_u == 0 for x in done):  # the pilot reference itself
            shown, u_link = "reference", "–"
        rows.append([code, kits, str(len(done)), str(len(links) - len(done)), shown,
                     u_link])  # fmt: skip
    widths = [14 * mm, 24 * mm, 24 * mm, 20 * mm, 28 * mm, 54 * mm]
    return table(rows, widths, wrap=(1, 5))


def _largest_u_link(data: ReportData, done: list[KitLink], named: bool) -> str:
    by_unit: dict[str, float] = {}
    for x in done:
        if x.u_link is not None:
            unit = data.points[x.point].unit
            by_unit[unit] = max(by_unit.get(unit, x.u_link), x.u_link)
    if not (named and by_unit):
        return unc(next(iter(by_unit.values()), None))
    return "; ".join(with_unit(unc(u), unit) for unit, u in by_unit.items())  # point order


def _links_table(data: ReportData, k: KitSection) -> Flowable:
    rows = [["Lab", "Device", "Point", "Kit", "Drift corr.", "u drift", "d", "U(d)", "u_link"]]
    own = []
    for n, link in enumerate(k.links, start=1):
        p = data.points[link.point]
        linked = link.d is not None
        rows.append(
            [
                link.code,
                p.device,
                p.label,
                link.kit,
                by_unc(link.correction, link.u_drift, sign=True) if link.correction else "–",
                unc(link.u_drift) if link.u_drift else "–",
                by_unc(link.d, link.big_u, sign=True)
                if linked
                else ("not linked" if k.linked_round else "–"),
                unc(link.big_u) if linked else "–",
                unc(link.u_link) if linked else "–",
            ]
        )
        if link.code == data.own_code:
            own.append(n)
    widths = [11 * mm, 15 * mm, 50 * mm, 13 * mm, 20 * mm, 17 * mm, 20 * mm, 14 * mm, 14 * mm]
    return table(rows, widths, own, wrap=(1, 2, 3))
