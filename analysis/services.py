"""Analysis runs: a persisted job per analysis
(``pending → running → succeeded | failed | cancelled``).

``analysis_run_start`` creates the run under a lock on the comparison and
enqueues the Celery task after the transaction commits.  The task calls
``analysis_run_execute``, which claims the run with a conditional UPDATE (two
workers never run the same job) and splits the measurement points that have
accepted results into chunks of about ``ANALYSIS_CHUNK_RESULTS`` results.  One
chunk (a small round) runs in the same task; more fan out as a group of
``analysis_chunk_execute`` tasks, and the chunk that stores the last one queues
``analysis_run_finish``.

Everything a chunk computes is per measurement point (assigned values, σ_pt,
scores), so chunks are independent.  A task works on a chunk under a claim: a
conditional UPDATE gives the chunk a new random ``token`` if it is not done and
unclaimed, or its claim's heartbeat is stale, or the claim is this very task's
(a redelivery).  A chunk stores its assigned values and scores, and the per-point
moments the compatibility matrices need, in one transaction under a lock on its
chunk row, only if the run is still running and the token is still its own; the
same transaction marks it done and counts it on the run (``F()``).  So a chunk
delivered twice, re-queued by the sweep while it finishes, or taken over from a
lost worker is stored exactly once: unique constraints forbid duplicates.  The
final step pools the moments of all chunks into the matrices
(``analysis.core.pooled``, the only cross-point work) and marks the run
succeeded.  The single-task path is the same code with one chunk, so both give
identical numbers.

Lost workers (``common.jobs``): every task heartbeats the run (and its chunk)
while it works; ``analysis_sweep`` (Celery beat) re-queues the chunks whose claim
went stale, and the work of a run silent for ``JOB_STALE_SECONDS`` (its run task,
its unclaimed chunks or its final step).  A run that fails or is cancelled keeps
none of its outputs: ``_fail`` locks the run row FOR UPDATE, so chunks in the middle
of storing are waited for and their rows deleted, and later ones find the run no
longer running and store nothing.
"""

from __future__ import annotations

import logging
import resource
import secrets
import time
from collections.abc import Callable, Iterable
from typing import Any

import numpy as np
from celery import group, uuid
from django.conf import settings
from django.contrib.auth.models import User
from django.db import connection, transaction
from django.db.models import F, Q, Value
from django.db.models.functions import Coalesce, Greatest
from django.utils import timezone

import proficiency
from analysis.bulk import planner_stats_refresh
from analysis.core.groups import CoreInputError
from analysis.core.pooled import Moments, compatibility_matrices_pooled, moments
from analysis.core.robust import DegenerateScaleError
from analysis.kit_run import KitOutputs, kit_outputs_delete, kit_outputs_store, kit_prepare
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
    linear_values_of,
    nonfinite_points,
    overflowing_results,
    sigma_pt_values,
)
from analysis.selectors import LoadedRound, load_round, point_result_counts, point_spec
from analysis.tasks import (
    analysis_chunk_task,
    analysis_finish_task,
    analysis_run_task,
    charts_warm_task,
)
from common import jobs
from common.errors import ApplicationError, StateConflict, ValidationFailed
from common.jobs import heartbeat
from common.points import POINT_LOOKUPS, group_text
from labs.models import Result
from labs.selectors import current_submissions
from proficiency.models import Comparison, ComparisonStatus, MeasurementPoint, SigmaPtMode

log = logging.getLogger(__name__)
R = AnalysisRun.Status
ACTIVE = (R.PENDING, R.RUNNING)
# Matrices stored with a run. The lab x lab matrix grows with the square of the
# participants at every point (10^9 cells for 1,000 labs x 1,000 points), so it is
# computed on request for the points asked for, never stored for the whole round.
STORED_FACTORS = tuple(f for f in FACTORS if f != "lab")


def analysis_run_start(
    *, comparison: Comparison, user: User | None, parameters: dict | None = None
) -> AnalysisRun:
    """Create a pending run and enqueue it once the transaction has committed."""
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
            created_by=user, heartbeat_at=timezone.now(),
        )  # fmt: skip
        transaction.on_commit(
            lambda: _enqueue(analysis_run_task, run.pk, on_unreachable=lambda: _fail_unsent(run.pk))
        )
    return run


