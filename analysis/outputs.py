"""The stored outputs of an analysis run, built column-wise from an ``Analysis``.

Scores go to PostgreSQL with one binary COPY assembled by numpy (``analysis.bulk``), to
other databases with ``bulk_create`` in large batches.  Assigned values are one row per
measurement point (with the point's consistency tests) and compatibility matrices one row
per group: small, built in Python.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from analysis.bulk import Column, copy_rows, is_postgresql
from analysis.consistency import consistency_records
from analysis.core.compatibility import CompatibilityMatrix as CoreMatrix
from analysis.core.pooled import Moments
from analysis.core.scores import FLAG_LABELS
from analysis.models import AnalysisRun, AssignedValue, CompatibilityMatrix, Score
from analysis.pipeline import Analysis, excluded_labs, json_value, matrix_record, point_method_of
from analysis.selectors import LoadedRound
from common.points import POINT_FIELDS
from common.quantities import shown_group

BATCH = 5000
_FLAGS = np.array([s.encode() for s in FLAG_LABELS])


def assigned_rows(run: AnalysisRun, loaded: LoadedRound, a: Analysis) -> list[AssignedValue]:
    """One row per point.  Diagnostics keep the keys that have a value at that point: with
    per-point methods the keys a set of points carries depends on which methods the set
    mixes, so a point's stored diagnostics never depend on how the round was chunked."""
    v = a.assigned
    diag = {k: arr for k, arr in v.diagnostics.items() if not k.startswith("_") and k != "method"}
    diag["excluded"] = np.array([*excluded_labs(a), None], dtype=object)[:-1]
    k_pt = v.coverage_factors
    tests = stored_consistency(a)
    return [
        AssignedValue(
            run=run,
            measurement_point_id=int(pid),
            value=float(v.value[g]),
            standard_uncertainty=float(v.standard_uncertainty[g]),
            method=point_method_of(v, g),
            sigma_pt=json_value(float(a.sigma_pt[g])),
            coverage_factor=float(k_pt[g]),
            diagnostics={k: x for k, arr in diag.items() if (x := json_value(arr[g])) is not None},
            consistency=tests[g],
        )
        for g, pid in enumerate(loaded.point_ids)
    ]


def stored_consistency(a: Analysis) -> list[dict[str, Any]]:
    """Per point, its consistency record without the point keys (the row names the point):
    per-point statistics, so a chunk holding all results of its points computes them."""
    return [
        {k: v for k, v in rec.items() if k not in POINT_FIELDS} for rec in consistency_records(a)
    ]


def score_columns(run_id: int, loaded: LoadedRound, a: Analysis) -> list[Column]:
    """The score rows as columns; z, z′ are NULL and z_flag empty where σ_pt is not set."""
    s, n = a.scores, loaded.result_id.size
    no_sigma = ~np.isfinite(a.sigma_pt)[loaded.groups.index]
    included, applies = a.in_assigned_value
    return [
        Column("run_id", "i8", np.full(n, run_id, dtype=np.int64)),
        Column("result_id", "i8", loaded.result_id),
        Column("d", "f8", s.d),
        Column("d_percent", "f8", s.d_percent, null=np.isnan(s.d_percent)),  # a phase: none
        Column("en", "f8", s.en),
        Column("zeta", "f8", s.zeta),
        Column("z", "f8", s.z, null=no_sigma),
        Column("z_prime", "f8", s.z_prime, null=no_sigma),
        Column("flag", "text", _FLAGS[s.en_flag]),
        Column("z_flag", "text", np.where(no_sigma, b"", _FLAGS[s.performance_flag])),
        Column("correlation_applied", "bool", np.asarray(s.correlation_applied, dtype=bool)),
        Column("correlation_failed", "bool", np.asarray(s.correlation_failed, dtype=bool)),
        Column("in_assigned_value", "bool", included, null=~applies),
    ]


def write_scores(run_id: int, loaded: LoadedRound, a: Analysis) -> int:
    """Insert the scores of ``loaded`` (inside the caller's transaction).

    Rows go in ascending result id: the (run, result) and result indexes then take them
    in one ordered sweep instead of one sweep per point (rows are loaded point by point),
    which halves PostgreSQL's index maintenance.
    """
    order = np.argsort(loaded.result_id, kind="stable")
    cols = [_take(c, order) for c in score_columns(run_id, loaded, a)]
    if is_postgresql():
        return copy_rows(Score._meta.db_table, cols)
    values = [_python_values(c) for c in cols]
    names = [c.name for c in cols]
    Score.objects.bulk_create(
        (Score(**dict(zip(names, row, strict=True))) for row in zip(*values, strict=True)),
        batch_size=BATCH,
    )
    return len(values[0])


def _take(c: Column, rows: np.ndarray) -> Column:
    null = None if c.null is None else c.null[rows]
    return Column(c.name, c.kind, c.values[rows], null)


def _python_values(c: Column) -> list[Any]:
    if c.kind == "text":
        return [v.decode() for v in c.values.tolist()]
    values = c.values.tolist()
    if c.null is None:
        return values
    return [None if null else v for v, null in zip(values, c.null.tolist(), strict=True)]


def moments_json(point_ids: np.ndarray, m: Moments) -> dict[str, list]:
    """Per-point moments as JSON (floats round-trip exactly through ``repr``)."""
    return {
        "point_id": point_ids.tolist(),
        "n": m.n.tolist(),
        "sum_x": m.sum_x.tolist(),
        "sum_u": m.sum_u.tolist(),
        "m2": m.m2.tolist(),
    }


def moments_from_json(parts: list[dict[str, list]]) -> tuple[np.ndarray, Moments]:
    """Concatenate the chunks' moments (chunks in point order)."""

    def cat(key: str, dtype: Any) -> np.ndarray:
        return np.concatenate([np.asarray(p[key], dtype=dtype) for p in parts])

    return cat("point_id", np.int64), Moments(
        n=cat("n", np.int64),
        sum_x=cat("sum_x", np.float64),
        sum_u=cat("sum_u", np.float64),
        m2=cat("m2", np.float64),
    )


def group_key(group: dict[str, Any]) -> str:
    """``device=MEMS 1, axis=X``: a matrix's group as text, the quantity kind only where it
    is not the magnitude (the keys of a round of magnitudes are those of before kinds)."""
    parts = [f"{k}={v}" for k, v in shown_group(group).items()]
    return ", ".join(parts) or "all"


def matrix_rows(run: AnalysisRun, matrices: list[CoreMatrix]) -> list[CompatibilityMatrix]:
    rows = []
    for rec in map(matrix_record, matrices):
        group = rec["group"]
        rows.append(
            CompatibilityMatrix(
                run=run,
                factor=rec["factor"],
                group=group,
                group_key=group_key(group),
                levels=rec["levels"],
                values=rec["value"],
                expanded_uncertainties=rec["expanded_uncertainty"],
                en=rec["en"],
                incompatible_pairs=rec["incompatible_pairs"],
            )
        )
    return rows
