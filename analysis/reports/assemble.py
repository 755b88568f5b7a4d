"""ORM → :class:`ReportData`: the current run of a comparison, read in a few queries.

Participants appear by code only; laboratory names are never read here.
"""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from django.conf import settings
from django.contrib.auth.models import User

import proficiency
from analysis import graph_data, performance
from analysis.history import PointHistory, RoundSummary, lab_histories, round_date, trend_series
from analysis.models import AnalysisRun, AssignedValue, CompatibilityMatrix, Score, method_label
from analysis.reports.consistency import consistency_summary
from analysis.reports.data import (
    PARTICIPANT,
    AssignedRow,
    ConsistencySummary,
    Counts,
    DeviceInfo,
    HistoryPoint,
    HistoryRound,
    KitSection,
    LabSummary,
    MandelRound,
    MatrixData,
    PerformanceLine,
    PointInfo,
    ReportData,
    ReportHistory,
    ResultListing,
    ResultRow,
    RoundStats,
    ScoreRow,
    StabilityRow,
)
from analysis.reports.kits import for_reader, kit_section_of_run
from analysis.reports.rounds import round_stats, stats_of_rows
from analysis.reports.sections import FULL_TABLE_ROWS
from analysis.reports.stability import stability_rows
from common.points import group_text
from common.quantities import point_unit
from common.sizes import counted
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
    "in_assigned_value",
    "correlation_failed",
)


COORDINATOR_ROLE = "coordinator"  # the role of every member of ``Comparison.coordinators``


def person(user: User) -> str:
    return user.get_full_name() or user.get_username()


def coordinator(user: User) -> str:
    """ "Full name, role" of one of the comparison's coordinators (the username only when
    the account has no name)."""
    return f"{person(user)}, {COORDINATOR_ROLE}"


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


@dataclass(frozen=True, eq=False)
class RunContext:
    """What every report of a run shares, read once per run per process (:func:`run_context`):
    points, participants, assigned values, matrices, stability and the round's figures.
    ``rows`` holds every (result, score) row of a small round (≤ ``FULL_TABLE_ROWS``,
    listed whole in each participant report); a large round keeps its figures only and a
    participant report reads its own rows (:func:`participant_rows`)."""

    key: tuple[object, ...]
    points: tuple[PointInfo, ...]
    index: dict[int, int]
    participants: tuple[str, ...]
    reference_code: str | None
    assigned: tuple[AssignedRow, ...]
    use_z: dict[int, bool]
    matrices: tuple[MatrixData, ...]
    stability_rows: tuple[StabilityRow, ...]
    stats: RoundStats
    rows: tuple[tuple[ResultRow, ...], tuple[ScoreRow, ...]] | None
    consistency: ConsistencySummary | None = None
    mandel: MandelRound | None = None
    kits: KitSection | None = None  # a round with kits: every participant's (§13, §14)


_CONTEXTS: OrderedDict[tuple[object, ...], RunContext] = OrderedDict()
_CONTEXTS_KEPT = 2  # a large round's figures hold its values: keep a few runs only
_STREAM_ROWS = 50_000


def run_context(run: AnalysisRun) -> RunContext:
    """The shared data of ``run``, cached per process: a finished run's outputs never
    change.  The key also holds what may change after the run (the participants, the En
    limit): a change builds the context again."""
    comparison = run.comparison
    n_parts = comparison.participants.count()
    key = (run.pk, run.comparison_id, run.finished_at, comparison.en_limit, n_parts)
    found = _CONTEXTS.get(key)
    if found is not None:
        _CONTEXTS.move_to_end(key)
        return found
    context = _build_context(run, key)
    _CONTEXTS[key] = context
    while len(_CONTEXTS) > _CONTEXTS_KEPT:
        _CONTEXTS.popitem(last=False)
    return context


def clear_run_contexts() -> None:
    _CONTEXTS.clear()


