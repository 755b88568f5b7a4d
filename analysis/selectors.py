"""Read side of analysis runs: the round's results as arrays, the current run."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from django.db.models import QuerySet

from analysis.core.compatibility import compatibility_matrices
from analysis.core.groups import Groups
from analysis.models import AnalysisRun, CompatibilityMatrix, Score
from analysis.pipeline import AssignedSpec, ResultTable, take_rows
from labs.models import Result, Submission
from labs.selectors import current_submissions
from proficiency.errors import ValidationFailed
from proficiency.models import AssignedValueMethod, Comparison, MeasurementPoint

_FIELDS = (
    "id",
    "measurement_point_id",
    "submission__participant__code",
    "submission__participant__is_reference",
    "measurement_point__device__name",
    "measurement_point__axis",
    "measurement_point__frequency_hz",
    "measurement_point__bench",
    "measurement_point__direction",
    "value",
    "expanded_uncertainty",
    "coverage_factor",
)


@dataclass(frozen=True)
class LoadedRound:
    """Accepted results of a comparison as columns, grouped by measurement point."""

    table: ResultTable
    result_id: np.ndarray
    is_reference: np.ndarray
    groups: Groups
    point_ids: np.ndarray  # one per group
    points: list[MeasurementPoint]  # one per group


def load_round(comparison: Comparison) -> LoadedRound:
    """One query for all current accepted results (no model instances per result)."""
    rows = list(
        Result.objects.filter(
            submission__in=current_submissions(comparison, (Submission.Status.ACCEPTED,))
        )
        .order_by("measurement_point_id", "submission__participant__code")
        .values_list(*_FIELDS)
    )
    cols = list(zip(*rows, strict=True)) if rows else [()] * len(_FIELDS)
    table = ResultTable(
        lab=np.array(cols[2], dtype=np.str_),
        device=np.array(cols[4], dtype=np.str_),
        axis=np.array(cols[5], dtype=np.str_),
        frequency_hz=np.array(cols[6], dtype=np.float64),
        bench=np.array(cols[7], dtype=np.str_),
        direction=np.array(cols[8], dtype=np.str_),
        value=np.array(cols[9], dtype=np.float64),
        expanded_uncertainty=np.array(cols[10], dtype=np.float64),
        coverage_factor=np.array(cols[11], dtype=np.float64),
    )
    point_of_result = np.array(cols[1], dtype=np.int64)
    point_ids, index = np.unique(point_of_result, return_inverse=True)
    by_id = MeasurementPoint.objects.select_related("device").in_bulk(point_ids.tolist())
    return LoadedRound(
        table=table,
        result_id=np.array(cols[0], dtype=np.int64),
        is_reference=np.array(cols[3], dtype=bool),
        groups=Groups.from_index(index.reshape(-1), point_ids.size),
        point_ids=point_ids,
        points=[by_id[int(i)] for i in point_ids],
    )


_METHOD_SPEC = {
    AssignedValueMethod.WEIGHTED_MEAN: "weighted_mean",
    AssignedValueMethod.ALGORITHM_A: "algorithm_a",
    AssignedValueMethod.MEDIAN: "median",
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


SCORE_FILTERS = {
    "device": "result__measurement_point__device__name",
    "axis": "result__measurement_point__axis",
    "frequency_hz": "result__measurement_point__frequency_hz",
    "bench": "result__measurement_point__bench",
    "direction": "result__measurement_point__direction",
    "lab": "result__submission__participant__code",
}


def run_scores(run: AnalysisRun, filters: dict[str, str]) -> QuerySet[Score]:
    """Scores of one run with their result and point, filtered by point keys or lab code."""
    qs = Score.objects.filter(run=run).select_related(
        "result__measurement_point__device", "result__submission__participant"
    )
    lookups = {SCORE_FILTERS[k]: v for k, v in filters.items() if k in SCORE_FILTERS and v}
    return qs.filter(**lookups).order_by(
        "result__measurement_point__device__name",
        "result__measurement_point__bench",
        "result__measurement_point__direction",
        "result__measurement_point__axis",
        "result__measurement_point__frequency_hz",
        "result__submission__participant__code",
    )


def run_matrices(
    run: AnalysisRun, factor: str, filters: dict[str, str]
) -> list[CompatibilityMatrix]:
    """Stored matrices of ``factor`` whose group matches every given key (device=..., ...)."""
    found = CompatibilityMatrix.objects.filter(run=run, factor=factor).order_by("group_key")
    wanted = {k: v for k, v in filters.items() if v}
    return [m for m in found if all(str(m.group.get(k)) == v for k, v in wanted.items()
                                    if k in m.group)]  # fmt: skip


MAX_LAB_MATRIX_POINTS = 50


def lab_matrices(comparison: Comparison, filters: dict[str, str]) -> list[Any]:
    """The lab x lab En matrices of the selected points, computed on request from the
    accepted results (never stored for a whole round: they grow with labs squared)."""
    loaded = load_round(comparison)
    t = loaded.table
    keep = np.ones(t.value.size, dtype=bool)
    for key in ("device", "axis", "bench", "direction"):
        if filters.get(key):
            keep &= getattr(t, key) == filters[key]
    if filters.get("frequency_hz"):
        keep &= np.isclose(t.frequency_hz, float(filters["frequency_hz"]), rtol=1e-9, atol=0)
    rows = np.flatnonzero(keep)
    table = take_rows(t, rows)
    n_points = np.unique(loaded.groups.index[rows]).size
    if n_points > MAX_LAB_MATRIX_POINTS:
        raise ValidationFailed(
            f"The lab matrix was asked for {n_points} measurement points; narrow it down to at "
            f"most {MAX_LAB_MATRIX_POINTS} with device, axis, frequency_hz, bench, direction."
        )
    return compatibility_matrices(table.columns(), "lab", None, limit=comparison.en_limit)
