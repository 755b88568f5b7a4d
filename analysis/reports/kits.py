"""The "Linking and drift" part of the reports (docs/domain.md §9, §13, §14): what the run
did with the round's kits, the drift judged per kit and point, and the degrees of
equivalence against the one reference with their link uncertainty — every participant's
by code in the summary, the reader's own only in a participant report."""

from __future__ import annotations

from html import escape

from reportlab.lib.units import mm
from reportlab.platypus import Flowable, Spacer

from analysis.kit_results import kit_fits, kit_scores
from analysis.models import AnalysisRun
from analysis.reports.data import KitDrift, KitLink, KitSection, ReportData
from analysis.reports.sections import by_unc, para, table, unc
from common.sizes import counted

_TREATMENT = {
    "correct": "each result on a drifting kit was corrected to the mean date t̄ of the "
    "pilot's repeats, x − b·(t − t̄), with |t − t̄|·u(b) added to its uncertainty (the "
    "reference corrected to the participant's date)",
    "u_stab": "a drifting kit kept its constant value and each result on it had u_stab(t) = "
    "|b·(t − t̄)|/√3 added to its uncertainty",
}


def kit_section_of_run(run: AnalysisRun, index: dict[int, int]) -> KitSection | None:
    """Every participant's kit rows and the run's drift fits (None: no kits), read once
    per run; :func:`for_reader` keeps what one report may print."""
    fits = list(kit_fits(run))
    if not fits:
        return None
    drift = tuple(
        KitDrift(
            index[f.measurement_point_id],
            d["kit"],
            d["n"],
            d["model"],
            d["slope"],
            d["u_slope"],
            d.get("p_value"),
        )
        for f in fits
        for d in f.drift
    )
    notes = tuple(dict.fromkeys(n for f in fits for n in f.notes))
    linked = [f for f in fits if f.reference]
    links = tuple(
        KitLink(
            k.result.submission.participant.code,
            index[k.result.measurement_point_id],
            k.kit.name if k.kit else "–",
            k.drift_correction,
            k.u_drift,
            k.linked_d,
            None if k.linked_u is None else 2 * k.linked_u,
            k.u_link,
        )
        for k in kit_scores(run)
    )
    treatment = str(run.parameters.get("drift_treatment") or run.comparison.drift_treatment)
    drifting = sum(d.model == "linear" for d in drift)
    text = (
        f"The pilot's repeat measurements judged {counted(len(drift), 'kit and point')} "
        f"(a line where its slope is significant at 5 %): {drifting} drifting. Where a kit "
        f"drifts, {_TREATMENT.get(treatment, treatment)}; elsewhere nothing changed."
    )
    if linked:
        refs = {f.reference for f in linked}
        ref = " and ".join(
            "the pilot" if r == "pilot" else "the weighted mean of the laboratories"
            for r in sorted(refs)
        )
        text += (
            f" Every participant's degree of equivalence d against one reference, "
            f"{ref}, across the kits was found by least squares over the kits and loops "
            f"at {counted(len(linked), 'point')} (the pilot's repeats linking the kits); "
            "U(d) = 2·u(d), and u_link is the part of u(d) that is not the laboratory's "
            f"own. {counted(len(fits) - len(linked), 'point')} could not be linked."
        )
    return KitSection(text, drift, notes, links, bool(linked))


def for_reader(section: KitSection | None, own_code: str | None) -> KitSection | None:
    """The summary keeps every link (by code); a participant report its own only, and the
    run's messages without other participants' codes."""
    if section is None or own_code is None:
        return section
    own = tuple(k for k in section.links if k.code == own_code)
    notes = tuple(n for n in section.notes if own_code in n)
    return KitSection(section.text, section.drift, notes, own, section.linked_round)


def kits_section(data: ReportData) -> list[Flowable]:
    k = data.kits
    if k is None:
        return []
    flow: list[Flowable] = [para("<b>Linking and drift</b>"), para(escape(k.text))]
    flow += [para(escape(n), "bullet") for n in k.notes[:20]]
    if k.drift:
        rows = [["Device", "Point", "Kit", "n", "Model", "Slope per day", "u(slope)", "p"]]
        for d in k.drift:
            p = data.points[d.point]
            rows.append(
                [
                    p.device,
                    p.label,
                    d.kit,
                    str(d.n),
                    d.model,
                    by_unc(d.slope, d.u_slope),
                    unc(d.u_slope),
                    "–" if d.p_value is None else f"{d.p_value:.3f}",
                ]
            )
        widths = [16 * mm, 44 * mm, 16 * mm, 8 * mm, 16 * mm, 24 * mm, 18 * mm, 14 * mm]
        flow += [Spacer(1, 2 * mm), table(rows, widths)]
    if k.links and data.is_participant:
        flow += [Spacer(1, 2 * mm), _links_table(data, k)]
    elif k.links and k.linked_round:
        flow += [Spacer(1, 2 * mm), _labs_table(k)]
    return flow


def _labs_table(k: KitSection) -> Flowable:
    """The summary: per participant (by code) its kit, its points linked and not, the
    largest |d|/U(d) and the largest u_link over its points."""
    by_code: dict[str, list[KitLink]] = {}
    for link in k.links:
        by_code.setdefault(link.code, []).append(link)
    rows = [["Lab", "Kit", "Points linked", "not linked", "largest |d|/U(d)", "largest u_link"]]
    for code, links in sorted(by_code.items()):
        done = [x for x in links if x.d is not None and x.big_u is not None]
        ratio = max((abs(x.d) / x.big_u for x in done if x.big_u and x.d is not None), default=None)
        u_link = max((x.u_link for x in done if x.u_link is not None), default=None)
        kits = ", ".join(sorted({x.kit for x in links}))
        rows.append([code, kits, str(len(done)), str(len(links) - len(done)),
                     "–" if ratio is None else f"{ratio:.2f}", unc(u_link)])  # fmt: skip
    return table(rows, [16 * mm, 30 * mm, 26 * mm, 22 * mm, 32 * mm, 30 * mm])


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
    widths = [11 * mm, 15 * mm, 45 * mm, 13 * mm, 17 * mm, 14 * mm, 18 * mm, 14 * mm, 14 * mm]
    return table(rows, widths, own)