def _build_context(run: AnalysisRun, key: tuple[object, ...]) -> RunContext:
    comparison = run.comparison
    points, index = _points(comparison)
    parts = list(comparison.participants.order_by("code").values_list("pk", "code", "is_reference"))
    assigned = _assigned(run, index)
    use_z = _use_z(run)
    stable = stability_rows(comparison, index, assigned)
    n_scores = Score.objects.filter(run=run).count()
    rows = None
    if n_scores <= FULL_TABLE_ROWS:
        rows = _results_and_scores(run, index, use_z)
        stats = stats_of_rows(points, rows[0], rows[1], comparison.en_limit)
    else:
        stats = _stream_stats(run, points, index, parts, n_scores, comparison.en_limit, use_z)
    return RunContext(
        key=key,
        points=tuple(points),
        index=index,
        participants=tuple(code for _, code, _ in parts),
        reference_code=next((code for _, code, ref in parts if ref), None),
        assigned=assigned,
        use_z=use_z,
        matrices=_matrices(run),
        stability_rows=stable,
        stats=stats,
        rows=rows,
        consistency=consistency_summary(run, index),
        mandel=_mandel(run),
        kits=kit_section_of_run(run, index),
    )


def _mandel(run: AnalysisRun) -> MandelRound | None:
    """Mandel's h and k as the web's charts read them (``graph_data.mandel_data``: the
    run's points and every result's mean and repeat standard deviation, two queries)."""
    found = graph_data.mandel_data(run)
    if found.graph is None:
        return None
    return MandelRound(tuple(found.labs), tuple(found.points), tuple(found.devices), found.graph)


def _stream_stats(
    run: AnalysisRun,
    points: list[PointInfo],
    index: dict[int, int],
    parts: list[tuple[int, str, bool]],
    n_scores: int,
    en_limit: float,
    use_z: dict[int, bool],
) -> RoundStats:
    """The round's figures from every score of the run, read in chunks into numpy columns
    (memory: a few arrays of ``n_scores`` numbers, no row objects)."""
    cols = np.empty((8, n_scores))
    rows = (
        Score.objects.filter(run=run)
        .order_by()
        .values_list(
            "result__measurement_point_id",
            "result__submission__participant_id",
            "result__value",
            "result__expanded_uncertainty",
            "en",
            "z",
            "z_prime",
            "result__coverage_factor",
            "correlation_applied",
            "correlation_failed",
        )
    )
    filled = 0
    chunk: list[tuple[float, ...]] = []
    nan = float("nan")
    for pid, part, x, big_u, en, z, z_prime, k, applied, failed in rows.iterator(
        chunk_size=_STREAM_ROWS
    ):
        used = z if use_z.get(pid, False) else z_prime
        chunk.append((pid, part, x, big_u, en, nan if used is None else used, k,
                      float(applied or failed)))  # fmt: skip
        if len(chunk) == _STREAM_ROWS:
            filled = _fill(cols, filled, chunk)
    filled = _fill(cols, filled, chunk)
    cols = cols[:, :filled]  # a score deleted since the count
    point_ids = np.array(sorted(index))
    point = np.array([index[p] for p in point_ids.tolist()])[
        np.searchsorted(point_ids, cols[0].astype(np.int64))
    ]
    part_ids = np.array([pk for pk, _, _ in parts])
    order = np.argsort(part_ids)
    lab = order[np.searchsorted(part_ids[order], cols[1].astype(np.int64))]
    codes = [code for _, code, _ in parts]
    doe = (cols[3] / cols[6], cols[7] > 0)  # U/k and the correction, as graph_data reads them
    return round_stats(
        points, codes, (point, lab, cols[2], cols[3]), (point, lab, cols[4], cols[5]), en_limit,
        doe,
    )  # fmt: skip


def _fill(cols: np.ndarray, filled: int, chunk: list[tuple[float, ...]]) -> int:
    if chunk:
        end = min(filled + len(chunk), cols.shape[1])
        cols[:, filled:end] = np.array(chunk[: end - filled], dtype=float).T
        filled = end
        chunk.clear()
    return filled


_LISTING_FIELDS = (
    "result__measurement_point_id",
    "result__submission__participant_id",
    "result__value",
    "result__expanded_uncertainty",
    "result__coverage_factor",
    "d",
    "en",
    "zeta",
    "z",
    "z_prime",
    "flag",
    "in_assigned_value",
    "correlation_failed",
)


