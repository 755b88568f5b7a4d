"""Analysis runs: a persisted job per analysis (``pending → running → succeeded | failed``).

``analysis_run_start`` creates the run under a lock on the comparison and
enqueues the Celery task after the transaction commits.  The task calls
``analysis_run_execute``, which claims the run with a conditional UPDATE (two
workers never run the same job) and splits the measurement points that have
accepted results into chunks of about ``ANALYSIS_CHUNK_RESULTS`` results.  One
chunk (a small round) runs in the same task; more fan out as a Celery chord: a
group of ``analysis_chunk_execute`` tasks, then ``analysis_run_finish``.

Everything a chunk computes is per measurement point (assigned values, σ_pt,
scores), so chunks are independent.  A chunk stores its assigned values and
scores, and the per-point moments the compatibility matrices need, in one
transaction under a lock on its chunk row that also marks it done and counts it
on the run (``F()``): a redelivered or retried chunk is a no-op once done and is
redone alone otherwise; unique constraints forbid duplicates.  The final step
pools the moments of all chunks into the matrices (``analysis.core.pooled``,
the only cross-point work) and marks the run succeeded.  The single-task path is
the same code with one chunk, so both give identical numbers.
"""

from __future__ import annotations

import datetime as dt
import logging
import resource
import time
from typing import Any

import numpy as np
from django.conf import settings
from django.contrib.auth.models import AbstractBaseUser
from django.db import connection, transaction
from django.db.models import F, Value
from django.db.models.functions import Coalesce, Greatest
from django.utils import timezone

import proficiency
from analysis.bulk import planner_stats_refresh
from analysis.core.groups import CoreInputError
from analysis.core.pooled import compatibility_matrices_pooled, moments
from analysis.models import AnalysisChunk, AnalysisRun, AssignedValue, CompatibilityMatrix, Score
from analysis.outputs import (
    BATCH,
    assigned_rows,
    matrix_rows,
    moments_from_json,
    moments_json,
    write_scores,
)
from analysis.pipeline import (
    FACTORS,
    Analysis,
    SigmaPtSpec,
    analyse_grouped,
    assigned_values_mixed,
    sigma_pt_values,
)
from analysis.selectors import LoadedRound, load_round, point_result_counts, point_spec
from labs.models import Result
from labs.selectors import current_submissions
from proficiency.errors import ApplicationError, StateConflict, ValidationFailed
from proficiency.models import Comparison, ComparisonStatus, MeasurementPoint, SigmaPtMode

log = logging.getLogger(__name__)
R = AnalysisRun.Status
# Matrices stored with a run. The lab x lab matrix grows with the square of the
# participants at every point (10^9 cells for 1,000 labs x 1,000 points), so it is
# computed on request for the points asked for, never stored for the whole round.
STORED_FACTORS = tuple(f for f in FACTORS if f != "lab")
STALE_AFTER = dt.timedelta(hours=1)  # a "running" run older than this was lost with its worker


def analysis_run_start(
    *, comparison: Comparison, user: AbstractBaseUser | None, parameters: dict | None = None
) -> AnalysisRun:
    """Create a pending run and enqueue it once the transaction has committed."""
    from analysis.tasks import analysis_run_task

    with transaction.atomic():
        locked = Comparison.objects.select_for_update().get(pk=comparison.pk)
        if locked.status not in (ComparisonStatus.CLOSED, ComparisonStatus.ANALYSED):
            raise StateConflict(
                f"Comparison {locked.code} is {locked.status}; close it before running the "
                "analysis."
            )
        params = _parameters(locked) | (parameters or {})
        if active := _active_run(locked, params):  # two coordinators at once: one run
            return active
        run = AnalysisRun.objects.create(
            comparison=locked, parameters=params, code_version=proficiency.__version__,
            created_by=user,
        )  # fmt: skip
        transaction.on_commit(lambda: _enqueue(analysis_run_task, run.pk))
    return run


