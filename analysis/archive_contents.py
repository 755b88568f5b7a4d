"""What a round's archive holds (docs/interfaces.md §6), written entry by entry into a ZIP.

Every entry is written as a stream into its ZIP member (``ZipFile.open(..., "w")``): rows
are read from querysets a few thousand at a time and reports copied in 1 MiB blocks, so
the archive's memory does not grow with the round.  The ZIP is the same bytes whenever
it is built from the same stored outputs: members in name order, each dated the run's
finish time (not the clock's), and every table in a fixed row order.

The two audiences see what their pages show: the coordinators every participant by code;
a participant its own results, every score by code (as its scores download), the
assigned values and matrices (aggregates, no laboratory), its own report and the summary.
No laboratory's name is written by this module.
"""

from __future__ import annotations

import datetime as dt
import shutil
import zipfile
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Any, BinaryIO

from django.conf import settings
from django.db.models import Count, Q

from analysis.access import download_name, reports_visible
from analysis.kit_results import COVARIANCE_COLUMNS, covariance_rows
from analysis.models import AnalysisRun, AssignedValue, CompatibilityMatrix, KitPointFit, Report
from analysis.selectors import score_columns_of, score_records
from labs.access import ComparisonAccess
from labs.importers import COLUMNS, write_table_to
from labs.models import Participant, Result
from proficiency.models import ComparisonStatus
from proficiency.selectors import POINT_ORDER

#: the rows an XLSX sheet holds (Excel's limit, less the header): beyond, scores.csv only
XLSX_MAX_ROWS = 1_048_575
#: an entry that may pass 2 GiB needs ZIP64 sizes in its local header before it is written
ZIP64_ROWS = 1_000_000
ASSIGNED_COLUMNS = [
    "device", "axis", "frequency_hz", "bench", "direction", "unit", "method", "value",
    "standard_uncertainty", "expanded_uncertainty", "coverage_factor", "sigma_pt", "n",
    "chi2_obs", "birge_ratio", "consistent", "n_excluded", "exhaustive", "excluded",
]  # fmt: skip
MATRIX_COLUMNS = [
    "factor", "group", "level_i", "value_i", "expanded_uncertainty_i", "level_j", "value_j",
    "expanded_uncertainty_j", "en",
]  # fmt: skip
_RESULT_FIELDS = {
    "lab": "submission__participant__code", "device": "measurement_point__device__name",
    "axis": "measurement_point__axis", "frequency_hz": "measurement_point__frequency_hz",
    "bench": "measurement_point__bench", "direction": "measurement_point__direction",
    "amplitude_m_s2": "measurement_point__amplitude_m_s2", "sensitivity": "value",
    "unit": "unit", "expanded_uncertainty": "expanded_uncertainty",
    "coverage_factor": "coverage_factor", "dof": "dof", "note": "note",
    "repeat_sd": "repeat_sd", "n_repeats": "n_repeats", "measured_on": "measured_on",
}  # fmt: skip


@dataclass(frozen=True)
class Entry:
    """One member of the archive: its name, what the README says of it, its writer."""

    name: str
    what: str
    write: Callable[[BinaryIO], object]


@dataclass(frozen=True)
class Audience:
    """Whose archive: the coordinators' (``participant`` None) or one participant's."""

    run: AnalysisRun
    participant: Participant | None = None

    @property
    def access(self) -> ComparisonAccess:
        return ComparisonAccess(self.run.comparison, self.participant, self.participant is None)


def archive_reports(audience: Audience) -> list[Report]:
    """The reports an archive holds: of each report issued from the run that the audience
    may read (``analysis.access.reports_visible``: a participant, once published, the
    final summary and its own), the newest version."""
    newest: dict[tuple[str, int | None], Report] = {}
    for report in reports_visible(audience.access).filter(run=audience.run):
        newest.setdefault((report.kind, report.participant_id), report)  # newest first
    return sorted(newest.values(), key=download_name)


def archive_entries(audience: Audience, reports: list[Report]) -> list[Entry]:
    """Every member of the archive, README.txt first, then in name order."""
    run, when = audience.run, stamp(audience.run)
    n_scores = run.scores.count()
    entries = [
        _results_entry(audience, n_scores),
        _scores_entry(run, "csv", n_scores, when),
        _assigned_entry(run),
        *_matrix_entries(run),
        *_covariance_entries(audience),
        *(_report_entry(r) for r in reports),
    ]
    if n_scores <= XLSX_MAX_ROWS:
        entries.append(_scores_entry(run, "xlsx", n_scores, when))
    entries.sort(key=lambda e: e.name)
    return [_readme(audience, entries, n_scores), *entries]


