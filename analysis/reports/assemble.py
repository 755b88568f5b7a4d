"""ORM → :class:`ReportData`: the current run of a comparison, read in a few queries.

Participants appear by code only; laboratory names are never read here.
"""

from __future__ import annotations

from django.conf import settings
from django.contrib.auth.models import AbstractBaseUser

import proficiency
from analysis.models import AnalysisRun, AssignedValue, CompatibilityMatrix, Score
from analysis.reports.data import (
    PARTICIPANT,
    AssignedRow,
    DeviceInfo,
    MatrixData,
    PointInfo,
    ReportData,
    ResultRow,
    ScoreRow,
    StabilityRow,
)
from analysis.reports.stability import stability_rows
from labs.models import Participant
from proficiency import protocols
from proficiency.models import (
    AssignedValueMethod,
    Comparison,
    ComparisonStatus,
    SigmaPtMode,
)

CHART_POINTS = 4
_SCORE_FIELDS = (
    "result__measurement_point_id",
    "result__submission__participant__code",
    "result__value",
    "result__expanded_uncertainty",
    "result__coverage_factor",
    "d",
    "d_percent",
    "en",
    "zeta",
    "z",
    "z_prime",
    "flag",
    "z_flag",
    "correlation_applied",
)


def person(user: AbstractBaseUser) -> str:
    return user.get_full_name() or user.get_username()  # type: ignore[attr-defined]


def authoriser(comparison: Comparison) -> str:
    """ "Name, role" of the person authorising the reports; empty when none is entered."""
    name, role = comparison.authorised_by_name.strip(), comparison.authorised_by_role.strip()
    return f"{name}, {role}" if name and role else name


def report_status(comparison: Comparison, authorised_by: str = "") -> str:
    """Final only once published *and* authorised (ISO/IEC 17043 reports are authorised);
    everything else, e.g. a report issued for review before publication, is preliminary."""
    published = comparison.status == ComparisonStatus.PUBLISHED
    return "final" if published and (authorised_by or authoriser(comparison)) else "preliminary"


def report_number(comparison: Comparison, participant: Participant | None, edition: int) -> str:
    """``<code>-S-v<n>`` for the summary, ``<code>-<participant code>-v<n>`` otherwise."""
    return f"{comparison.code}-{participant.code if participant else 'S'}-v{edition}"


def report_data(
    *,
    run: AnalysisRun,
    participant: Participant | None = None,
    edition: int = 1,
    authorised_by: str = "",
    comments: str = "",
) -> ReportData:
    """The data of the summary report (``participant`` None) or of one participant's.

    Comments, conclusions and the authoriser come from the comparison (entered by the
    coordinator); ``authorised_by`` and ``comments`` override them when given."""
    comparison = run.comparison
    points, index = _points(comparison)
    coordinators = tuple(person(u) for u in comparison.coordinators.order_by("username"))
    parts = list(comparison.participants.order_by("code").values_list("code", "is_reference"))
    results, scores = _results_and_scores(run, index)
    assigned = _assigned(run, index)
    template = protocols.TEMPLATES.get(comparison.protocol)
    stable = stability_rows(comparison, index, assigned)
    assert run.finished_at is not None, "only a finished run is reported"
    return ReportData(
        kind=PARTICIPANT if participant else "summary",
        provider=settings.PT_PROVIDER_NAME,
        comparison_code=comparison.code,
        comparison_title=comparison.title,
        report_number=report_number(comparison, participant, edition),
        issue_date=run.finished_at,
        status=report_status(comparison, authorised_by),
        authorised_by=authorised_by or authoriser(comparison),
        coordinators=coordinators,
        software_version=proficiency.__version__,
        protocol_title=template.title if template else "Custom protocol",
        protocol_description=comparison.description or (template.description if template else ""),
        bench_descriptions=tuple(b.description for b in template.benches) if template else (),
        frequencies_hz=tuple(sorted({p.frequency_hz for p in points})),
        amplitudes=_amplitudes(points),
        devices=_devices(comparison),
        participants=tuple(code for code, _ in parts),
        reference_code=next((code for code, ref in parts if ref), None),
        points=tuple(points),
        results=results,
        assigned=assigned,
        scores=scores,
        matrices=_matrices(run),
        en_limit=comparison.en_limit,
        sigma_pt_description=_sigma_pt(comparison),
        traceability=_traceability(comparison),
        stability=_stability(stable),
        stability_rows=stable,
        comments=comments or comparison.report_comments,
        conclusions=comparison.report_conclusions,
        own_code=participant.code if participant else None,
        chart_points=_chart_points(scores, participant.code if participant else None),
    )


def _points(comparison: Comparison) -> tuple[list[PointInfo], dict[int, int]]:
    rows = comparison.measurement_points.select_related("device").order_by(
        "device__name", "bench", "direction", "axis", "frequency_hz", "amplitude_m_s2", "pk"
    )
    points, index = [], {}
    for i, p in enumerate(rows):
        index[p.pk] = i
        points.append(
            PointInfo(
                i,
                p.device.name,
                p.axis,
                p.frequency_hz,
                p.bench,
                p.direction,
                p.amplitude_m_s2,
                p.device.unit,
            )
        )
    return points, index


def _devices(comparison: Comparison) -> tuple[DeviceInfo, ...]:
    return tuple(
        DeviceInfo(
            d.name,
            d.model,
            d.serial,
            d.unit,
            d.nominal_sensitivity,
            d.tolerance,
            d.tolerance_relative,
            d.get_tolerance_distribution_display(),
        )
        for d in comparison.devices.order_by("name")
    )


