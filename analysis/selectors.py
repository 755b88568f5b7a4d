"""Read side of analysis runs: the round's results as arrays, the current run."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from analysis.core.groups import Groups
from analysis.models import AnalysisRun
from analysis.pipeline import AssignedSpec, ResultTable
from labs.models import Result, Submission
from labs.selectors import current_submissions
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
