"""The sections of a PT report (docs/domain.md §9) as lists of platypus flowables."""

from __future__ import annotations

from collections.abc import Sequence
from html import escape

import numpy as np
from reportlab.lib.units import mm
from reportlab.lib.utils import ImageReader
from reportlab.platypus import (
    Flowable,
    Image,
    KeepTogether,
    Paragraph,
    Spacer,
    Table,
    TableStyle,
)

from analysis.consistency import statistic_text
from analysis.reports import figures, standard
from analysis.reports.data import (
    ConsistencyRow,
    Counts,
    HistoryRound,
    LabSummary,
    ReportData,
    ResultListing,
    ResultRow,
    ScoreRow,
)
from analysis.reports.styles import BOLD, GRID, HEAD_BACKGROUND, OWN_BACKGROUND
from analysis.reports.styles import STYLES as S
from analysis.reports.tables import (
    ROW_HEIGHT,
    FastTable,
    LabelRows,
    cell_height,
    cell_styles,
    width_needed,
    wrapped_cells,
)
from common import numbers
from common.quantities import unit_text
from common.sizes import counted

CONFIDENTIALITY = (
    "This report is confidential. Participants are identified by a code known only to "
    "the participant itself and to the coordinators; no participant learns which code "
    "another laboratory holds. The results may not be reproduced, except in full, without "
    "the written permission of the provider."
)
INTERPRETATION = (
    "Interpretation: |En| ≤ {limit:g} means the result agrees with the assigned value within "
    "the stated expanded uncertainties; |En| > {limit:g} (action) means it does not. ζ and z "
    "(or z′) are judged satisfactory at |score| ≤ 2, questionable for 2 < |score| < 3 and "
    "unsatisfactory at |score| ≥ 3 (ISO 13528:2022 §9). D = x − x_pt. Beside the laboratory "
    "code, ● marks a result that entered its point's assigned value (its ζ and En then carry "
    "the correlation correction of Cox 2002) and ○ one that did not; no mark: the assigned "
    "value uses no result. † after En: the result is the sole contributor to its assigned "
    "value, so no correction can be made and the uncorrected sum is used."
)
INSIDE_MARK = {True: " ●", False: " ○", None: ""}


STATUS_TEXT = {
    "final": "Final",
    "preliminary": "Preliminary (not the final report; results may still change)",
    "preview": "Preview for the coordinator (not issued; results may still change)",
}


def num(value: float | None, spec: str) -> str:
    return "–" if value is None else format(value, spec)


# The numbers of a table (docs/domain.md §3.1): an uncertainty (U, u, σ_pt, u_stab) to two
# significant digits; a value beside its own uncertainty (and D beside the result's U)
# rounded to that uncertainty's last digit, trailing zeros kept; a column of values with
# no uncertainty of their own to one number of decimals for the whole column
# (``numbers.column_places``); scores to two decimals.


def unc(u: float | None) -> str:
    """An uncertainty-like number (U, u, σ_pt) to two significant digits; – for none."""
    return "–" if u is None else numbers.uncertainty(u)


def by_unc(x: float | None, u: float | None, *, sign: bool = False) -> str:
    """``x`` to the last digit of ``unc(u)`` (GUM 7.2.6); – for none."""
    return "–" if x is None else numbers.round_to_uncertainty(x, u, sign=sign)


def at(x: float | None, places: int, *, sign: bool = False) -> str:
    """``x`` with ``places`` decimals (a column's :func:`numbers.column_places`)."""
    if x is None:
        return "–"
    text = numbers.fixed(x, places)
    return "+" + text if sign and x > 0 and text.strip("0.") else text


def para(text: str, style: str = "body") -> Paragraph:
    return Paragraph(text, S[style])


def intro(text: str) -> Paragraph:
    """A sentence that introduces the table or figure right after it: a page never ends
    with it (``render.keep_headings`` keeps it with the start of what follows)."""
    return Paragraph(text, S["intro"])


def table(
    rows: list[list[str]],
    widths: Sequence[float],
    own_rows: Sequence[int] = (),
    bad_cells: Sequence[tuple[int, int]] = (),
    wrap: Sequence[int] = (),
) -> Table:
    """A grid with a repeated dark header; the reader's own rows bold on a pink background.

    Cells are single-line strings, except those of the ``wrap`` columns (a point's label)
    that are wider than their column: these are wrapped (:func:`~analysis.reports.tables.
    wrapped_cells`).  Every row's height is given, which saves reportlab from measuring
    every remaining row again at each page break.  The cells' styles are given, one object
    per look (:func:`~analysis.reports.tables.cell_styles`), rather than set by style
    commands on a style object per cell."""
    styles = cell_styles(len(rows), len(widths), own_rows, bad_cells)
    cells, heights = wrapped_cells(rows, widths, wrap, styles)
    t = FastTable(
        cells,
        colWidths=list(widths),
        rowHeights=heights,
        repeatRows=1,
        cellStyles=styles,
    )
    style: list[tuple[object, ...]] = [
        ("BACKGROUND", (0, 0), (-1, 0), HEAD_BACKGROUND),
        ("GRID", (0, 0), (-1, -1), 0.25, GRID),
    ]
    style += [("BACKGROUND", (0, r), (-1, r), OWN_BACKGROUND) for r in own_rows]
    t.setStyle(TableStyle(style))
    return t