def write_archive(out: BinaryIO, entries: list[Entry], when: dt.datetime) -> None:
    """The ZIP (deflated) of ``entries`` into ``out``, each member dated ``when``."""
    date_time = zip_date(when)
    with zipfile.ZipFile(out, "w", zipfile.ZIP_DEFLATED, allowZip64=True) as archive:
        for entry in entries:
            info = zipfile.ZipInfo(entry.name, date_time=date_time)
            info.compress_type = zipfile.ZIP_DEFLATED
            info.external_attr = 0o644 << 16
            large = getattr(entry.write, "large", False)
            with archive.open(info, "w", force_zip64=large) as member:
                entry.write(member)  # type: ignore[arg-type]  # a ZipExtFile is a binary file


def stamp(run: AnalysisRun) -> dt.datetime:
    """The date of every member: the run's finish (fixed once the run succeeded)."""
    return (run.finished_at or run.created_at).astimezone(dt.UTC)


def zip_date(when: dt.datetime) -> tuple[int, int, int, int, int, int]:
    if when.year < 1980:  # the earliest date a ZIP member can carry
        return (1980, 1, 1, 0, 0, 0)
    return (when.year, when.month, when.day, when.hour, when.minute, when.second)


def _large(write: Callable[[BinaryIO], object], n_rows: int) -> Callable[[BinaryIO], object]:
    write.large = n_rows > ZIP64_ROWS  # type: ignore[attr-defined]
    return write


# --- the tables -----------------------------------------------------------------------------


def _result_rows(audience: Audience) -> Iterator[dict[str, Any]]:
    """The results the run scored (a participant's: its own), as §1 rows by code."""
    found = Result.objects.filter(scores__run=audience.run)
    if audience.participant is not None:
        found = found.filter(submission__participant=audience.participant)
    order = ("submission__participant__code", *POINT_ORDER)
    names = list(_RESULT_FIELDS)
    rows = found.order_by(*order).values_list(*_RESULT_FIELDS.values())
    for values in rows.iterator(chunk_size=5000):
        yield dict(zip(names, values, strict=True))


def _result_columns(audience: Audience) -> list[str]:
    """Every §1 column, ``repeat_sd`` and ``n_repeats``, and ``measured_on``, only when a
    result has one (as a results download leaves them out)."""
    found = Result.objects.filter(scores__run=audience.run)
    with_repeats = found.filter(Q(repeat_sd__isnull=False) | Q(n_repeats__isnull=False)).exists()
    dated = found.filter(measured_on__isnull=False).exists()
    left_out = (() if with_repeats else ("repeat_sd", "n_repeats")) + (
        () if dated else ("measured_on",)
    )
    return [c for c in COLUMNS if c not in left_out]


def _results_entry(audience: Audience, n_scores: int) -> Entry:
    def write(out: BinaryIO) -> None:
        write_table_to(out, _result_rows(audience), format="csv",
                       columns=_result_columns(audience))  # fmt: skip

    whose = "your laboratory's results" if audience.participant else "every participant's results"
    return Entry(
        "results.csv",
        f"{whose} that the run scored, as a results table (the columns of an upload): one row "
        "per result, laboratories by participant code; the input of pt_compare",
        _large(write, n_scores),
    )


def _scores_entry(run: AnalysisRun, fmt: str, n_scores: int, when: dt.datetime) -> Entry:
    def write(out: BinaryIO) -> None:
        write_table_to(out, score_records(run, {}), format=fmt,  # type: ignore[arg-type]
                       columns=score_columns_of(run.comparison), when=when)  # fmt: skip

    return Entry(
        f"scores.{fmt}",
        f"every score of the run ({fmt.upper()}): the scores download of the results pages, "
        "one row per result with its point's assigned value, full precision",
        _large(write, n_scores),
    )


def _assigned_rows(run: AnalysisRun) -> Iterator[dict[str, Any]]:
    found = AssignedValue.objects.filter(run=run).select_related("measurement_point__device")
    counts = dict(
        run.scores.values_list("result__measurement_point").annotate(n=Count("pk")).order_by()
    )
    for a in found.order_by(*POINT_ORDER).iterator(chunk_size=2000):
        p, d = a.measurement_point, a.diagnostics
        yield {
            "device": p.device.name, "axis": p.axis, "frequency_hz": p.frequency_hz,
            "bench": p.bench, "direction": p.direction, "unit": p.device.unit,
            "method": a.method, "value": a.value, "standard_uncertainty": a.standard_uncertainty,
            "expanded_uncertainty": a.expanded_uncertainty,
            "coverage_factor": a.coverage_factor, "sigma_pt": a.sigma_pt,
            "n": counts.get(p.pk, 0), "excluded": " ".join(d.get("excluded") or ()),
            **{k: d.get(k) for k in ("chi2_obs", "birge_ratio", "consistent", "n_excluded",
                                     "exhaustive")},
        }  # fmt: skip