def _active_run(comparison: Comparison, parameters: dict) -> AnalysisRun | None:
    """A pending or running run of the same parameters (the caller holds the comparison's
    lock, so a concurrent start waits and then finds it).  A run whose worker was lost is
    still the active one: the sweep resumes it, or a coordinator cancels it."""
    active = AnalysisRun.objects.filter(comparison=comparison, status__in=ACTIVE).order_by("-pk")
    return next((run for run in active if run.parameters == parameters), None)


def _enqueue(
    task: Any, *args: Any, queue: str | None = None,
    on_unreachable: Callable[[], object] | None = None,
) -> bool:  # fmt: skip
    """Send a task of run ``args[0]`` (``common.jobs.send``); when the broker cannot be
    reached, ``on_unreachable`` runs (a new run: :func:`_fail_unsent`), and a later step is
    left to the sweep."""
    return jobs.send(task, args, queue=queue, what=f"analysis run {args[0]}",
                     on_unreachable=on_unreachable)  # fmt: skip


BROKER_UNREACHABLE = "The task queue (broker) could not be reached; start the run again."


def _fail_unsent(run_id: int) -> None:
    """A new run whose task could not be sent fails with a clear error: never a run
    pending for ever (a coordinator starts it again)."""
    AnalysisRun.objects.filter(pk=run_id, status=R.PENDING).update(
        status=R.FAILED, finished_at=timezone.now(), error=BROKER_UNREACHABLE
    )


def _parameters(c: Comparison) -> dict[str, Any]:
    return {
        "assigned_value_method": c.assigned_value_method,
        "sigma_pt_mode": c.sigma_pt_mode,
        "sigma_pt_value": c.sigma_pt_value,
        "en_limit": c.en_limit,
        "compare": list(STORED_FACTORS),
        "drift_treatment": c.drift_treatment,
    }


def _claim(run_id: int, delivery: str = "") -> bool:
    """pending → running; or take over a running run whose heartbeat is stale, or that
    this very task (``delivery``: its Celery id, redelivered after its worker was lost)
    had claimed.  Taking over keeps the run's plan: only its lost work is redone."""
    fresh = {"status": R.RUNNING, "started_at": timezone.now(), "progress": 1, "error": "",
             "chunks_total": 0, "chunks_done": 0}  # fmt: skip
    rows = AnalysisRun.objects.filter(pk=run_id)
    return jobs.claim(rows, delivery=delivery, fresh=fresh, takeover={})


def _stage(run_id: int, stage: str, progress: int | None = None) -> None:
    fields: dict[str, Any] = {"stage": stage}
    if progress is not None:
        fields["progress"] = progress
    AnalysisRun.objects.filter(pk=run_id, status=R.RUNNING).update(**fields)


def _table(model: Any) -> str:
    return connection.ops.quote_name(model._meta.db_table)


def _beat_run(run_id: int) -> None:
    """The run's heartbeat; skipped while the run row is locked (a chunk counting itself,
    a failure or cancellation in progress): never waits."""
    jobs.beat(AnalysisRun, run_id, status=R.RUNNING)


def _beat_chunk(run_id: int, chunk_id: int, token: str) -> None:
    """The chunk's heartbeat while its claim is ``token``, and the run's.  Skipped while
    the chunk row is locked, i.e. while its outputs are being stored."""
    jobs.beat(AnalysisChunk, chunk_id, lock="UPDATE", token=token)
    _beat_run(run_id)


def analysis_run_execute(*, run_id: int, queue: str | None = None, delivery: str = "") -> str:
    """Claim ``run_id`` and analyse it: in this task (one chunk) or fanned out (chunk tasks
    sent to ``queue``, else the default queue).  ``delivery``: this task's Celery id.

    Returns the run's status when this task ends ("running" while chunks are queued).
    """
    if not _claim(run_id, delivery):
        return AnalysisRun.objects.get(pk=run_id).status
    with heartbeat(lambda: _beat_run(run_id), f"analysis run {run_id}"):
        return _execute(run_id, queue, delivery)


