"""Read side of analysis runs: the round's results as arrays, the current run."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any, cast

import numpy as np
from django.db.models import (
    BooleanField,
    Case,
    Count,
    F,
    FloatField,
    OuterRef,
    QuerySet,
    Subquery,
    Value,
    When,
)
from django.db.models.functions import Abs, Coalesce

from analysis.bulk import read_columns
from analysis.core.assigned import EXACT_MAX  # noqa: F401  (re-exported for the results page)
from analysis.core.compatibility import compatibility_matrices
from analysis.core.groups import Groups
from analysis.core.scores import NEGLIGIBLE_FRACTION
from analysis.models import AnalysisRun, AssignedValue, CompatibilityMatrix, Score
from analysis.pipeline import AssignedSpec, ResultTable
from common.errors import ValidationFailed
from labs.models import Result, Submission
from labs.selectors import current_submissions, has_other_kinds
from proficiency.models import AssignedValueMethod, Comparison, MeasurementPoint

_RESULT_COLUMNS = (
    ("id", "i8"),
    ("measurement_point_id", "i8"),
    ("submission_id", "i8"),
    ("value", "f8"),
    ("expanded_uncertainty", "f8"),
    ("coverage_factor", "f8"),
    ("repeat_sd_or_0", "f8"),  # read NOT NULL (``read_columns``): 0 where none is given
    ("n_repeats_or_0", "i8"),
)
#: repeat_sd > 0 and n_repeats >= 2 where given (a CHECK constraint): 0 stands for none.
_REPEATS = {
    "repeat_sd_or_0": Coalesce("repeat_sd", Value(0.0)),
    "n_repeats_or_0": Coalesce("n_repeats", Value(0)),
}


@dataclass(frozen=True)
class LoadedRound:
    """Accepted results of a comparison as columns, grouped by measurement point."""

    table: ResultTable
    result_id: np.ndarray
    is_reference: np.ndarray
    groups: Groups
    point_ids: np.ndarray  # one per group
    points: list[MeasurementPoint]  # one per group
    submission_ids: np.ndarray  # the current accepted submissions read, ascending


def accepted_results(comparison: Comparison) -> QuerySet[Result]:
    """The current accepted results of a comparison (latest accepted version per lab)."""
    return Result.objects.filter(
        submission__in=current_submissions(comparison, (Submission.Status.ACCEPTED,))
    )


def accepted_submissions(comparison: Comparison) -> tuple[np.ndarray, np.ndarray]:
    """Ids of the current accepted submissions (ascending) and their participants' ids."""
    rows = (
        current_submissions(comparison, (Submission.Status.ACCEPTED,))
        .order_by()
        .values_list("id", "participant_id")
    )
    ids, participants = read_columns(rows, ("i8", "i8"))
    order = np.argsort(ids)
    return ids[order], participants[order]


def _results_of(submission_ids: np.ndarray) -> QuerySet[Result]:
    """The results of these submissions, by a list of ids: the same rows as
    ``accepted_results`` but without the subquery, whose row count PostgreSQL estimates as
    one, so it walked every result of each submission to keep a chunk's points (~1,000,000
    rows visited per 100,000 loaded); with the ids the point range uses its index."""
    return Result.objects.filter(submission_id__in=submission_ids.tolist())


def point_result_counts(comparison: Comparison) -> tuple[np.ndarray, np.ndarray]:
    """Ids of the points with accepted results (ascending) and their result counts."""
    rows = (
        _results_of(accepted_submissions(comparison)[0])
        .values_list("measurement_point_id")
        .annotate(n=Count("id"))
        .order_by()  # sorted here: PostgreSQL then hashes the groups instead of sorting 10⁶ rows
    )
    ids, counts = read_columns(rows, ("i8", "i8"))
    order = np.argsort(ids)
    return ids[order], counts[order]