def _active_run(comparison: Comparison, parameters: dict) -> AnalysisRun | None:
    """A pending or running run of the same parameters that is not stale (the caller
    holds the comparison's lock, so a concurrent start waits and then finds it)."""
    active = AnalysisRun.objects.filter(
        comparison=comparison, status__in=(R.PENDING, R.RUNNING),
        created_at__gte=timezone.now() - STALE_AFTER,
    ).order_by("-pk")  # fmt: skip
    return next((run for run in active if run.parameters == parameters), None)


def _enqueue(task: Any, run_id: int) -> None:
    """Send the run's task; when the broker cannot be reached the run fails with a clear
    error (never a run pending for ever) and the coordinator starts it again later."""
    from kombu.exceptions import OperationalError

    try:
        task.delay(run_id)
    except (OperationalError, OSError) as exc:
        log.error("analysis run %s not queued, broker unreachable: %s", run_id, exc)
        _fail(run_id, "The task queue (broker) could not be reached; start the run again.")


def _parameters(c: Comparison) -> dict[str, Any]:
    return {
        "assigned_value_method": c.assigned_value_method,
        "sigma_pt_mode": c.sigma_pt_mode,
        "sigma_pt_value": c.sigma_pt_value,
        "en_limit": c.en_limit,
        "compare": list(STORED_FACTORS),
    }


def _claim(run_id: int) -> bool:
    """pending → running, or take over a running run whose worker was lost."""
    now = timezone.now()
    fresh = {"status": R.RUNNING, "started_at": now, "progress": 1, "error": "",
             "chunks_total": 0, "chunks_done": 0}  # fmt: skip
    if AnalysisRun.objects.filter(pk=run_id, status=R.PENDING).update(**fresh):
        return True
    stale = AnalysisRun.objects.filter(
        pk=run_id, status=R.RUNNING, started_at__lt=now - STALE_AFTER
    )
    return bool(stale.update(**fresh))


def _stage(run_id: int, stage: str, progress: int | None = None) -> None:
    fields: dict[str, Any] = {"stage": stage}
    if progress is not None:
        fields["progress"] = progress
    AnalysisRun.objects.filter(pk=run_id, status=R.RUNNING).update(**fields)


def analysis_run_execute(*, run_id: int, queue: str | None = None) -> str:
    """Claim ``run_id`` and analyse it: in this task (one chunk) or fanned out (a chord
    sent to ``queue``, else the default queue).

    Returns the run's status when this task ends ("running" while chunks are queued).
    """
    if not _claim(run_id):
        return AnalysisRun.objects.get(pk=run_id).status
    try:
        n_chunks = _plan(AnalysisRun.objects.select_related("comparison").get(pk=run_id))
    except ApplicationError as exc:
        return _fail(run_id, exc.message)
    except Exception as exc:  # any other error is shown too, never a silent stuck run
        log.exception("analysis run %s failed", run_id)
        return _fail(run_id, f"{type(exc).__name__}: {exc}")
    if n_chunks == 1:
        if analysis_chunk_execute(run_id=run_id, index=0) != R.RUNNING:
            return AnalysisRun.objects.get(pk=run_id).status
        return analysis_run_finish(run_id=run_id)
    _stage(run_id, f"analysing {n_chunks} chunks", 5)
    _dispatch(run_id, n_chunks, queue)
    return AnalysisRun.objects.get(pk=run_id).status


def _dispatch(run_id: int, n_chunks: int, queue: str | None) -> None:
    from celery import chord

    from analysis.tasks import analysis_chunk_task, analysis_finish_task

    options = {"queue": queue} if queue else {}
    header = [analysis_chunk_task.si(run_id, i).set(**options) for i in range(n_chunks)]
    chord(header)(analysis_finish_task.si(run_id).set(**options))