def _execute(run_id: int, queue: str | None, delivery: str) -> str:
    run = AnalysisRun.objects.select_related("comparison").get(pk=run_id)
    n_chunks = run.chunks_total  # > 0: a run taken over after it was planned
    if n_chunks == 0:
        try:
            n_chunks = _plan(run)
        except ApplicationError as exc:
            return _fail(run_id, exc.message)
        except Exception as exc:  # any other error is shown too, never a silent stuck run
            log.exception("analysis run %s failed", run_id)
            return _fail(run_id, f"{type(exc).__name__}: {exc}")
    if n_chunks == 1:
        done = AnalysisChunk.objects.filter(run_id=run_id, index=0, done=True).exists()
        if not done and analysis_chunk_execute(
            run_id=run_id, index=0, delivery=delivery, then_finish=False
        ) != R.RUNNING:  # fmt: skip
            return AnalysisRun.objects.get(pk=run_id).status
        return analysis_run_finish(run_id=run_id)
    todo = list(
        AnalysisChunk.objects.filter(run_id=run_id, done=False).values_list("index", flat=True)
    )
    if not todo:  # taken over after every chunk was stored
        return analysis_run_finish(run_id=run_id)
    if len(todo) == n_chunks:
        _stage(run_id, f"analysing {n_chunks} chunks", 5)
    _dispatch(run_id, todo, queue)
    return AnalysisRun.objects.get(pk=run_id).status


def _dispatch(run_id: int, indexes: Iterable[int], queue: str | None) -> None:
    """Send one task per chunk; the chunk that stores the last one queues the final step."""
    options = {"queue": queue} if queue else {}
    group(analysis_chunk_task.si(run_id, i).set(**options) for i in indexes).apply_async()


@transaction.atomic
def _plan(run: AnalysisRun) -> int:
    """Split the points with accepted results into chunks of about ANALYSIS_CHUNK_RESULTS
    results (whole points, ascending ids); replaces an earlier plan and its outputs."""
    comparison = run.comparison
    locked = AnalysisRun.objects.select_for_update().get(pk=run.pk)
    if locked.chunks_total:  # planned meanwhile by the task this one took over from
        return locked.chunks_total
    planner_stats_refresh()  # right after a bulk import the tables may have no statistics
    point_ids, counts = point_result_counts(comparison)
    if point_ids.size == 0:
        raise ValidationFailed(f"Comparison {comparison.code} has no accepted results to analyse.")
    _delete_outputs(run.pk)
    AnalysisChunk.objects.filter(run=run).delete()
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


def _delete_outputs(run_id: int) -> None:
    for model in (AssignedValue, Score, CompatibilityMatrix):
        model.objects.filter(run_id=run_id).delete()
    kit_outputs_delete(run_id)


def _fail(run_id: int, message: str) -> str:
    """Fail an active run with ``message``, deleting its outputs; the run's status
    afterwards (a run already ended is left as it is)."""
    _end(run_id, message, R.FAILED)
    return _status(run_id)


def _end(run_id: int, message: str, status: str) -> bool:
    """End an active run as ``status`` with ``message`` and delete every output it stored;
    whether it was active."""
    with transaction.atomic():
        # FOR UPDATE waits for the chunks storing their outputs (they hold the row FOR KEY
        # SHARE) and makes later ones wait for this and then find the run ended.
        run = AnalysisRun.objects.select_for_update().filter(pk=run_id).first()
        if run is None or run.status not in ACTIVE:
            return False
        AnalysisRun.objects.filter(pk=run_id).update(
            status=status, error=message, finished_at=timezone.now()
        )
        _delete_outputs(run_id)
    return True


def analysis_run_cancel(*, run: AnalysisRun, user: User | None) -> AnalysisRun:
    """Cancel a pending or running run: it stores nothing more and keeps no outputs; its
    queued tasks find it cancelled and do nothing.  A new run can be started at once."""
    who = getattr(user, "get_username", lambda: "")() or "a coordinator"
    if not _end(run.pk, f"Cancelled by {who}.", R.CANCELLED):
        raise StateConflict(
            f"Analysis run {run.pk} is {_status(run.pk)}; only a pending or running run can "
            "be cancelled."
        )
    run.refresh_from_db()
    return run