def load_round(
    comparison: Comparison,
    first_point_id: int | None = None,
    last_point_id: int | None = None,
    *,
    only_points: list[int] | None = None,
    submissions: tuple[np.ndarray, np.ndarray] | None = None,
) -> LoadedRound:
    """Accepted results of all points, of the point ids ``first..last`` or of the listed
    ``only_points``, read straight into numpy arrays (two queries: the current accepted
    submissions, then their results; no model instances).  ``submissions`` (ids ascending,
    participant ids) replaces the current accepted ones, e.g. by those a run scored.

    Rows are ordered by point, then participant code: every path (one task, or chunks)
    feeds the core the same rows in the same order, so sums round the same way.
    """
    sub_ids, sub_participants = submissions or accepted_submissions(comparison)
    qs = _results_of(sub_ids)
    if first_point_id is not None:
        qs = qs.filter(
            measurement_point_id__gte=first_point_id, measurement_point_id__lte=last_point_id
        )
    if only_points is not None:
        qs = qs.filter(measurement_point_id__in=only_points)
    names, kinds = zip(*_RESULT_COLUMNS, strict=True)
    rows = qs.order_by().annotate(**_REPEATS).values_list(*names)
    rid, pid, sub, value, big_u, k, sd, n_rep = read_columns(rows, kinds)
    part = sub_participants[np.searchsorted(sub_ids, sub)]
    codes, is_ref, sorted_ids, rank_of_sorted = _participants(comparison)
    lab = rank_of_sorted[np.searchsorted(sorted_ids, part)]
    order = np.lexsort((lab, pid))
    rid, pid, lab, value, big_u, k, sd, n_rep = (
        a[order] for a in (rid, pid, lab, value, big_u, k, sd, n_rep)
    )
    point_ids, index = np.unique(pid, return_inverse=True)
    by_id = MeasurementPoint.objects.select_related("device").in_bulk(point_ids.tolist())
    points = [by_id[int(i)] for i in point_ids]
    index = index.reshape(-1)
    return LoadedRound(
        table=_table(points, index, codes[lab], value, big_u, k, (sd, n_rep)),
        result_id=rid,
        is_reference=is_ref[lab],
        groups=Groups.from_index(index, point_ids.size),
        point_ids=point_ids,
        points=points,
        submission_ids=sub_ids,
    )


def _participants(comparison: Comparison) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Participants ranked by code: codes and reference flags by rank, plus the ids sorted
    ascending with the rank of each (for ``searchsorted`` lookups of result rows)."""
    rows = sorted(comparison.participants.values_list("code", "is_reference", "id"))
    codes = np.array([r[0] for r in rows], dtype=np.str_)
    is_ref = np.array([r[1] for r in rows], dtype=bool)
    ids = np.array([r[2] for r in rows], dtype=np.int64)
    rank_of_sorted = np.argsort(ids)
    return codes, is_ref, ids[rank_of_sorted], rank_of_sorted


def _table(
    points: list[MeasurementPoint], index: np.ndarray, lab: np.ndarray, value: np.ndarray,
    big_u: np.ndarray, k: np.ndarray, repeats: tuple[np.ndarray, np.ndarray],
) -> ResultTable:  # fmt: skip
    def per_point(get: Any, dtype: Any = np.str_) -> np.ndarray:
        return np.array([get(p) for p in points], dtype=dtype)[index]

    return ResultTable(
        lab=lab,
        device=per_point(lambda p: p.device.name),
        axis=per_point(lambda p: p.axis),
        frequency_hz=per_point(lambda p: p.frequency_hz, np.float64),
        bench=per_point(lambda p: p.bench),
        direction=per_point(lambda p: p.direction),
        quantity=per_point(lambda p: p.quantity),
        value=value,
        expanded_uncertainty=big_u,
        coverage_factor=k,
        repeat_sd=np.where(repeats[1] >= 2, repeats[0], np.nan),
        n_repeats=repeats[1],
    )


_METHOD_SPEC = {
    AssignedValueMethod.WEIGHTED_MEAN: "weighted_mean",
    AssignedValueMethod.ALGORITHM_A: "algorithm_a",
    AssignedValueMethod.MEDIAN: "median",
    AssignedValueMethod.MEDIAN_NIQR: "median_niqr",
    AssignedValueMethod.Q_HAMPEL: "q_hampel",
    AssignedValueMethod.DERSIMONIAN_LAIRD: "dersimonian_laird",
}


def point_spec(
    comparison: Comparison, point: MeasurementPoint, reference_code: str
) -> AssignedSpec:
    """The assigned-value method of one point: its override, else the comparison's."""
    method = point.assigned_value_method or comparison.assigned_value_method
    if method == AssignedValueMethod.REFERENCE:
        return AssignedSpec("reference", reference_lab=reference_code)
    if method == AssignedValueMethod.NOMINAL:
        d = point.device
        return AssignedSpec(
            "nominal",
            nominal=d.nominal_sensitivity,
            tolerance=d.tolerance,
            tolerance_relative=d.tolerance_relative,
            distribution=d.tolerance_distribution,
        )
    return AssignedSpec(_METHOD_SPEC[AssignedValueMethod(method)])


def current_run(comparison: Comparison) -> AnalysisRun | None:
    """The latest succeeded run: its results are the ones shown (older runs stay browsable)."""
    return (
        comparison.analysis_runs.filter(status=AnalysisRun.Status.SUCCEEDED)
        .order_by("-finished_at", "-pk")
        .first()
    )