def result_listing(run: AnalysisRun, context: RunContext) -> ResultListing:
    """Every scored result of ``run`` as columns (the summary of a large round), read in
    chunks: no row objects are kept, whatever the number of results."""
    n = Score.objects.filter(run=run).count()
    ids = dict(run.comparison.participants.values_list("pk", "code"))
    labs = sorted(ids.values())
    rank = {code: i for i, code in enumerate(labs)}
    lab_of = {pk: rank[code] for pk, code in ids.items()}
    use_z = context.use_z
    flags: dict[str, int] = {}
    ints = np.empty((5, n), dtype=np.int32)  # point, lab, flag, inside (1/0/-1), failed
    floats = np.empty((7, n))  # value, U, k, d, en, zeta, z
    filled = 0
    chunk: list[tuple[Any, ...]] = []

    def flush() -> None:
        nonlocal filled
        end = min(filled + len(chunk), n)
        take = chunk[: end - filled]
        ints[0, filled:end] = [context.index[r[0]] for r in take]
        ints[1, filled:end] = [lab_of[r[1]] for r in take]
        ints[2, filled:end] = [flags.setdefault(r[10], len(flags)) for r in take]
        ints[3, filled:end] = [-1 if r[11] is None else int(r[11]) for r in take]
        ints[4, filled:end] = [int(r[12]) for r in take]
        floats[:, filled:end] = np.array(
            [
                (*r[2:8], np.nan if (z := r[8] if use_z.get(r[0], False) else r[9]) is None else z)
                for r in take
            ],
            dtype=float,
        ).T
        filled = end
        chunk.clear()

    rows = Score.objects.filter(run=run).order_by().values_list(*_LISTING_FIELDS)
    for row in rows.iterator(chunk_size=_STREAM_ROWS):
        chunk.append(row)
        if len(chunk) == _STREAM_ROWS:
            flush()
    flush()
    ints, floats = ints[:, :filled], floats[:, :filled]  # a score deleted since the count
    names = sorted({p.device for p in context.points})
    device_rank = np.array([names.index(p.device) for p in context.points], dtype=np.int32)
    device = device_rank[ints[0]] if filled else np.empty(0, dtype=np.int32)
    order = np.lexsort((ints[1], ints[0], device))
    ints, floats, device = ints[:, order], floats[:, order], device[order]
    bounds = np.searchsorted(device, np.arange(len(names) + 1))
    devices = tuple(
        (name, int(bounds[i]), int(bounds[i + 1]))
        for i, name in enumerate(names)
        if bounds[i + 1] > bounds[i]
    )
    value, big_u, k, d, en, zeta, z = floats
    return ResultListing(
        labs=tuple(labs),
        flags=tuple(flags),
        devices=devices,
        point=ints[0],
        lab=ints[1],
        value=value,
        expanded_uncertainty=big_u,
        coverage_factor=k,
        d=d,
        en=en,
        zeta=zeta,
        z=z,
        flag=ints[2].astype(np.int8 if len(flags) < 128 else np.int32),
        inside=ints[3].astype(np.int8),
        failed=ints[4].astype(bool),
    )


def _listing_chart_points(listing: ResultListing) -> tuple[int, ...]:
    """:func:`_chart_points` of a summary's listing."""
    if not len(listing):
        return ()
    points = np.unique(listing.point)
    worst = np.zeros(int(points.max()) + 1)
    np.maximum.at(worst, listing.point, np.abs(listing.en))
    ranked = sorted(points.tolist(), key=lambda p: (-float(worst[p]), p))[:CHART_POINTS]
    return tuple(sorted(ranked))


def participant_rows(
    run: AnalysisRun, context: RunContext, participant_ids: Sequence[int]
) -> dict[int, tuple[tuple[ResultRow, ...], tuple[ScoreRow, ...]]]:
    """The scored results of these participants in ``run``, by participant id: one query
    through the (participant → submission → result → score) indexes, whatever the round."""
    rows = (
        Score.objects.filter(run=run, result__submission__participant_id__in=list(participant_ids))
        .order_by()
        .values_list("result__submission__participant_id", *_SCORE_FIELDS)
    )
    found: dict[int, list[tuple[object, ...]]] = {pk: [] for pk in participant_ids}
    for pk, *row in rows:
        found.setdefault(pk, []).append(tuple(row))
    return {pk: _rows(r, context.index, context.use_z) for pk, r in found.items()}