@transaction.atomic
def _plan(run: AnalysisRun) -> int:
    """Split the points with accepted results into chunks of about ANALYSIS_CHUNK_RESULTS
    results (whole points, ascending ids); replaces an earlier plan and its outputs."""
    comparison = run.comparison
    planner_stats_refresh()  # right after a bulk import the tables may have no statistics
    point_ids, counts = point_result_counts(comparison)
    if point_ids.size == 0:
        raise ValidationFailed(f"Comparison {comparison.code} has no accepted results to analyse.")
    for model in (AssignedValue, Score, CompatibilityMatrix, AnalysisChunk):
        model.objects.filter(run=run).delete()
    budget = max(1, int(settings.ANALYSIS_CHUNK_RESULTS))
    chunk_of = (np.cumsum(counts) - counts) // budget  # a point is never split
    _, first = np.unique(chunk_of, return_index=True)
    last = np.append(first[1:], point_ids.size) - 1
    AnalysisChunk.objects.bulk_create(
        AnalysisChunk(run=run, index=i, first_point_id=int(point_ids[a]),
                      last_point_id=int(point_ids[b]), n_results=int(counts[a : b + 1].sum()))
        for i, (a, b) in enumerate(zip(first.tolist(), last.tolist(), strict=True))
    )  # fmt: skip
    AnalysisRun.objects.filter(pk=run.pk).update(chunks_total=first.size, chunks_done=0)
    return int(first.size)


def _fail(run_id: int, message: str) -> str:
    AnalysisRun.objects.filter(pk=run_id, status__in=(R.PENDING, R.RUNNING)).update(
        status=R.FAILED, error=message, finished_at=timezone.now()
    )
    return R.FAILED


def analysis_chunk_execute(*, run_id: int, index: int) -> str:
    """Analyse one chunk of a running run and store its outputs; a done chunk is a no-op.

    Returns "running" when the chunk is stored (or was already), else the run's status.
    """
    chunks = AnalysisChunk.objects.select_related("run__comparison")
    chunk = chunks.filter(run_id=run_id, index=index).first()
    if chunk is None or chunk.run.status != R.RUNNING or chunk.done:  # None: re-planned
        return AnalysisRun.objects.get(pk=run_id).status
    run = chunk.run
    AnalysisChunk.objects.filter(pk=chunk.pk).update(attempts=F("attempts") + 1)
    t0 = time.perf_counter()
    try:
        if run.chunks_total == 1:
            _stage(run_id, "loading results", 10)
        loaded = load_round(run.comparison, chunk.first_point_id, chunk.last_point_id)
        analysis = _compute(run, loaded)
        _save_chunk(run, chunk, loaded, analysis, t0)
    except (ApplicationError, CoreInputError) as exc:
        return _fail(run_id, str(getattr(exc, "message", exc)))
    except Exception as exc:  # any other error is shown too, never a silent stuck run
        log.exception("analysis run %s, chunk %s failed", run_id, index)
        return _fail(run_id, f"{type(exc).__name__}: {exc}")
    return R.RUNNING


def peak_rss_kb() -> int:
    """This process's peak resident set size so far, in KiB.

    Linux: ``VmHWM`` of /proc/self/status, the high-water mark of this process's own
    memory; ``ru_maxrss`` is kept across ``execve`` and so starts at the RSS of the
    process that forked the worker.  Elsewhere ``ru_maxrss``.
    """
    try:
        with open("/proc/self/status", encoding="ascii") as status:
            for line in status:
                if line.startswith("VmHWM:"):
                    return int(line.split()[1])
    except OSError:
        pass
    return int(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss)


@transaction.atomic
def _save_chunk(
    run: AnalysisRun, chunk: AnalysisChunk, loaded: LoadedRound, a: Analysis, t0: float
) -> None:
    """Store one chunk's outputs, mark it done and count it on the run, atomically."""
    _lock_run(run.pk)  # before the chunk row: the order a deletion of the run locks them
    locked = AnalysisChunk.objects.select_for_update().get(pk=chunk.pk)
    if locked.done:  # a concurrent delivery stored it while this one computed
        return
    span = {"gte": chunk.first_point_id, "lte": chunk.last_point_id}
    points = {f"measurement_point_id__{op}": v for op, v in span.items()}
    stale, _ = AssignedValue.objects.filter(run=run, **points).delete()
    if stale:  # outputs without the done mark: not expected, but never duplicated
        Score.objects.filter(run=run, **{f"result__{k}": v for k, v in points.items()}).delete()
    AssignedValue.objects.bulk_create(assigned_rows(run, loaded, a), batch_size=BATCH)
    write_scores(run.pk, loaded, a)
    # Score.result has no database-level foreign key (see the model): one query per chunk
    # checks that every result scored still exists, instead of one locking check per row.
    if not _results_still_there(run, loaded, points):
        raise StateConflict(
            "Results of this comparison were deleted while the analysis ran; start it again."
        )
    rss = peak_rss_kb()
    m = moments(loaded.table.value, loaded.table.standard_uncertainty, loaded.groups)
    AnalysisChunk.objects.filter(pk=chunk.pk).update(
        done=True, moments=moments_json(loaded.point_ids, m), peak_rss_kb=rss,
        seconds=time.perf_counter() - t0, finished_at=timezone.now(),
    )  # fmt: skip
    AnalysisRun.objects.filter(pk=run.pk, status=R.RUNNING).update(
        chunks_done=F("chunks_done") + 1,
        progress=Value(5) + (F("chunks_done") + 1) * 90 / F("chunks_total"),
        peak_rss_kb=Greatest(Coalesce(F("peak_rss_kb"), Value(0)), Value(rss)),
    )