def _status(run_id: int) -> str:
    return AnalysisRun.objects.filter(pk=run_id).values_list("status", flat=True).first() or (
        "missing"
    )


def _claim_chunk(chunk_id: int, delivery: str) -> str | None:
    """Claim a chunk that is not done: unclaimed, or its claim's heartbeat is stale, or
    the claim was this very task's (a redelivery).  The new claim's token, or None."""
    token = secrets.token_hex(16)
    takeover = Q(token="") | jobs.silent() | jobs.redelivered(delivery)
    claimed = AnalysisChunk.objects.filter(takeover, pk=chunk_id, done=False).update(
        token=token, claimed_by=delivery, heartbeat_at=timezone.now(),
        attempts=F("attempts") + 1,
    )  # fmt: skip
    return token if claimed else None


def analysis_chunk_execute(
    *, run_id: int, index: int, delivery: str = "", queue: str | None = None,
    then_finish: bool = True,
) -> str:  # fmt: skip
    """Analyse one chunk of a running run and store its outputs; a done chunk is a no-op,
    and so is a chunk another live task holds.  ``then_finish``: the chunk that stores the
    run's last one queues the final step (to ``queue``).

    Returns "running" when the chunk is stored (or was already, or is held), else the
    run's status.
    """
    chunks = AnalysisChunk.objects.select_related("run__comparison")
    chunk = chunks.filter(run_id=run_id, index=index).first()
    if chunk is None or chunk.run.status != R.RUNNING or chunk.done:  # None: re-planned
        return _status(run_id)
    token = _claim_chunk(chunk.pk, delivery)
    if token is None:  # stored meanwhile, held by another live task, or deleted with the run
        return _status(run_id)
    run = chunk.run
    t0 = time.perf_counter()
    with heartbeat(lambda: _beat_chunk(run_id, chunk.pk, token), f"chunk {index} of {run_id}"):
        try:
            if run.chunks_total == 1:
                _stage(run_id, "loading results", 10)
            loaded = load_round(run.comparison, chunk.first_point_id, chunk.last_point_id)
            loaded, kits = kit_prepare(run, loaded)  # drift handled, kits linked (§13, §14)
            analysis, m = _compute_checked(run, loaded)
            stored, last = _save_chunk(run, chunk, token, loaded, analysis, m, t0, kits)
        except (ApplicationError, CoreInputError) as exc:
            return _fail(run_id, str(getattr(exc, "message", exc)))
        except Exception as exc:  # any other error is shown too, never a silent stuck run
            log.exception("analysis run %s, chunk %s failed", run_id, index)
            return _fail(run_id, f"{type(exc).__name__}: {exc}")
    if not stored:  # the run ended meanwhile, or the chunk was taken over
        return _status(run_id)
    if last and then_finish:
        _enqueue(analysis_finish_task, run_id, queue=queue)  # if lost: the sweep sends it
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
    run: AnalysisRun, chunk: AnalysisChunk, token: str, loaded: LoadedRound, a: Analysis,
    m: Moments, t0: float, kits: KitOutputs | None = None,
) -> tuple[bool, bool]:  # fmt: skip
    """Store one chunk's outputs, mark it done and count it on the run, atomically, if
    the run still runs and the chunk's claim is still ``token``: whether it stored them,
    and whether that was the run's last chunk."""
    # the run before the chunk row: the order a deletion of the run locks them
    if _lock_run(run.pk) != R.RUNNING:  # failed or cancelled meanwhile: store nothing
        return False, False
    # of=self, no ordering: the default ordering joins the run, which FOR UPDATE would lock
    query = AnalysisChunk.objects.select_for_update(of=("self",)).order_by().filter(pk=chunk.pk)
    locked = query.first()
    if locked is None or locked.done or locked.token != token:
        return False, False  # re-planned, stored by another delivery, or taken over
    span = {"gte": chunk.first_point_id, "lte": chunk.last_point_id}
    points = {f"measurement_point_id__{op}": v for op, v in span.items()}
    stale, _ = AssignedValue.objects.filter(run=run, **points).delete()
    if stale:  # outputs without the done mark: not expected, but never duplicated
        Score.objects.filter(run=run, **{f"result__{k}": v for k, v in points.items()}).delete()
    AssignedValue.objects.bulk_create(assigned_rows(run, loaded, a), batch_size=BATCH)
    write_scores(run.pk, loaded, a)
    kit_outputs_store(run, chunk.first_point_id, chunk.last_point_id, kits)
    # Score.result has no database-level foreign key (see the model): one query per chunk
    # checks that every result scored still exists, instead of one locking check per row.
    if not _results_still_there(run, loaded, points):
        raise StateConflict(
            "Results of this comparison were deleted while the analysis ran; start it again."
        )
    rss = peak_rss_kb()
    now = timezone.now()
    AnalysisChunk.objects.filter(pk=chunk.pk).update(
        done=True, moments=moments_json(loaded.point_ids, m), peak_rss_kb=rss,
        seconds=time.perf_counter() - t0, finished_at=now, heartbeat_at=now,
    )  # fmt: skip
    AnalysisRun.objects.filter(pk=run.pk, status=R.RUNNING).update(
        chunks_done=F("chunks_done") + 1,
        progress=Value(5) + (F("chunks_done") + 1) * 90 / F("chunks_total"),
        peak_rss_kb=Greatest(Coalesce(F("peak_rss_kb"), Value(0)), Value(rss)),
        heartbeat_at=now,
    )
    # the run row is now locked by this transaction: the count read is exact, and only
    # one chunk's transaction reads the total
    done, total = AnalysisRun.objects.values_list("chunks_done", "chunks_total").get(pk=run.pk)
    return True, done == total


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