def report_data(
    *,
    run: AnalysisRun,
    participant: Participant | None = None,
    edition: int = 1,
    authorised_by: str = "",
    comments: str = "",
    own: tuple[tuple[ResultRow, ...], tuple[ScoreRow, ...]] | None = None,
    common: ComparisonCommon | None = None,
    context: RunContext | None = None,
    status: str | None = None,
    history: ReportHistory | None = None,
) -> ReportData:
    """The data of the summary report (``participant`` None) or of one participant's.

    Comments, conclusions and the authoriser come from the comparison (entered by the
    coordinator); ``authorised_by`` and ``comments`` override them when given.  The run's
    shared data comes from :func:`run_context`; a batch passes the participant's ``own``
    rows (:func:`participant_rows`), the ``common`` comparison data and the ``context`` it
    read once; ``status`` (preliminary / final), the issuing code's, read under its lock,
    else :func:`report_status` of the comparison.  The summary of a large round lists
    every result from columns (:func:`result_listing`), not from row objects: its
    ``results`` and ``scores`` are empty.  ``history``: the participant's, read for a
    batch by :func:`report_histories` (else read here)."""
    comparison = run.comparison
    context = context or run_context(run)
    common = common or comparison_common(comparison)
    listing = None
    if context.rows is not None:
        results, scores = context.rows
    elif participant is None:
        results, scores = (), ()
        listing = result_listing(run, context)
    else:
        results, scores = own or participant_rows(run, context, [participant.pk])[participant.pk]
    template = protocols.TEMPLATES.get(comparison.protocol)
    assert run.finished_at is not None, "only a finished run is reported"
    return ReportData(
        kind=PARTICIPANT if participant else "summary",
        provider=settings.PT_PROVIDER_NAME,
        provider_address=settings.PT_PROVIDER_ADDRESS,
        provider_accreditation=settings.PT_PROVIDER_ACCREDITATION,
        provider_logo=settings.PT_PROVIDER_LOGO,
        comparison_code=comparison.code,
        comparison_title=comparison.title,
        report_number=report_number(comparison, participant, edition),
        issue_date=run.finished_at,
        status=status or report_status(comparison, authorised_by),
        authorised_by=authorised_by or authoriser(comparison),
        coordinators=common.coordinators,
        software_version=proficiency.__version__,
        protocol_title=template.title if template else "Custom protocol",
        protocol_description=comparison.description or (template.description if template else ""),
        bench_descriptions=tuple(b.description for b in template.benches) if template else (),
        frequencies_hz=tuple(sorted({p.frequency_hz for p in context.points})),
        amplitudes=_amplitudes(context.points),
        devices=common.devices,
        participants=context.participants,
        reference_code=context.reference_code,
        points=context.points,
        results=results,
        assigned=context.assigned,
        scores=scores,
        matrices=context.matrices,
        en_limit=comparison.en_limit,
        sigma_pt_description=_sigma_pt(comparison),
        traceability=_traceability(comparison),
        stability=_stability(context.stability_rows, context.kits),
        stability_rows=context.stability_rows,
        kits=for_reader(context.kits, participant.code if participant else None),
        comments=comments or comparison.report_comments,
        conclusions=comparison.report_conclusions,
        own_code=participant.code if participant else None,
        chart_points=(
            _listing_chart_points(listing)
            if listing is not None
            else _chart_points(scores, participant.code if participant else None)
        ),
        stats=context.stats,
        listing=listing,
        consistency=context.consistency,
        performance=_own_summary(participant.code, context.points, scores) if participant else None,
        performances=() if participant else _summaries(run),
        history=_history(run, participant, history),
        mandel=context.mandel,
    )


def _history(
    run: AnalysisRun, participant: Participant | None, given: ReportHistory | None
) -> ReportHistory | None:
    if participant is None or given is not None:
        return given
    return report_histories(run, [participant])[participant.pk]


def report_histories(
    run: AnalysisRun, participants: Sequence[Participant]
) -> dict[int, ReportHistory]:
    """Participant id → its laboratory's history up to this round, with this run
    (``analysis.history.lab_histories``: a fixed number of queries for all of them); only
    each laboratory's own rounds and codes."""
    found = lab_histories({p.laboratory_id for p in participants},
                          until=round_date(run.comparison), run=run)  # fmt: skip
    return {p.pk: _report_history(*found.get(p.laboratory_id, ([], []))) for p in participants}