def run_consistency(run: AnalysisRun, *, signals_only: bool) -> QuerySet[AssignedValue]:
    """The run's points with their consistency tests, in point order; ``signals_only``:
    those where a test finds a straggler or an outlier."""
    order = [f"measurement_point__{f}" for f in cast(list[str], MeasurementPoint._meta.ordering)]
    found = AssignedValue.objects.filter(run=run).select_related("measurement_point__device")
    if signals_only:
        found = found.filter(consistency__signals=True)
    return found.defer("diagnostics").order_by(*order)


SCORE_FILTERS = {
    "device": "result__measurement_point__device__name",
    "axis": "result__measurement_point__axis",
    "frequency_hz": "result__measurement_point__frequency_hz",
    "bench": "result__measurement_point__bench",
    "direction": "result__measurement_point__direction",
    "quantity": "result__measurement_point__quantity",
    "lab": "result__submission__participant__code",
    "flag": "flag",
    "z_flag": "z_flag",
}
POINT_ORDER_OF_SCORES = (
    "result__measurement_point__device__name",
    "result__measurement_point__bench",
    "result__measurement_point__direction",
    "result__measurement_point__quantity",
    "result__measurement_point__axis",
    "result__measurement_point__frequency_hz",
    "result__submission__participant__code",
)
#: the orders the scores page offers besides the points' (largest first)
SCORE_ORDERS = {"en": "abs_en", "z": "abs_z_used"}


def run_scores(run: AnalysisRun, filters: dict[str, str], order: str = "") -> QuerySet[Score]:
    """Scores of one run with their result and point, filtered by point keys, lab code or
    flag, in the points' order or (``order``: ``en``, ``z``) by |En| or by |z| of the z
    that counts, largest first.

    Each score carries ``z_is_prime`` and ``z_used``: ISO 13528 uses z′ instead of z where
    u(x_pt) > 0.3 σ_pt (9.5; docs/domain.md, the scores), the rule of
    ``analysis.core.scores``, read here from the point's assigned value in the run."""
    qs = with_z_used(
        Score.objects.filter(run=run).select_related(
            "result__measurement_point__device", "result__submission__participant"
        )
    )
    lookups = {SCORE_FILTERS[k]: v for k, v in filters.items() if k in SCORE_FILTERS and v}
    qs = qs.filter(**lookups)
    if order in SCORE_ORDERS:
        qs = qs.annotate(abs_en=Abs("en"), abs_z_used=Abs("z_used"))
        key = F(SCORE_ORDERS[order]).desc(nulls_last=True)
        return qs.order_by(key, *POINT_ORDER_OF_SCORES)
    return qs.order_by(*POINT_ORDER_OF_SCORES)


def with_z_used(scores: QuerySet[Score]) -> QuerySet[Score]:
    """``scores`` (of any runs) annotated with ``z_is_prime`` and ``z_used``, the z that
    counts: z′ where u(x_pt) > 0.3 σ_pt at the point in the score's own run, else z
    (ISO 13528:2022 9.2.1, 9.5; docs/domain.md §4)."""
    assigned = AssignedValue.objects.filter(
        run=OuterRef("run"), measurement_point=OuterRef("result__measurement_point")
    )
    return (
        scores.annotate(
            u_pt=Subquery(assigned.values("standard_uncertainty")[:1], output_field=FloatField()),
            sigma=Subquery(assigned.values("sigma_pt")[:1], output_field=FloatField()),
        )
        .annotate(
            z_is_prime=Case(
                When(sigma__isnull=False, u_pt__gt=F("sigma") * NEGLIGIBLE_FRACTION, then=True),
                default=Value(False),
                output_field=BooleanField(),
            ),
        )
        .annotate(
            z_used=Case(When(z_is_prime=True, then=F("z_prime")), default=F("z")),
        )
    )


def z_used_name(score: Score) -> str | None:
    """``z`` or ``z_prime``: the score a ``run_scores`` row's ``z_flag`` is of (None: the
    point has no σ_pt, so no z at all)."""
    if score.z is None:
        return None
    return "z_prime" if getattr(score, "z_is_prime", False) else "z"


#: the scores download's columns (CSV, XLSX and the round's archive)
SCORE_COLUMNS = [
    "lab", "device", "axis", "frequency_hz", "bench", "direction", "sensitivity", "unit",
    "expanded_uncertainty", "coverage_factor", "assigned_value", "assigned_standard_uncertainty",
    "assigned_expanded_uncertainty", "d", "d_percent", "en", "zeta", "z", "z_prime", "flag",
    "z_flag", "in_assigned_value", "correlation_applied", "correlation_failed", "z_used",
]  # fmt: skip