def _lock_run(run_id: int) -> str:
    """Hold the run row FOR KEY SHARE until this transaction ends; the run's status, or
    fail if it is gone.

    ``Score.run`` has no database foreign key (its per-row check cost more than the COPY):
    this one lock per chunk is what keeps a run from being deleted while its chunk writes
    scores (a deletion locks the run FOR UPDATE first: ``models.lock_run_before_delete``),
    and from failing or being cancelled without deleting them (``_fail`` locks it FOR
    UPDATE too).  KEY SHARE, not SHARE: chunks of the same run share it and still update
    the run's counters.  Other databases (SQLite, for development): a read only.
    """
    if connection.vendor == "postgresql":
        with connection.cursor() as cur:
            cur.execute(
                f"SELECT status FROM {_table(AnalysisRun)} WHERE id = %s FOR KEY SHARE", [run_id]
            )
            row = cur.fetchone()
    else:
        row = AnalysisRun.objects.filter(pk=run_id).values_list("status").first()
    if row is None:
        raise StateConflict("This analysis run was deleted while it ran.")
    return str(row[0])


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
    with heartbeat(lambda: _beat_run(run_id), f"analysis run {run_id}"):
        try:
            _stage(run_id, "compatibility", 96)
            matrices = _matrices(run, [c.moments for c in chunks])
            _check_matrices(matrices)
            return _finish(run, matrices)
        except (ApplicationError, CoreInputError) as exc:
            return _fail(run_id, str(getattr(exc, "message", exc)))
        except Exception as exc:
            log.exception("analysis run %s failed in its final step", run_id)
            return _fail(run_id, f"{type(exc).__name__}: {exc}")


def _matrices(run: AnalysisRun, parts: list[dict]) -> list:
    point_ids, m = moments_from_json(parts)
    rows = MeasurementPoint.objects.filter(pk__in=point_ids.tolist()).values_list(
        "pk", *POINT_LOOKUPS
    )
    by_id = {r[0]: r[1:] for r in rows}
    cols = list(zip(*(by_id[int(p)] for p in point_ids), strict=True))
    labels = {
        "device": np.array(cols[0], dtype=np.str_),
        "axis": np.array(cols[1], dtype=np.str_),
        "frequency_hz": np.array(cols[2], dtype=np.float64),
        "bench": np.array(cols[3], dtype=np.str_),
        "direction": np.array(cols[4], dtype=np.str_),
        "quantity": np.array(cols[5], dtype=np.str_),
    }
    limit = run.comparison.en_limit
    return [
        mat
        for factor in run.parameters.get("compare", STORED_FACTORS)
        for mat in compatibility_matrices_pooled(labels, m, factor, limit=limit)
    ]