def _results_and_scores(
    run: AnalysisRun, index: dict[int, int]
) -> tuple[tuple[ResultRow, ...], tuple[ScoreRow, ...]]:
    """The scored results of the run with their scores, in point then lab order."""
    sigma = dict(run.assigned_values.values_list("measurement_point_id", "sigma_pt"))
    u_pt = dict(run.assigned_values.values_list("measurement_point_id", "standard_uncertainty"))
    rows = Score.objects.filter(run=run).values_list(*_SCORE_FIELDS)
    results, scores = [], []
    for pid, lab, x, big_u, k, d, dp, en, zeta, z, zp, flag, zflag, corr in rows:
        i = index[pid]
        results.append(ResultRow(i, lab, x, big_u, k))
        sigma_pt = sigma.get(pid)
        use_z = sigma_pt is not None and u_pt[pid] <= 0.3 * sigma_pt
        scores.append(
            ScoreRow(
                i,
                lab,
                d,
                dp,
                en,
                zeta,
                z if use_z else zp,
                "z" if use_z else "z′",
                flag,
                zflag,
                corr,
            )
        )
    results.sort(key=lambda r: (r.point, r.lab))
    scores.sort(key=lambda s: (s.point, s.lab))
    return tuple(results), tuple(scores)


def method_label(method: str) -> str:
    try:
        return str(AssignedValueMethod(method).label)
    except ValueError:
        return method.replace("_", " ")


def _assigned(run: AnalysisRun, index: dict[int, int]) -> tuple[AssignedRow, ...]:
    rows = AssignedValue.objects.filter(run=run).values_list(
        "measurement_point_id", "value", "standard_uncertainty", "method", "sigma_pt"
    )
    out = [AssignedRow(index[p], v, u, method_label(m), s) for p, v, u, m, s in rows]
    return tuple(sorted(out, key=lambda a: a.point))


def _matrices(run: AnalysisRun) -> tuple[MatrixData, ...]:
    found = CompatibilityMatrix.objects.filter(run=run).order_by("factor", "group_key")
    return tuple(
        MatrixData(
            m.factor,
            ", ".join(f"{k} {v}" for k, v in m.group.items()) or "all",
            tuple(str(level) for level in m.levels),
            tuple(m.values),
            tuple(m.expanded_uncertainties),
            tuple(tuple(row) for row in m.en),
            m.incompatible_pairs,
        )
        for m in found
    )


def _amplitudes(points: list[PointInfo]) -> tuple[str, ...]:
    seen = {
        (p.bench, p.direction, p.frequency_hz): p.amplitude_m_s2
        for p in points
        if p.amplitude_m_s2 is not None
    }
    return tuple(f"{b} {d} {f:g} Hz: {a:.3g} m/s²" for (b, d, f), a in sorted(seen.items()))


def _sigma_pt(comparison: Comparison) -> str:
    mode = comparison.sigma_pt_mode
    if mode == SigmaPtMode.NONE:
        return "not used; the criterion is En (primary) and ζ"
    value = f" = {comparison.sigma_pt_value:g}" if comparison.sigma_pt_value else ""
    pct = " %" if mode == SigmaPtMode.RELATIVE and value else ""
    return f"{SigmaPtMode(mode).label}{value}{pct}; z is used when u(x_pt) ≤ 0.3·σ_pt, else z′"


def _traceability(comparison: Comparison) -> str:
    method = comparison.assigned_value_method
    if method == AssignedValueMethod.REFERENCE:
        return (
            "the assigned values are the results of the reference (pilot) laboratory, "
            "traceable to the SI through its calibrated reference transducer "
            "(ISO 16063-21 comparison method); u(x_pt) is its stated standard uncertainty."
        )
    if method == AssignedValueMethod.NOMINAL:
        return (
            "the assigned values are the manufacturer's nominal sensitivities; u(x_pt) "
            "follows from the tolerance and its distribution. They are not an SI-traceable "
            "measurement."
        )
    return (
        "the assigned values are consensus values of the participants' results "
        f"({method_label(method)}); their traceability is that of the participants' own "
        "calibrations, and u(x_pt) is the uncertainty of the consensus."
    )


def _stability(rows: tuple[StabilityRow, ...]) -> str:
    homogeneity = (
        "Homogeneity: each artefact is one item circulated to every participant, so there is "
        "no between-item inhomogeneity (u_hom = 0). "
    )
    if not rows:
        return homogeneity + (
            "Stability: no measurements of the pilot before and after circulation were "
            "recorded for this round; u_stab is taken as zero."
        )
    bad = sum(not r.stable for r in rows)
    return homogeneity + (
        f"Stability: the pilot measured the artefacts before and after circulation at "
        f"{len(rows)} measurement point(s); {len(rows) - bad} are stable (|Δ| ≤ 0.3·σ_pt or "
        f"En ≤ 1, domain.md §7) and {bad} are not. At an unstable point the drift adds "
        "u_stab = |Δ|/√3, listed below, to u(x_pt) = √(u_char² + u_hom² + u_stab²)."
    )


def _chart_points(scores: tuple[ScoreRow, ...], own: str | None) -> tuple[int, ...]:
    """The points with the largest |En| (the participant's own when it is its report)."""
    worst: dict[int, float] = {}
    for s in scores:
        if own is None or s.lab == own:
            worst[s.point] = max(worst.get(s.point, 0.0), abs(s.en))
    ranked = sorted(worst, key=lambda p: (-worst[p], p))[:CHART_POINTS]
    return tuple(sorted(ranked))