def score_columns_of(comparison: Comparison) -> list[str]:
    """:data:`SCORE_COLUMNS`, with ``quantity`` after ``direction`` where the comparison has
    a point of another kind than the magnitude (a download of magnitudes reads as before)."""
    if not has_other_kinds(comparison):
        return SCORE_COLUMNS
    at = SCORE_COLUMNS.index("direction") + 1
    return [*SCORE_COLUMNS[:at], "quantity", *SCORE_COLUMNS[at:]]


def score_records(run: AnalysisRun, filters: dict[str, str]) -> Iterator[dict[str, Any]]:
    """The scores download's rows (:data:`SCORE_COLUMNS`), one per score of ``run_scores``,
    with the point's assigned value: read 5,000 scores at a time, never all at once."""
    assigned = dict(
        (pid, (v, u, k * u)) for pid, v, u, k in run.assigned_values.values_list(
            "measurement_point_id", "value", "standard_uncertainty", "coverage_factor")
    )  # fmt: skip
    for s in run_scores(run, filters).iterator(chunk_size=5000):
        r, p = s.result, s.result.measurement_point
        x_pt, u_pt, big_u_pt = assigned.get(p.pk, (None, None, None))
        yield {
            "lab": r.submission.participant.code, "device": p.device.name, "axis": p.axis,
            "frequency_hz": p.frequency_hz, "bench": p.bench, "direction": p.direction,
            "quantity": p.quantity, "sensitivity": r.value, "unit": r.unit,
            "expanded_uncertainty": r.expanded_uncertainty,
            "coverage_factor": r.coverage_factor, "assigned_value": x_pt,
            "assigned_standard_uncertainty": u_pt, "assigned_expanded_uncertainty": big_u_pt,
            "d": s.d, "d_percent": s.d_percent, "en": s.en, "zeta": s.zeta, "z": s.z,
            "z_prime": s.z_prime, "flag": s.flag, "z_flag": s.z_flag,
            "in_assigned_value": s.in_assigned_value, "correlation_applied": s.correlation_applied,
            "correlation_failed": s.correlation_failed, "z_used": z_used_name(s) or "",
        }  # fmt: skip


def approximate_subsets(run: AnalysisRun) -> int:
    """Points of ``run`` whose largest consistent subset is the sequential approximation
    (too many results for the exact search: ``analysis.core.assigned.EXACT_MAX``)."""
    return run.assigned_values.filter(diagnostics__exhaustive=False).count()


def run_matrices(
    run: AnalysisRun, factor: str, filters: dict[str, str]
) -> list[CompatibilityMatrix]:
    """Stored matrices of ``factor`` whose group matches every given key (device=..., ...)."""
    found = CompatibilityMatrix.objects.filter(run=run, factor=factor).order_by("group_key")
    wanted = {k: v for k, v in filters.items() if v}
    return [m for m in found if all(str(m.group.get(k)) == v for k, v in wanted.items()
                                    if k in m.group)]  # fmt: skip


MAX_LAB_MATRIX_POINTS = 50


def lab_matrices(run: AnalysisRun, filters: dict[str, str]) -> list[Any]:
    """The lab x lab En matrices of the selected points, computed on request from the
    results ``run`` scored (never stored for a whole round: they grow with labs squared).
    A published run's matrix stays what was published when results change later."""
    comparison = run.comparison
    exact = {k: v for k, v in filters.items() if v and k in SCORE_FILTERS}
    exact.pop("lab", None)
    frequency = exact.pop("frequency_hz", None)
    scored = Score.objects.filter(run=run, **{SCORE_FILTERS[k]: v for k, v in exact.items()})
    if frequency:  # within rounding of the number as typed
        f = float(frequency)
        scored = scored.filter(
            result__measurement_point__frequency_hz__range=(f - abs(f) * 1e-9, f + abs(f) * 1e-9)
        )
    scored = scored.order_by()
    point_ids = sorted(set(scored.values_list("result__measurement_point_id", flat=True)))
    if len(point_ids) > MAX_LAB_MATRIX_POINTS:
        raise ValidationFailed(
            f"The lab matrix was asked for {len(point_ids)} measurement points; narrow it down "
            f"to at most {MAX_LAB_MATRIX_POINTS} with device, axis, frequency_hz, bench, direction."
        )
    pairs = scored.values_list("result__submission_id", "result__submission__participant_id")
    ids, participants = read_columns(pairs.distinct(), ("i8", "i8"))
    order = np.argsort(ids)
    loaded = load_round(
        comparison, only_points=point_ids, submissions=(ids[order], participants[order])
    )
    limit = float(run.parameters.get("en_limit", comparison.en_limit))
    return compatibility_matrices(loaded.table.columns(), "lab", None, limit=limit)