def _results_still_there(run: AnalysisRun, loaded: LoadedRound, points: dict[str, int]) -> bool:
    """Whether every result the chunk scored still exists.

    PostgreSQL: count the results of the loaded submissions at the chunk's points (an
    index-only scan of the (submission, point) unique index, ~50 ms per 100,000 results)
    against the loaded ones.  Exact because results are added to and deleted from draft
    versions only (``labs.services``, ``labs.bulk_import``): a submitted or accepted
    version's results change only when the version itself is deleted, so no insertion can
    hide a deletion.  This replaces a join of the run's scores with the results, which
    cost more with every chunk already stored (chunk k joined k + 1 chunks' rows), and
    an index probe per result id (~0.4 s per 100,000).  Elsewhere (small rounds): the join.
    """
    if connection.vendor != "postgresql":
        scored = Score.objects.filter(run=run, **{f"result__{k}": v for k, v in points.items()})
        return scored.count() == loaded.result_id.size
    with connection.cursor() as cur:
        cur.execute(
            f"SELECT count(*) FROM {Result._meta.db_table} "
            "WHERE submission_id = ANY(%s) AND measurement_point_id BETWEEN %s AND %s",
            [loaded.submission_ids.tolist(), points["measurement_point_id__gte"],
             points["measurement_point_id__lte"]],
        )  # fmt: skip
        return int(cur.fetchone()[0]) == loaded.result_id.size


def _lock_run(run_id: int) -> None:
    """Hold the run row FOR KEY SHARE until this transaction ends, or fail if it is gone.

    ``Score.run`` has no database foreign key (its per-row check cost more than the COPY):
    this one lock per chunk is what keeps a run from being deleted while its chunk writes
    scores (a deletion locks the run FOR UPDATE first: ``models.lock_run_before_delete``).
    KEY SHARE, not SHARE: chunks of the same run share it and still update the run's
    counters.  Other databases (SQLite, for development): an existence check only.
    """
    if connection.vendor == "postgresql":
        with connection.cursor() as cur:
            cur.execute(
                f"SELECT 1 FROM {AnalysisRun._meta.db_table} WHERE id = %s FOR KEY SHARE",
                [run_id],
            )
            found = cur.fetchone() is not None
    else:
        found = AnalysisRun.objects.filter(pk=run_id).exists()
    if not found:
        raise StateConflict("This analysis run was deleted while it ran.")


def analysis_run_finish(*, run_id: int) -> str:
    """The final step: pool the chunks' moments into compatibility matrices, store them and
    mark the run succeeded (a run that failed or finished already is left as it is)."""
    run = AnalysisRun.objects.select_related("comparison").get(pk=run_id)
    if run.status != R.RUNNING:
        return run.status
    chunks = list(AnalysisChunk.objects.filter(run=run).order_by("index"))
    missing = [c.index for c in chunks if not c.done]
    if missing or len(chunks) != run.chunks_total or not chunks:
        return _fail(run_id, f"Chunks {missing} of this run were not stored; start it again.")
    try:
        _stage(run_id, "compatibility", 96)
        matrices = _matrices(run, [c.moments for c in chunks])
        _finish(run, matrices)
    except (ApplicationError, CoreInputError) as exc:
        return _fail(run_id, str(getattr(exc, "message", exc)))
    except Exception as exc:
        log.exception("analysis run %s failed in its final step", run_id)
        return _fail(run_id, f"{type(exc).__name__}: {exc}")
    return R.SUCCEEDED