def _check_matrices(matrices: list) -> None:
    """Matrices are stored as JSON, which has no NaN or infinity (PostgreSQL refuses them)."""
    for m in matrices:
        numbers = (np.asarray(m.value), np.asarray(m.expanded_uncertainty), np.asarray(m.en))
        if not all(np.isfinite(a).all() for a in numbers):
            group = group_text(m.group) or "the whole round"
            raise ValidationFailed(
                f"The {m.factor} compatibility matrix of {group} is not finite: the results "
                "pooled there are too large or their uncertainties too small to compute with. "
                "Correct them and start the run again."
            )


@transaction.atomic
def _finish(run: AnalysisRun, matrices: list) -> str:
    locked = AnalysisRun.objects.select_for_update().get(pk=run.pk)
    if locked.status != R.RUNNING:  # finished by another delivery, or failed or cancelled
        return locked.status
    CompatibilityMatrix.objects.filter(run=run).delete()
    CompatibilityMatrix.objects.bulk_create(matrix_rows(run, matrices), batch_size=BATCH)
    AnalysisRun.objects.filter(pk=run.pk, status=R.RUNNING).update(
        status=R.SUCCEEDED, progress=100, stage="done", finished_at=timezone.now(),
        peak_rss_kb=Greatest(Coalesce(F("peak_rss_kb"), Value(0)), Value(peak_rss_kb())),
    )  # fmt: skip
    Comparison.objects.filter(pk=run.comparison_id, status=ComparisonStatus.CLOSED).update(
        status=ComparisonStatus.ANALYSED
    )
    if settings.CHART_WARMING:  # the coordinator's first view of the charts finds them drawn
        transaction.on_commit(lambda: _enqueue(charts_warm_task, run.pk))
    return R.SUCCEEDED


# --- the stale-job sweep -------------------------------------------------------------------


def analysis_sweep() -> dict[str, int]:
    """Celery beat (``JOB_SWEEP_SECONDS``): re-queue the work of runs whose worker was lost.

    * a chunk whose claim's heartbeat is older than ``JOB_STALE_SECONDS``: its claim is
      dropped and a new chunk task sent (a chunk being stored is locked, so skipped);
    * a run silent for that long (no heartbeat of any of its tasks): its run task if it is
      pending or not planned yet (the new task may take the claim over), else its chunks
      that no task holds and none was sent for within that time, else (every chunk
      stored) its final step.

    Idempotent: each task sent is decided by a conditional UPDATE (a dropped claim, or a
    chunk's or the run's heartbeat moved to now), so two sweeps at once send each task
    once, and a task delivered twice finds its work claimed or done.  Returns the counts
    of tasks sent.
    """
    sent = {"runs": 0, "chunks": 0, "finish": 0}
    now = timezone.now()
    with transaction.atomic():
        lost = list(
            AnalysisChunk.objects.select_for_update(skip_locked=True, of=("self",))
            .order_by()
            .filter(jobs.silent(), run__status=R.RUNNING, done=False)
            .exclude(token="")
            .values_list("pk", "run_id", "index")
        )
        # the heartbeat moved to now: the task is sent, the run rule below waits for it
        AnalysisChunk.objects.filter(pk__in=[c[0] for c in lost]).update(
            token="", claimed_by="", heartbeat_at=now
        )
    for _, run_id, index in lost:
        log.warning("analysis run %s: chunk %s lost with its worker, queued again", run_id, index)
        sent["chunks"] += _enqueue(analysis_chunk_task, run_id, index)
    for run in AnalysisRun.objects.filter(jobs.silent("created_at"), status__in=ACTIVE):
        log.warning("analysis run %s silent since %s: its work is queued again", run.pk,
                    run.heartbeat_at or run.created_at)  # fmt: skip
        if run.status == R.PENDING or run.chunks_total == 0:
            task_id = uuid()  # the run task sent may take the claim over
            if _lease(run, claimed_by=task_id):
                sent["runs"] += _send(analysis_run_task, run.pk, task_id=task_id)
            continue
        unsent = AnalysisChunk.objects.filter(
            jobs.silent() | Q(heartbeat_at__isnull=True), run=run, done=False, token=""
        )
        for pk, index, beat in unsent.values_list("pk", "index", "heartbeat_at"):
            if AnalysisChunk.objects.filter(pk=pk, token="", heartbeat_at=beat).update(
                heartbeat_at=now
            ):  # fmt: skip
                sent["chunks"] += _enqueue(analysis_chunk_task, run.pk, index)
        if not AnalysisChunk.objects.filter(run=run, done=False).exists() and _lease(run):
            sent["finish"] += _enqueue(analysis_finish_task, run.pk)
    return sent