def title_page(data: ReportData) -> list[Flowable]:
    """The title block: the provider's logo, name, address and accreditation, the report's
    identity, status, coordinators and authorisation."""
    kind = (
        f"Participant report for participant {data.own_code}"
        if data.is_participant
        else "Summary report"
    )
    rows = [
        ["Proficiency testing provider", data.provider],
        *([["Address", data.provider_address]] if data.provider_address else []),
        *([["Accreditation", data.provider_accreditation]] if data.provider_accreditation else []),
        ["Comparison", f"{data.comparison_code} — {data.comparison_title}"],
        ["Report number", data.report_number],
        ["Issue date", data.issue_date.strftime("%Y-%m-%d")],
        ["Status", STATUS_TEXT.get(data.status, data.status)],
        ["Coordinators", "; ".join(data.coordinators) or "–"],
        ["Authorised by", data.authorised_by or "not yet authorised"],
        ["Software", f"proficiency {data.software_version}"],
    ]
    t = Table([[para(escape(a)), para(escape(b))] for a, b in rows], colWidths=[55 * mm, 119 * mm])
    t.setStyle(
        TableStyle(
            [("LINEBELOW", (0, 0), (-1, -1), 0.25, GRID), ("VALIGN", (0, 0), (-1, -1), "TOP")]
        )
    )
    return [
        *logo(data.provider_logo),
        para(escape(data.provider), "subtitle"),
        para("Proficiency test report", "title"),
        para(escape(kind), "subtitle"),
        t,
        Spacer(1, 4 * mm),
        para(_authorisation(data)),
    ]


LOGO_HEIGHT = 16 * mm


def logo(path: str) -> list[Flowable]:
    """The provider's logo, 16 mm high, at the left; nothing when ``path`` is empty or not
    a readable PNG or JPEG (a report is never refused for its furniture)."""
    if not path:
        return []
    try:
        width, height = ImageReader(path).getSize()
    except (OSError, ValueError):  # missing, unreadable or not an image
        return []
    image = Image(path, width=LOGO_HEIGHT * width / height, height=LOGO_HEIGHT)
    image.hAlign = "LEFT"
    return [image, Spacer(1, 3 * mm)]


def _authorisation(data: ReportData) -> str:
    if not data.authorised_by:
        return (
            "<b>Preliminary report, not yet authorised for issue.</b> The results and "
            "scores may still change before the final report."
        )
    return (
        f"Authorised for issue by {escape(data.authorised_by)}, "
        f"on behalf of {escape(data.provider)}."
    )


def confidentiality(data: ReportData) -> list[Flowable]:
    return [para("1 Confidentiality", "h1"), para(CONFIDENTIALITY)]


SQU = (
    "S satisfactory, Q questionable (a warning signal), U unsatisfactory (an action signal): "
    "En is satisfactory at |En| ≤ {limit:g}, else unsatisfactory; z (z′ where u(x_pt) > "
    "0.3·σ_pt, ISO 13528:2022 9.5) is satisfactory at |z| ≤ 2, questionable for 2 < |z| < 3, "
    "unsatisfactory at |z| ≥ 3 and counted only at points with a σ_pt."
)


def _squ(c: Counts) -> list[str]:
    return [str(c.satisfactory), str(c.questionable), str(c.unsatisfactory)]


def _largest(x: float | None) -> str:
    return "–" if x is None else numbers.fixed(x, 2)