def _assigned_entry(run: AnalysisRun) -> Entry:
    def write(out: BinaryIO) -> None:
        write_table_to(out, _assigned_rows(run), format="csv", columns=ASSIGNED_COLUMNS)

    return Entry(
        "assigned_values.csv",
        "the assigned value x_pt of each measurement point with u(x_pt), U(x_pt) = k·u(x_pt), "
        "σ_pt, the number of results and the method's diagnostics (excluded: participant "
        "codes left out of the largest consistent subset)",
        write,
    )


def _matrix_rows(run: AnalysisRun, factor: str) -> Iterator[dict[str, Any]]:
    found = CompatibilityMatrix.objects.filter(run=run, factor=factor).order_by("group_key")
    for m in found.iterator(chunk_size=500):
        for i, level_i in enumerate(m.levels):
            for j in range(i + 1, len(m.levels)):
                yield {
                    "factor": factor, "group": m.group_key, "level_i": level_i,
                    "value_i": m.values[i], "expanded_uncertainty_i": m.expanded_uncertainties[i],
                    "level_j": m.levels[j], "value_j": m.values[j],
                    "expanded_uncertainty_j": m.expanded_uncertainties[j], "en": m.en[i][j],
                }  # fmt: skip


def _matrix_entries(run: AnalysisRun) -> list[Entry]:
    factors = sorted(set(run.matrices.values_list("factor", flat=True).order_by()))
    return [_matrix_entry(run, factor) for factor in factors]


def _matrix_entry(run: AnalysisRun, factor: str) -> Entry:
    def write(out: BinaryIO) -> None:
        write_table_to(out, _matrix_rows(run, factor), format="csv", columns=MATRIX_COLUMNS)

    return Entry(
        f"matrices/{factor}.csv",
        f"the compatibility matrices of the factor {factor} in long form: "
        "per group, one row per pair of levels i < j with each level's value and U and "
        "their En",
        write,
    )


def _covariance_entries(audience: Audience) -> list[Entry]:
    """The coordinators' archive of a linked round: the covariance of the linked degrees
    of equivalence (docs/domain.md §14) in long form.  A participant's has none: every
    row is a pair of laboratories."""
    if audience.participant is not None:
        return []
    run = audience.run
    sizes = (KitPointFit.objects.filter(run=run).exclude(reference="")
             .values_list("doe_covariance__codes", flat=True))  # fmt: skip
    n_rows = sum(len(c) * (len(c) + 1) // 2 for c in sizes if c)
    if not n_rows:
        return []

    def write(out: BinaryIO) -> None:
        write_table_to(out, covariance_rows(run), format="csv", columns=COVARIANCE_COLUMNS)

    return [Entry(
        "doe_covariance.csv",
        "the covariance of the participants' degrees of equivalence against the one "
        "reference across the kits, in long form: per linked point, "
        "one row per pair of participant codes a ≤ b with their covariance (a = b: u²(d)) "
        "and correlation r; u²(d_a − d_b) = u²(d_a) + u²(d_b) − 2·covariance",
        _large(write, n_rows),
    )]  # fmt: skip


def _report_entry(report: Report) -> Entry:
    def write(out: BinaryIO) -> None:
        with report.file.open("rb") as pdf:
            shutil.copyfileobj(pdf, out, 2**20)

    what = "the summary report" if report.participant_id is None else "your participant report"
    return Entry(
        f"reports/{download_name(report)}",
        f"{what}, version {report.version} ({report.get_status_display().lower()}), as "
        f"issued: SHA-256 {report.sha256}",
        write,
    )


# --- README.txt -----------------------------------------------------------------------------


def _readme(audience: Audience, entries: list[Entry], n_scores: int) -> Entry:
    run = audience.run
    comparison = run.comparison
    who = (
        f"participant {audience.participant.code} (laboratories appear by code only)"
        if audience.participant is not None
        else "the coordinators (every participant, by code)"
    )
    finished = stamp(run).strftime("%Y-%m-%d %H:%M UTC")
    status = ComparisonStatus(comparison.status).label.lower()
    lines = [
        f"{settings.PT_PROVIDER_NAME}: proficiency test {comparison.code}",
        f"{comparison.title}",
        "",
        f"Archive of analysis run {run.pk}, finished {finished}; the round is {status}.",
        f"For {who}.",
        "Numbers are written at full precision; the reports round them for reading.",
        "",
        "Files:",
        *(f"  {e.name}: {e.what}" for e in entries),
    ]
    if n_scores > XLSX_MAX_ROWS:
        lines.append(f"  (no scores.xlsx: {n_scores} scores are more than a sheet holds)")
    if not any(e.name.startswith("reports/") for e in entries):
        lines.append("  (no report: none of this run is issued to you yet)")
    text = "\r\n".join([*lines, ""]).encode()
    return Entry("README.txt", "this file", lambda out: out.write(text))