def _lease(run: AnalysisRun, **fields: Any) -> bool:
    """Move a silent run's heartbeat to now, unless another sweep or a task did."""
    return jobs.lease(AnalysisRun.objects.all(), pk=run.pk, status=run.status,
                      heartbeat_at=run.heartbeat_at, **fields)  # fmt: skip


def _send(task: Any, run_id: int, *, task_id: str) -> bool:
    return jobs.send(task, (run_id,), task_id=task_id, what=f"analysis run {run_id}")


# --- computing a chunk ---------------------------------------------------------------------


def _compute_checked(run: AnalysisRun, loaded: LoadedRound) -> tuple[Analysis, Moments]:
    """The chunk's analysis and moments, or a ValidationFailed naming the participants and
    points whose values make a number to store non-finite (never NaN or inf stored: JSON
    has no such numbers and PostgreSQL refuses them)."""
    with np.errstate(all="ignore"):  # overflow is checked below, where it can be named
        try:
            a = _compute(run, loaded)
            linear = linear_values_of(loaded.table, loaded.groups)  # phases: docs/domain.md §12
            m = moments(linear, loaded.table.standard_uncertainty, loaded.groups)
        except CoreInputError as exc:
            extreme = overflowing_results(loaded.table)
            if extreme.any():
                raise ValidationFailed(_nonfinite_message(loaded, extreme)) from exc
            raise
    bad = nonfinite_points(a, m)
    if bad.any():
        in_bad = bad[loaded.groups.index]
        extreme = overflowing_results(loaded.table) & in_bad
        # at a bad point without an extreme result, the results only overflow together
        named = np.bincount(loaded.groups.index[extreme], minlength=bad.size) > 0
        raise ValidationFailed(_nonfinite_message(loaded, extreme | (in_bad & ~named[
            loaded.groups.index])))  # fmt: skip
    return a, m


def _nonfinite_message(loaded: LoadedRound, rows: np.ndarray, limit: int = 10) -> str:
    t, index = loaded.table, loaded.groups.index
    where = np.flatnonzero(rows)
    named = [
        f"participant {t.lab[i]} at {loaded.points[index[i]]} (sensitivity {t.value[i]:g}, "
        f"U {t.expanded_uncertainty[i]:g})"
        for i in where[:limit]
    ]
    more = f"; and {where.size - limit} more" if where.size > limit else ""
    return (
        "The analysis cannot compute with these results (a value too large or an "
        f"uncertainty too small gives a non-finite number): {'; '.join(named)}{more}. "
        "Correct them and start the run again."
    )


def _compute(run: AnalysisRun, loaded: LoadedRound) -> Analysis:
    comparison = run.comparison
    reference = _reference_code(comparison)
    specs = [point_spec(comparison, p, reference) for p in loaded.points]
    _check_specs(specs, loaded)
    keys = [p.key.measurand for p in loaded.points]
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
    override = np.array([p.sigma_pt_value or np.nan for p in loaded.points], dtype=float)
    try:
        linear = linear_values_of(loaded.table, loaded.groups)
        return sigma_pt_values(linear, loaded.groups, values, spec, override)
    except DegenerateScaleError as exc:
        names = "; ".join(str(loaded.points[g]) for g in exc.groups[:10])
        more = f"; and {len(exc.groups) - 10} more" if len(exc.groups) > 10 else ""
        raise ValidationFailed(
            f"σ_pt cannot be the robust s* at {names}{more}: s* is 0 there (a single result, "
            "or most results identical). Set a σ_pt for these measurement points, or choose "
            "another σ_pt mode, and start the run again."
        ) from exc