def own_performance(data: ReportData) -> list[Flowable]:
    """The participant's performance summary, first (docs/domain.md §4, "Performance
    summary"): one or two sentences, its counts by device, bench and axis, its largest
    scores; the results section lists every one."""
    mine = data.performance
    flow: list[Flowable] = [para(f"Performance summary of participant {data.own_code}", "h1")]
    if mine is None:
        return [*flow, para("This report has no scored result of yours.")]
    flow.append(intro(_performance_text(data, mine)))
    has_z = bool(mine.total.z.scored or mine.total.z.not_scored)
    head = ["", "n", "En S", "En Q", "En U", *(["z S", "z Q", "z U"] if has_z else [])]
    rows, bad = [head], []
    lines = [("All results", mine.total)]
    lines += [(f"{heading} {line.level}", line) for heading, found in mine.breakdowns
              for line in found]  # fmt: skip
    for label, line in lines:
        n = line.en.scored + line.en.not_scored
        rows.append([label, str(n), *_squ(line.en), *(_squ(line.z) if has_z else [])])
        bad += [(len(rows) - 1, c) for c, k in ((4, line.en.unsatisfactory),
                (7, line.z.unsatisfactory if has_z else 0)) if k]  # fmt: skip
    widths = [58 * mm, 14 * mm] + [14 * mm] * (len(head) - 2)
    flow += [table(rows, widths, (), bad), para(SQU.format(limit=data.en_limit), "small")]
    flow += _worst_table(data, mine)
    return flow


def _performance_text(data: ReportData, mine: LabSummary) -> str:
    en, z, limit = mine.total.en, mine.total.z, data.en_limit
    text = (
        f"Of your {mine.n_results} results, {en.satisfactory} are satisfactory in En "
        f"(|En| ≤ {limit:g}) and {en.unsatisfactory} unsatisfactory"
        + (f", {en.not_scored} not scored" if en.not_scored else "")
        + f"; the largest |En| is {_largest(mine.max_en)}."
    )
    if not (z.scored or z.not_scored):
        return text + " No z score: none of your points has a σ_pt."
    return text + (
        f" In z (or z′), {z.satisfactory} of {z.scored} are satisfactory, {z.questionable} "
        f"questionable and {z.unsatisfactory} unsatisfactory; the largest |z| is "
        f"{_largest(mine.max_z)}. Section 6 lists every result with its scores."
    )


def _worst_table(data: ReportData, mine: LabSummary) -> list[Flowable]:
    """The largest |En| and |z| results, whatever their flags (the first places to look):
    one row per result, |En|'s first."""
    rows = [["Largest scores", "Point", "Score", "Flag"]]
    bad = []
    for s in mine.worst_en:
        rows.append(["|En|", data.points[s.point].full_label, f"En {s.en:.2f}", s.flag])
        if abs(s.en) > data.en_limit:
            bad.append((len(rows) - 1, 2))
    for s in mine.worst_z:
        rows.append(["|z|", data.points[s.point].full_label, f"{s.z_kind} {num(s.z, '.2f')}",
                     s.z_flag])  # fmt: skip
        if s.z_flag == "action":
            bad.append((len(rows) - 1, 2))
    if len(rows) == 1:
        return []
    widths = [27 * mm, 85 * mm, 24 * mm, 26 * mm]
    return [Spacer(1, 2 * mm), table(rows, widths, (), bad, wrap=(1,))]


HISTORY_NOTE = (
    "Your code is drawn anew in every round, so it differs between rounds. Points of "
    "different rounds are comparable when they have the same device model, bench, "
    "direction and axis and the same frequency and excitation amplitude (to a relative "
    "10⁻⁶); RSZ = Σz/√n and RLP = √(Σz²/n) combine the z (or z′) of the n rounds in which "
    "a comparable point has one."
)


def _share(satisfactory: int, scored: int) -> str:
    return "–" if not scored else f"{satisfactory}/{scored} ({100 * satisfactory / scored:.0f} %)"


def _round_row(r: HistoryRound) -> list[str]:
    en, z = _share(r.en_satisfactory, r.en_scored), _share(r.z_satisfactory, r.z_scored)
    return [r.code, r.date.strftime("%Y-%m-%d"), r.own_code, str(r.en_scored), en, z]


def own_history(data: ReportData) -> list[Flowable]:
    """The participant's results over the rounds up to this one (docs/domain.md §4.1): a
    row per round, a row per comparable point with RSZ and RLP; only its own codes."""
    found = data.history
    if found is None:
        return []
    flow: list[Flowable] = [para("Your results over the rounds", "h1")]
    if len(found.rounds) <= 1:
        return [*flow, para("This is the only round of your laboratory so far: there is no "
                            "history across rounds yet.")]  # fmt: skip
    head = ["Round", "Date", "Your code", "n", "Satisfactory En", "Satisfactory z"]
    rows = [head, *(_round_row(r) for r in found.rounds)]
    widths = [34 * mm, 22 * mm, 20 * mm, 12 * mm, 36 * mm, 36 * mm]
    flow += [intro(f"Your laboratory took part in {len(found.rounds)} rounds up to this one."),
             table(rows, widths, ()), *standard.history_graph(data)]  # fmt: skip
    points = [["Comparable point", "Rounds", "RSZ", "RLP"]]
    for p in found.points:
        points.append([p.label, str(p.n_rounds), _combined(p.rsz, p.rsz_flag),
                       _combined(p.rlp, p.rlp_flag)])  # fmt: skip
    flow += [Spacer(1, 2 * mm), table(points, [88 * mm, 16 * mm, 28 * mm, 28 * mm], wrap=(0,)),
             para(HISTORY_NOTE, "small")]  # fmt: skip
    return flow