def _matrices(run: AnalysisRun, parts: list[dict]) -> list:
    point_ids, m = moments_from_json(parts)
    rows = MeasurementPoint.objects.filter(pk__in=point_ids.tolist()).values_list(
        "pk", "device__name", "axis", "frequency_hz", "bench", "direction"
    )
    by_id = {r[0]: r[1:] for r in rows}
    cols = list(zip(*(by_id[int(p)] for p in point_ids), strict=True))
    labels = {
        "device": np.array(cols[0], dtype=np.str_),
        "axis": np.array(cols[1], dtype=np.str_),
        "frequency_hz": np.array(cols[2], dtype=np.float64),
        "bench": np.array(cols[3], dtype=np.str_),
        "direction": np.array(cols[4], dtype=np.str_),
    }
    limit = run.comparison.en_limit
    return [
        mat
        for factor in run.parameters.get("compare", STORED_FACTORS)
        for mat in compatibility_matrices_pooled(labels, m, factor, limit=limit)
    ]


@transaction.atomic
def _finish(run: AnalysisRun, matrices: list) -> None:
    CompatibilityMatrix.objects.filter(run=run).delete()
    CompatibilityMatrix.objects.bulk_create(matrix_rows(run, matrices), batch_size=BATCH)
    AnalysisRun.objects.filter(pk=run.pk, status=R.RUNNING).update(
        status=R.SUCCEEDED, progress=100, stage="done", finished_at=timezone.now(),
        peak_rss_kb=Greatest(Coalesce(F("peak_rss_kb"), Value(0)), Value(peak_rss_kb())),
    )  # fmt: skip
    Comparison.objects.filter(pk=run.comparison_id, status=ComparisonStatus.CLOSED).update(
        status=ComparisonStatus.ANALYSED
    )


def _compute(run: AnalysisRun, loaded: LoadedRound) -> Analysis:
    comparison = run.comparison
    reference = _reference_code(comparison)
    specs = [point_spec(comparison, p, reference) for p in loaded.points]
    _check_specs(specs, loaded)
    keys = [(p.device.name, p.axis, p.frequency_hz, p.bench, p.direction) for p in loaded.points]
    values = assigned_values_mixed(loaded.table, loaded.groups, keys, specs)
    sigma = _sigma(comparison, loaded, values)
    return analyse_grouped(
        loaded.table, loaded.groups, keys, values, sigma=sigma, en_limit=comparison.en_limit
    )


def _reference_code(comparison: Comparison) -> str:
    """The reference laboratory's code: the first by code among current accepted ones."""
    code = (
        current_submissions(comparison)
        .filter(participant__is_reference=True)
        .order_by("participant__code")
        .values_list("participant__code", flat=True)
        .first()
    )
    return code or ""


def _check_specs(specs: list, loaded: LoadedRound) -> None:
    for spec, point in zip(specs, loaded.points, strict=True):
        if spec.method == "nominal" and not (spec.nominal and spec.tolerance):
            raise ValidationFailed(
                f"Device {point.device.name} has no nominal sensitivity and tolerance, needed "
                "for the nominal assigned value."
            )
        if spec.method == "reference" and not spec.reference_lab:
            raise ValidationFailed(
                "No participant is marked as the reference laboratory of this comparison."
            )


def _sigma(comparison: Comparison, loaded: LoadedRound, values: Any) -> np.ndarray:
    mode, value = comparison.sigma_pt_mode, comparison.sigma_pt_value
    spec = SigmaPtSpec() if mode == SigmaPtMode.NONE else SigmaPtSpec(mode, value)
    sigma = sigma_pt_values(loaded.table.value, loaded.groups, values, spec)
    override = np.array([p.sigma_pt_value or np.nan for p in loaded.points], dtype=float)
    return np.where(np.isfinite(override), override, sigma)