def _report_history(rounds: list[RoundSummary], points: list[PointHistory]) -> ReportHistory:
    found = tuple(
        HistoryRound(r.code, r.date, r.own_code, r.en_satisfactory, r.en_scored,
                     r.z_satisfactory, r.z_scored)
        for r in rounds
    )  # fmt: skip
    rows = []
    for p in points:
        c = p.combined
        rows.append(
            HistoryPoint(p.key.label, p.n_rounds, c.rsz, c.rsz_flag, c.rlp, c.rlp_flag)
            if c is not None
            else HistoryPoint(p.key.label, p.n_rounds, None, "", None, "")
        )
    codes, en, z = trend_series(rounds, points)
    trend = tuple((c, tuple(e), tuple(zz)) for c, e, zz in zip(codes, en, z, strict=True))
    return ReportHistory(found, tuple(rows), trend)


def _counts(t: performance.Tally) -> Counts:
    return Counts(t.satisfactory, t.warning, t.action, t.not_scored)


def _line(row: performance.Row) -> PerformanceLine:
    return PerformanceLine(row.level, _counts(row.en), _counts(row.z))


def _lab_summary(
    found: performance.LabPerformance,
    worst_en: tuple[ScoreRow, ...] = (),
    worst_z: tuple[ScoreRow, ...] = (),
) -> LabSummary:
    breakdowns = tuple((heading, tuple(_line(r) for r in rows))
                       for _, heading, rows in found.breakdowns)  # fmt: skip
    return LabSummary(found.code, _line(found.total), breakdowns, found.max_abs_en,
                      found.max_abs_z, worst_en, worst_z)  # fmt: skip


def _summaries(run: AnalysisRun) -> tuple[LabSummary, ...]:
    """Every participant's summary, as the coordinator's performance page shows it."""
    return tuple(_lab_summary(found) for found in performance.performance(run))


def _own_summary(
    code: str, points: Sequence[PointInfo], scores: Sequence[ScoreRow]
) -> LabSummary | None:
    """The participant's summary from its own score rows (no query), counted by
    ``analysis.performance``'s rule; its largest |En| and |z| first, as
    ``analysis.performance.lab_performance`` lists them (None: it has no score)."""
    own = [s for s in scores if s.lab == code]
    if not own:
        return None
    groups = [(code, (p := points[s.point]).device, p.bench, p.axis, s.flag, s.z_flag, 1)
              for s in own]  # fmt: skip
    found = performance.summaries_of(groups)[code]
    found.max_abs_en = max(abs(s.en) for s in own)
    found.max_abs_z = max((abs(s.z) for s in own if s.z is not None), default=None)
    by_en = sorted(own, key=lambda s: (-abs(s.en), s.point))
    with_z = [s for s in own if s.z_flag and s.z is not None]
    by_z = sorted(with_z, key=lambda s: (-abs(s.z or 0.0), s.point))
    worst = performance.WORST
    return _lab_summary(found, tuple(by_en[:worst]), tuple(by_z[:worst]))


@dataclass(frozen=True)
class ComparisonCommon:
    """The comparison's coordinators and devices: read once per batch of reports."""

    coordinators: tuple[str, ...]
    devices: tuple[DeviceInfo, ...]


def comparison_common(comparison: Comparison) -> ComparisonCommon:
    coordinators = tuple(coordinator(u) for u in comparison.coordinators.order_by("username"))
    return ComparisonCommon(coordinators, _devices(comparison))