def _combined(value: float | None, flag: str) -> str:
    return "–" if value is None else f"{numbers.fixed(value, 2)} {flag}"


def participants_performance(data: ReportData) -> list[Flowable]:
    """Every participant's counts in one table (the coordinator's performance page)."""
    found = data.performances
    flow: list[Flowable] = [para("Performance of the participants", "h1")]
    if not found:
        return [*flow, para("No participant has a scored result in this run.")]
    signals = sum(1 for lab in found if lab.total.en.unsatisfactory or lab.total.z.unsatisfactory)
    flow.append(intro(
        f"{counted(len(found), 'participant')} with scored results; {signals} with at least "
        "one unsatisfactory En or z. Per participant: its number of results, the En and z "
        "(or z′) counts and its largest |En| and |z|."
    ))  # fmt: skip
    head = ["Code", "n", "En S", "En Q", "En U", "z S", "z Q", "z U", "max |En|", "max |z|"]
    rows: list[list[str]] = []
    bad: list[tuple[int, int]] = []
    for lab in found:
        en, z = lab.total.en, lab.total.z
        rows.append([lab.code, str(lab.n_results), *_squ(en), *_squ(z), _largest(lab.max_en),
                     _largest(lab.max_z)])  # fmt: skip
        bad += [(len(rows), c) for c, k in ((4, en.unsatisfactory), (7, z.unsatisfactory)) if k]
    widths = [22 * mm, 14 * mm] + [14 * mm] * 6 + [19 * mm, 19 * mm]
    return [*flow, PagedTable(head, rows, widths, bad), para(SQU.format(limit=data.en_limit),
                                                            "small")]  # fmt: skip