def _points(comparison: Comparison) -> tuple[list[PointInfo], dict[int, int]]:
    rows = comparison.measurement_points.select_related("device").order_by(
        "device__name",
        "bench",
        "direction",
        "axis",
        "frequency_hz",
        "quantity",
        "amplitude_m_s2",
        "pk",
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
                point_unit(p.quantity, p.device.unit),
                p.quantity,
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


def _use_z(run: AnalysisRun) -> dict[int, bool]:
    """Per point id: z (u(x_pt) ≤ 0.3·σ_pt) or z′ is printed."""
    rows = run.assigned_values.values_list(
        "measurement_point_id", "sigma_pt", "standard_uncertainty"
    )
    return {pid: sigma is not None and u <= 0.3 * sigma for pid, sigma, u in rows}


def _results_and_scores(
    run: AnalysisRun, index: dict[int, int], use_z: dict[int, bool]
) -> tuple[tuple[ResultRow, ...], tuple[ScoreRow, ...]]:
    """The scored results of the run with their scores, in point then lab order."""
    return _rows(Score.objects.filter(run=run).order_by().values_list(*_SCORE_FIELDS), index, use_z)


def _rows(
    rows: Iterable[Sequence[Any]], index: dict[int, int], use_z: dict[int, bool]
) -> tuple[tuple[ResultRow, ...], tuple[ScoreRow, ...]]:
    results, scores = [], []
    for pid, lab, x, big_u, k, d, dp, en, zeta, z, zp, flag, zflag, corr, inside, failed in rows:
        i = index[pid]
        results.append(ResultRow(i, lab, x, big_u, k))
        z_ok = use_z.get(pid, False)
        scores.append(
            ScoreRow(
                i, lab, d, dp, en, zeta, z if z_ok else zp, "z" if z_ok else "z′", flag, zflag,
                corr, inside, failed,
            )
        )  # fmt: skip
    results.sort(key=lambda r: (r.point, r.lab))
    scores.sort(key=lambda s: (s.point, s.lab))
    return tuple(results), tuple(scores)


def _assigned(run: AnalysisRun, index: dict[int, int]) -> tuple[AssignedRow, ...]:
    rows = AssignedValue.objects.filter(run=run).values_list(
        "measurement_point_id", "value", "standard_uncertainty", "method", "sigma_pt",
        "coverage_factor", "diagnostics",
    )  # fmt: skip
    out = [
        AssignedRow(
            index[p],
            v,
            u,
            method_label(m),
            s,
            coverage_factor=k,
            excluded=None if (codes := d.get("excluded")) is None else tuple(codes),
            exhaustive=d.get("exhaustive", True) is not False,
        )
        for p, v, u, m, s, k, d in rows
    ]
    return tuple(sorted(out, key=lambda a: a.point))


def _matrices(run: AnalysisRun) -> tuple[MatrixData, ...]:
    found = CompatibilityMatrix.objects.filter(run=run).order_by("factor", "group_key")
    return tuple(
        MatrixData(
            m.factor,
            group_text(m.group) or "all",
            tuple(str(level) for level in m.levels),
            tuple(m.values),
            tuple(m.expanded_uncertainties),
            tuple(tuple(row) for row in m.en),
            m.incompatible_pairs,
        )
        for m in found
    )


def _amplitudes(points: Sequence[PointInfo]) -> tuple[str, ...]:
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


def _stability(rows: tuple[StabilityRow, ...], kits: KitSection | None = None) -> str:
    homogeneity = (
        "Homogeneity: each artefact is one item circulated to every participant, so there is "
        "no between-item inhomogeneity (u_hom = 0). "
    )
    if not rows and kits is not None and kits.drift:
        n_kits = len({d.kit for d in kits.drift})
        if n_kits > 1:
            homogeneity = (
                f"Homogeneity: the artefacts travelled in {n_kits} kits, each circulated to "
                "the participants of its own loop; how the kits' items differ is measured "
                "(section Linking and drift), not assumed. "
            )
        drifting = sum(d.model == "linear" for d in kits.drift)
        series = counted(len(kits.drift), "series", "series")
        return homogeneity + (
            f"Stability: the pilot measured each kit repeatedly over its circulation "
            f"({series} of one kit at one point, {drifting} drifting); section Linking and "
            "drift gives the drift found and what the scores do with it."
        )
    if not rows:
        return homogeneity + (
            "Stability: no measurements of the pilot before and after circulation were "
            "recorded for this round; u_stab is taken as zero."
        )
    bad = sum(not r.stable for r in rows)
    return homogeneity + (
        f"Stability: the pilot measured the artefacts before and after circulation at "
        f"{counted(len(rows), 'measurement point')}; {len(rows) - bad} "
        f"{'is' if len(rows) - bad == 1 else 'are'} stable (|Δ| ≤ 0.3·σ_pt or En ≤ 1) and "
        f"{bad} {'is' if bad == 1 else 'are'} not. The table below gives u_stab = |Δ|/√3 at "
        "each unstable point; the scores of this round use u(x_pt) = u_char and do not "
        "include it, so a score at an unstable point should be read with the drift in mind."
    )


def _chart_points(scores: tuple[ScoreRow, ...], own: str | None) -> tuple[int, ...]:
    """The points with the largest |En| (the participant's own when it is its report)."""
    worst: dict[int, float] = {}
    for s in scores:
        if own is None or s.lab == own:
            worst[s.point] = max(worst.get(s.point, 0.0), abs(s.en))
    ranked = sorted(worst, key=lambda p: (-worst[p], p))[:CHART_POINTS]
    return tuple(sorted(ranked))