class PagedTable(Flowable):
    """Rows of single-line cells under a header repeated on every page, built one page at
    a time as :class:`ListingTable` is (one ``Table`` of ten thousand rows costs quadratic
    time at its page breaks).  ``bad`` holds (row, column) of red cells, rows from 1."""

    def __init__(
        self,
        head: list[str],
        rows: list[list[str]],
        widths: Sequence[float],
        bad: Sequence[tuple[int, int]] = (),
        start: int = 0,
    ) -> None:
        super().__init__()
        self.head, self.rows, self.widths, self.bad, self.start = head, rows, widths, bad, start

    def wrap(self, availWidth: float, availHeight: float) -> tuple[float, float]:
        self.width, self.height = sum(self.widths), (len(self.rows) - self.start + 1) * ROW_HEIGHT
        return self.width, self.height

    def split(self, availWidth: float, availHeight: float) -> list[Flowable]:
        fit = min(int(availHeight // ROW_HEIGHT) - 1, len(self.rows) - self.start)
        if fit <= 0:
            return []
        part = self.table(self.start, self.start + fit)
        if self.start + fit == len(self.rows):
            return [part]
        rest = PagedTable(self.head, self.rows, self.widths, self.bad, self.start + fit)
        return [part, rest]

    def draw(self) -> None:
        part = self.table(self.start, len(self.rows))
        part.wrap(self.width, self.height)
        part.drawOn(self.canv, 0, 0)

    def table(self, start: int, stop: int) -> Table:
        bad = [(r - start, c) for r, c in self.bad if start < r <= stop]
        return table([self.head, *self.rows[start:stop]], self.widths, (), bad)


def design(data: ReportData) -> list[Flowable]:
    freqs = ", ".join(f"{f:g}" for f in data.frequencies_hz)
    flow: list[Flowable] = [
        para("2 Scheme design and protocol", "h1"),
        para(
            f"<b>Protocol:</b> {escape(data.protocol_title)}. {escape(data.protocol_description)}"
        ),
        para(f"<b>Frequencies:</b> {freqs} Hz. <b>Measurement points:</b> {len(data.points)}."),
    ]
    flow += [para(f"<b>Bench:</b> {escape(b)}", "bullet") for b in data.bench_descriptions]
    if data.amplitudes:
        flow.append(para("<b>Amplitudes:</b> " + escape("; ".join(data.amplitudes)) + "."))
    return flow


def artefacts(data: ReportData) -> list[Flowable]:
    rows = [["Device", "Model", "Serial", "Nominal ± tolerance", "Distribution", "Unit"]]
    for d in data.devices:
        tol = "–"
        if d.nominal is not None:
            pct = " %" if d.tolerance_relative else ""
            tol = f"{d.nominal:g} ± {num(d.tolerance, 'g')}{pct}"
        rows.append([d.name, d.model or "–", d.serial or "–", tol, d.distribution,
                     unit_text(d.unit)])  # fmt: skip
    return [
        para("3 Artefacts", "h1"),
        table(rows, [18 * mm, 22 * mm, 34 * mm, 34 * mm, 34 * mm, 32 * mm], wrap=(0, 1, 2, 5)),
        Spacer(1, 3 * mm),
        (intro if data.stability_rows else para)(
            f"<b>Homogeneity and stability:</b> {escape(data.stability)}"
        ),
        *_stability_table(data),
    ]


def _stability_table(data: ReportData) -> list[Flowable]:
    """The pilot's before/after means per point, Δ, En, 0.3·σ_pt and the verdict (§7)."""
    if not data.stability_rows:
        return []
    rows = [["Device", "Point", "before", "after", "Δ", "En", "0.3·σ_pt", "Stable", "u_stab"]]
    bad = []
    places = numbers.column_places(v for r in data.stability_rows for v in (r.before, r.after))
    for n, r in enumerate(data.stability_rows, start=1):
        p = data.points[r.point]
        rows.append(
            [
                p.device,
                p.label,
                at(r.before, places),
                at(r.after, places),
                at(r.delta, places, sign=True),
                f"{r.en:.2f}",
                unc(r.limit),
                "yes" if r.stable else "no",
                unc(r.u_stab),
            ]
        )
        if not r.stable:
            bad.append((n, 7))
    widths = [16 * mm, 52 * mm, 17 * mm, 17 * mm, 16 * mm, 11 * mm, 17 * mm, 13 * mm, 15 * mm]
    return [table(rows, widths, (), bad, wrap=(0, 1))]  # right below its intro (stability)


CODES_LISTED = 1000  # above this many participants a participant report lists no codes


def participants(data: ReportData) -> list[Flowable]:
    """The participants by code; a participant report of a round of more than
    ``CODES_LISTED`` participants gives their number and its own code only (pages of
    codes in each of thousands of reports; the summary lists them)."""
    ref = (
        f" The reference (pilot) laboratory is {data.reference_code}."
        if data.reference_code
        else ""
    )
    n = len(data.participants)
    if data.is_participant and n > CODES_LISTED:
        text = (
            f"{n:,} participants; your code is <b>{data.own_code}</b>. The summary report "
            f"lists every participant's code.{ref}"
        )
        return [para("4 Participants", "h1"), para(text)]
    codes = ", ".join(f"<b>{c}</b>" if c == data.own_code else c for c in data.participants)
    return [
        para("4 Participants", "h1"),
        para(f"{n} participants, by code: {codes}.{ref}"),
    ]


def assigned_values(data: ReportData) -> list[Flowable]:
    rows = [["Device", "Point", "x_pt", "u(x_pt)", "U(x_pt)", "σ_pt", "Method"]]
    for a in data.assigned:
        p = data.points[a.point]
        k = "" if a.coverage_factor == 2.0 else f" (k = {a.coverage_factor:g})"
        method = a.method if a.exhaustive else f"{a.method} (approximate)"
        rows.append(
            [
                p.device,
                p.label,
                by_unc(a.value, a.standard_uncertainty),
                unc(a.standard_uncertainty),
                f"{unc(a.expanded_uncertainty)}{k}",
                unc(a.sigma_pt),
                method,
            ]
        )
    flow: list[Flowable] = [
        para("5 Assigned values", "h1"),
        para(f"<b>Metrological traceability:</b> {escape(data.traceability)}"),
        intro(
            f"<b>σ_pt:</b> {escape(data.sigma_pt_description)}. U(x_pt) = 2·u(x_pt) (k = 2), "
            "except a reference laboratory's U, taken as it reported it (its k in brackets)."
        ),
    ]
    approximate = [a for a in data.assigned if not a.exhaustive]
    if approximate:
        flow.append(intro(
            f"<b>Warning:</b> {counted(len(approximate), 'point')} had too many results for the "
            "exact largest-consistent-subset search; their subset is the sequential approximation, "
            "which can be smaller than the largest consistent subset (marked “approximate”)."
        ))  # fmt: skip
    widths = [18 * mm, 44 * mm, 20 * mm, 16 * mm, 20 * mm, 14 * mm, 42 * mm]
    flow.append(table(rows, widths, wrap=(0, 1, 6)))
    left_out = [(data.points[a.point], a.excluded) for a in data.assigned if a.excluded]
    if left_out:
        listed = "; ".join(
            f"{escape(p.device)} {escape(p.label)}: {', '.join(codes)}" for p, codes in left_out
        )
        flow.append(para(
            "Results left out of the largest consistent subset (still scored, without the "
            f"correlation correction), by participant code: {listed}.", "small",
        ))  # fmt: skip
    return flow


def results_and_scores(data: ReportData) -> list[Flowable]:
    """Per device: every result (value, U, k) with its scores and flag (docs/domain.md §4)."""
    scores = {(s.point, s.lab): s for s in data.scores}
    flow: list[Flowable] = [
        para("6 Results and scores", "h1"),
        para(INTERPRETATION.format(limit=data.en_limit)),
    ]
    if data.listing is not None:
        for device, start, stop in data.listing.devices:
            flow += [para(escape(device), "h2"), ListingTable(data, data.listing, start, stop)]
        return flow
    shown = data.results
    if is_large(data):
        shown = tuple(r for r in data.results if r.lab == data.own_code)
        flow += [intro(_LARGE_ROUND.format(n=data.round.n_results, own=data.own_code))]
        flow += _spread_table(data)
    by_device: dict[str, list[ResultRow]] = {}
    for r in shown:
        by_device.setdefault(data.points[r.point].device, []).append(r)
    for device in sorted(by_device):
        flow += [para(escape(device), "h2"), _result_table(data, by_device[device], scores)]
    return flow


FULL_TABLE_ROWS = 2000  # above this, a participant report lists its own rows only
_LARGE_ROUND = (
    "This round has {n:,} results: this report lists yours ({own}) with the spread of all "
    "participants' results at each point; the summary report lists every result by code."
)


def is_large(data: ReportData) -> bool:
    """A participant report of a round too large to list every result."""
    return data.is_participant and data.round.n_results > FULL_TABLE_ROWS


def _spread_table(data: ReportData) -> list[Flowable]:
    """Per point: number of results, min / median / max, x_pt and the incompatible count."""
    x_pt = {a.point: a.value for a in data.assigned}
    rows = [["Device", "Point", "n", "min", "median", "max", "x_pt", "|En| > limit"]]
    spread = data.round.spread
    places = numbers.column_places(
        v for r in spread for v in (r.low, r.median, r.high, x_pt.get(r.point))
    )
    for r in spread:
        p = data.points[r.point]
        rows.append(
            [p.device, p.label, str(r.n), at(r.low, places), at(r.median, places),
             at(r.high, places), at(x_pt.get(r.point), places), str(r.bad)]
        )  # fmt: skip
    widths = [16 * mm, 46 * mm, 12 * mm, 20 * mm, 20 * mm, 20 * mm, 20 * mm, 20 * mm]
    return [table(rows, widths, wrap=(0, 1)), Spacer(1, 2 * mm)]


def _result_table(
    data: ReportData, rows: Sequence[ResultRow], scores: dict[tuple[int, str], ScoreRow]
) -> Table:
    out = [list(RESULT_HEAD)]
    own: list[int] = []
    bad: list[tuple[int, int]] = []
    last = -1
    for r in rows:
        s: ScoreRow | None = scores.get((r.point, r.lab))
        label = data.points[r.point].label if r.point != last else ""
        last = r.point
        out.append(
            result_cells(
                label, r.lab, r.value, r.expanded_uncertainty, r.coverage_factor,
                s.d if s else None, s.en if s else None, s.zeta if s else None,
                s.z if s else None, s.flag if s else "–",
                inside=s.in_assigned_value if s else None,
                failed=s.correlation_failed if s else False,
            )
        )  # fmt: skip
        if r.lab == data.own_code:
            own.append(len(out) - 1)
        if s and abs(s.en) > data.en_limit:
            bad.append((len(out) - 1, 6))
    return table(out, RESULT_WIDTHS, own, bad, wrap=(0,))


RESULT_HEAD = ["Point", "Lab", "Value", "U", "k", "D", "En", "ζ", "z / z′", "Flag"]


def result_cells(
    label: str, lab: str, value: float, big_u: float, k: float,
    d: float | None, en: float | None, zeta: float | None, z: float | None, flag: str,
    *, inside: bool | None = None, failed: bool = False,
) -> list[str]:  # fmt: skip
    """One row of the results table (both the one-table and the page-by-page listing);
    ``inside`` marks the lab code (see INTERPRETATION), ``failed`` puts † after En."""
    en_text = num(en, ".2f") + ("†" if failed else "")
    x_text, u_text = numbers.value_with_uncertainty(value, big_u)
    return [label, lab + INSIDE_MARK[inside], x_text, u_text, f"{k:g}",
            by_unc(d, big_u, sign=True), en_text, num(zeta, ".2f"), num(z, ".2f"),
            flag]  # fmt: skip


RESULT_WIDTHS = [
    42 * mm,
    14 * mm,
    19 * mm,
    14 * mm,
    8 * mm,
    17 * mm,
    13 * mm,
    13 * mm,
    14 * mm,
    20 * mm,
]


class ListingTable(Flowable):
    """Rows ``start:stop`` of a :class:`ResultListing` as a results table built one page at
    a time: splitting builds a page-sized :class:`FastTable` of the rows that fit (their
    heights are known: one line, or a wrapped label's lines, :class:`~analysis.reports.
    tables.LabelRows`) and a new ``ListingTable`` of the rest, so the cost is linear in the
    rows and only one page of cells exists at a time.  (One reportlab ``Table`` of every
    row re-creates the remaining rows at each page break: quadratic time, and the cells of
    every row held at once.)  The point's label is printed on its first row and again at
    the top of each page."""

    def __init__(
        self, data: ReportData, listing: ResultListing, start: int, stop: int,
        labels: LabelRows | None = None,
    ) -> None:  # fmt: skip
        super().__init__()
        self.data, self.listing, self.start, self.stop = data, listing, start, stop
        self.labels = labels or LabelRows(
            listing.point[start:stop], start,
            lambda p: cell_height(data.points[p].label, RESULT_WIDTHS[0]),
        )  # fmt: skip

    def _height(self, start: int, stop: int) -> float:
        """The height of rows ``start:stop`` under the header."""
        return (stop - start + 1) * ROW_HEIGHT + self.labels.added(start, stop)

    def wrap(self, availWidth: float, availHeight: float) -> tuple[float, float]:
        self.width, self.height = sum(RESULT_WIDTHS), self._height(self.start, self.stop)
        return self.width, self.height

    def split(self, availWidth: float, availHeight: float) -> list[Flowable]:
        fit = min(int(availHeight // ROW_HEIGHT) - 1, self.stop - self.start)
        while fit > 0 and self._height(self.start, self.start + fit) > availHeight:
            fit -= 1
        while fit > 0:
            part = self.table(self.start, self.start + fit)
            if part.wrap(availWidth, availHeight)[1] <= availHeight:
                break
            fit -= 1
        if fit <= 0:
            return []
        if self.start + fit == self.stop:
            return [part]
        rest = ListingTable(self.data, self.listing, self.start + fit, self.stop, self.labels)
        return [part, rest]

    def draw(self) -> None:
        part = self.table(self.start, self.stop)
        part.wrap(self.width, self.height)
        part.drawOn(self.canv, 0, 0)

    def table(self, start: int, stop: int) -> Table:
        """The rows ``start:stop`` with the header, formatted as :func:`_result_table` does."""
        data, s = self.data, self.listing
        limit, labs, flags = data.en_limit, s.labs, s.flags
        out = [list(RESULT_HEAD)]
        bad: list[tuple[int, int]] = []
        last = -1
        size = stop - start
        inside = s.inside[start:stop] if s.inside is not None else np.full(size, -1)
        failed = s.failed[start:stop] if s.failed is not None else np.zeros(size, dtype=bool)
        columns = zip(
            *(
                a[start:stop].tolist()
                for a in (s.point, s.lab, s.value, s.expanded_uncertainty, s.coverage_factor,
                          s.d, s.en, s.zeta, s.z, s.flag)
            ),
            inside.tolist(), failed.tolist(),
            strict=True,
        )  # fmt: skip
        for n, (point, lab, x, big_u, k, d, en, zeta, z, flag, ins, fail) in enumerate(
            columns, start=1
        ):
            label = data.points[point].label if point != last else ""
            no_z = z != z  # NaN: no z
            out.append(
                result_cells(label, labs[lab], x, big_u, k, d, en, zeta, None if no_z else z,
                             flags[flag], inside=None if ins < 0 else bool(ins), failed=fail)
            )  # fmt: skip
            last = point
            if abs(en) > limit:
                bad.append((n, 6))
        return table(out, RESULT_WIDTHS, (), bad, wrap=(0,))


def matrices(data: ReportData) -> list[Flowable]:
    flow: list[Flowable] = [para("7 Compatibility matrices", "h1")]
    if not data.matrices:
        return [*flow, para("No compatibility matrices were stored for this run.")]
    flow.append(intro(f"Pairwise En between levels; |En| > {data.en_limit:g} is incompatible."))
    for m in data.matrices:
        head = ["", "value", "U", *list(m.levels)]
        rows = [head]
        bad = []
        for i, level in enumerate(m.levels):
            value, big_u = m.values[i], m.expanded_uncertainties[i]
            row = [level, by_unc(value, big_u), unc(big_u)]
            row += ["–" if i == j else f"{e:.2f}" for j, e in enumerate(m.en[i])]
            bad += [(i + 1, j + 3) for j, e in enumerate(m.en[i]) if i != j and e > data.en_limit]
            rows.append(row)
        widths = [22 * mm, 18 * mm, 14 * mm] + [_level_width(m.levels)] * len(m.levels)
        title = f"{m.factor} | {m.group} — {counted(m.incompatible_pairs, 'incompatible pair')}"
        part = table(rows, widths, (), bad, wrap=(0,))
        flow.append(KeepTogether([para(escape(title), "small"), part, Spacer(1, 3 * mm)]))
    return flow


def _level_width(levels: Sequence[str]) -> float:
    """The width of a matrix's En columns: 18 mm, less where many levels share 110 mm, but
    wide enough for the levels' names in their bold heading (``curvilinear``) while all of
    them fit in 120 mm."""
    n = max(len(levels), 1)
    needed = max((width_needed(str(v), BOLD) for v in levels), default=0.0)
    return min(max(min(18.0, 110.0 / n) * mm, needed), 120.0 * mm / n)


CONSISTENCY = (
    "The tests of ISO 5725-2 §7 at each measurement point, on each participant's result (the "
    "mean of its repeats): Grubbs' test for one outlying result and, where it finds no "
    "outlier, for two; Mandel's h of each participant. Where the participants gave the "
    "standard deviation of their repeats and their number (the same number everywhere): "
    "Cochran's test of the largest variance and Mandel's k of each participant. A statistic "
    "beyond its 5 % critical value marks a straggler, beyond its 1 % value an outlier (the "
    "double Grubbs ratio is small when two results lie apart: beyond means below); "
    "stragglers and outliers are reasons to look at a result, not to reject it. The "
    "participants' scores above do not depend on these tests."
)


def consistency(data: ReportData) -> list[Flowable]:
    """The points where an ISO 5725-2 test signals, one row per finding (docs/domain.md §6)."""
    flow: list[Flowable] = [para("8 Consistency of the results (ISO 5725-2)", "h1"),
                            para(CONSISTENCY)]  # fmt: skip
    c = data.consistency
    if c is None:
        return [*flow, para("This analysis run stored no consistency tests (it was made before "
                            "they existed); a new run computes them.")]  # fmt: skip
    lead = intro if c.rows else para  # introduces the findings' table, if there is one
    flow.append(
        lead(
            f"A test signals a straggler or an outlier at {c.n_signalling} of "
            f"{c.n_points} measurement points" + (": listed below." if c.rows else ".")
        )
    )
    if c.not_applicable:
        text = "; ".join(f"{escape(t)} at {n} point{'s' if n != 1 else ''} ({escape(why)})"
                         for t, why, n in c.not_applicable)  # fmt: skip
        flow.append(lead(f"<b>Not applicable:</b> {text}."))
    if c.rows:
        flow.append(_consistency_table(data, c.rows))
    return flow


def _consistency_table(data: ReportData, rows: Sequence[ConsistencyRow]) -> Table:
    st = statistic_text
    out = [["Device", "Point", "Test", "Lab", "Statistic", "Critical 5 % / 1 %", "Verdict"]]
    own, bad = [], []
    for r in rows:  # the point on every row: a point's findings may run over a page break
        p = data.points[r.point]
        out.append([p.device, p.label, r.test, r.labs, st(r.statistic),
                    f"{st(r.critical_5)} / {st(r.critical_1)}", r.verdict])  # fmt: skip
        if data.own_code and data.own_code in r.labs.split(", "):
            own.append(len(out) - 1)
        if r.verdict == "outlier":
            bad.append((len(out) - 1, 6))
    widths = [16 * mm, 46 * mm, 30 * mm, 20 * mm, 16 * mm, 28 * mm, 18 * mm]
    return table(out, widths, own, bad, wrap=(0, 1, 2))


def charts(data: ReportData) -> list[Flowable]:
    return [para("9 Graphs", "h1"), *figures.figures(data)]


def plain(text: str) -> str:
    """Coordinator text as paragraph markup: <, > and & escaped (reportlab's Paragraph
    reads markup), line breaks kept."""
    return escape(text.strip(), quote=False).replace("\r\n", "\n").replace("\n", "<br/>")


def comments(data: ReportData) -> list[Flowable]:
    """The coordinator's comments and conclusions, then the count of compatible results."""
    n, bad = data.round.n_scores, data.round.n_bad
    conclusions = plain(data.conclusions) or "No conclusions were entered."
    return [
        para("10 Comments and conclusions", "h1"),
        para("Comments on performance", "h2"),
        para(plain(data.comments) or "No comments."),
        para("Conclusions", "h2"),
        para(conclusions),
        para(
            f"<b>Conclusion:</b> {n - bad} of {n} results are compatible with their assigned "
            f"values (|En| ≤ {data.en_limit:g}); {bad} are not."
        ),
    ]
