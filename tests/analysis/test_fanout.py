"""Fanned-out analysis runs: chunks of measurement points, progress, lost chunks, and the
same stored numbers as the single-task path (eager Celery; SQLite or PostgreSQL)."""

import resource

import numpy as np
import pytest
from django.db import connection

from analysis import outputs, services, tasks
from analysis.models import AnalysisChunk, AnalysisRun, AssignedValue, CompatibilityMatrix, Score
from analysis.services import (
    analysis_chunk_execute,
    analysis_run_execute,
    analysis_run_finish,
    analysis_run_start,
)
from proficiency.models import Comparison

pytestmark = pytest.mark.django_db(transaction=True)


def stored(run):
    """Every stored number of a run, keyed by point / result / matrix (not by row id)."""
    assigned = sorted(
        AssignedValue.objects.filter(run=run).values_list(
            "measurement_point_id", "value", "standard_uncertainty", "method", "sigma_pt",
            "diagnostics",
        )
    )  # fmt: skip
    scores = sorted(
        Score.objects.filter(run=run).values_list(
            "result_id", "d", "d_percent", "en", "zeta", "z", "z_prime", "flag", "z_flag",
            "correlation_applied",
        )
    )  # fmt: skip
    matrices = sorted(
        CompatibilityMatrix.objects.filter(run=run).values_list(
            "factor", "group_key", "group", "levels", "values", "expanded_uncertainties", "en",
            "incompatible_pairs",
        )
    )  # fmt: skip
    return assigned, scores, matrices


def run_with(comparison, settings, chunk_results):
    settings.ANALYSIS_CHUNK_RESULTS = chunk_results
    run = analysis_run_start(comparison=comparison, user=None)  # eager: chord runs inline
    run.refresh_from_db()
    assert run.status == "succeeded", run.error
    return run


@pytest.mark.parametrize(
    ("method", "sigma_mode", "sigma_value"),
    [("nominal", "relative", 1.0), ("algorithm_a", "robust", None),
     ("weighted_mean", "none", None), ("median", "absolute", 4.0)],
)  # fmt: skip
def test_chunked_run_stores_exactly_what_the_single_task_stores(
    demo, settings, method, sigma_mode, sigma_value
):
    Comparison.objects.filter(pk=demo.pk).update(
        assigned_value_method=method, sigma_pt_mode=sigma_mode, sigma_pt_value=sigma_value
    )
    demo.refresh_from_db()
    single = run_with(demo, settings, 10**9)
    chunked = run_with(demo, settings, 100)  # 891 results, 11 per point: 9 chunks
    assert (single.chunks_total, single.chunks_done) == (1, 1)
    assert (chunked.chunks_total, chunked.chunks_done, chunked.progress) == (9, 9, 100)
    one, many = stored(single), stored(chunked)
    assert len(one[0]) == 81 and len(one[1]) == 891 and len(one[2]) > 0
    assert one == many  # every float bit for bit, every flag, every matrix cell
    sizes = list(AnalysisChunk.objects.filter(run=chunked).values_list("n_results", flat=True))
    assert sum(sizes) == 891 and max(sizes) <= 100 + 11 - 1
    assert chunked.peak_rss_kb > 10_000  # a Python process with numpy: tens of MiB at least


def test_per_point_overrides_cross_chunks(demo, settings):
    """Points of one chunk with different methods: each method runs on its own points."""
    points = list(demo.measurement_points.order_by("pk")[:30:3])
    for p in points:
        p.assigned_value_method = "weighted_mean"
        p.sigma_pt_value = 3.5
        p.save()
    single, chunked = run_with(demo, settings, 10**9), run_with(demo, settings, 50)
    assert stored(single) == stored(chunked)
    methods = dict(
        AssignedValue.objects.filter(run=chunked).values_list("measurement_point_id", "method")
    )
    assert {methods[p.pk] for p in points} <= {"weighted_mean", "largest_consistent_subset"}
    sigma = AssignedValue.objects.get(run=chunked, measurement_point=points[0]).sigma_pt
    assert sigma == 3.5


def started(comparison, settings, chunk_results, monkeypatch):
    """A claimed and planned run whose chunks were not sent (``_dispatch`` recorded)."""
    settings.ANALYSIS_CHUNK_RESULTS = chunk_results
    sent = []
    monkeypatch.setattr(
        services, "_dispatch", lambda run_id, todo, q: sent.append((run_id, len(list(todo))))
    )
    finish_sent: list[int] = []  # the final step, sent by the chunk that stores the last one
    monkeypatch.setattr(tasks.analysis_finish_task, "delay", finish_sent.append)
    run = AnalysisRun.objects.create(comparison=comparison, parameters=services._parameters(
        comparison))  # fmt: skip
    assert analysis_run_execute(run_id=run.pk) == "running"
    assert sent == [(run.pk, AnalysisRun.objects.get(pk=run.pk).chunks_total)]
    run = AnalysisRun.objects.get(pk=run.pk)
    run.finish_sent = finish_sent  # type: ignore[attr-defined]  # the test's record, on the run
    return run


class WorkerLost(BaseException):
    """Stands for SIGKILL: not an Exception, so nothing in the task catches it."""


def test_a_lost_chunk_is_redone_alone_and_never_duplicated(demo, settings, monkeypatch):
    reference = stored(run_with(demo, settings, 10**9))
    run = started(demo, settings, 300, monkeypatch)  # 891 results: 3 chunks
    assert (run.chunks_total, run.chunks_done, run.progress) == (3, 0, 5)
    assert analysis_chunk_execute(run_id=run.pk, index=0) == "running"
    run.refresh_from_db()
    assert (run.chunks_done, run.progress) == (1, 5 + 90 // 3)

    real_write = outputs.write_scores

    def dies_mid_write(run_id, loaded, a):
        real_write(run_id, loaded, a)  # the rows are written, then the worker is killed
        raise WorkerLost

    monkeypatch.setattr(services, "write_scores", dies_mid_write)
    with pytest.raises(WorkerLost):
        analysis_chunk_execute(run_id=run.pk, index=1, delivery="task-of-chunk-1")
    monkeypatch.setattr(services, "write_scores", real_write)
    chunk1 = AnalysisChunk.objects.get(run=run, index=1)
    assert not chunk1.done and chunk1.attempts == 1
    first_ids = set(Score.objects.filter(run=run).values_list("pk", flat=True))
    assert len(first_ids) == AnalysisChunk.objects.get(run=run, index=0).n_results  # rolled back

    assert analysis_chunk_execute(run_id=run.pk, index=2) == "running"
    # the same task delivered again (its worker lost): it takes its own claim over
    assert analysis_chunk_execute(run_id=run.pk, index=1, delivery="task-of-chunk-1") == "running"
    assert analysis_chunk_execute(run_id=run.pk, index=1, delivery="task-of-chunk-1") == "running"
    attempts = dict(AnalysisChunk.objects.filter(run=run).values_list("index", "attempts"))
    assert attempts == {0: 1, 1: 2, 2: 1}
    assert first_ids <= set(Score.objects.filter(run=run).values_list("pk", flat=True))
    run.refresh_from_db()
    assert (run.status, run.chunks_done, run.progress) == ("running", 3, 95)
    assert run.finish_sent == [run.pk]  # once, by the redelivered chunk 1 (the last stored)
    assert analysis_run_finish(run_id=run.pk) == "succeeded"
    assert analysis_run_finish(run_id=run.pk) == "succeeded"  # the body delivered twice
    assert stored(run) == reference
    assert Score.objects.filter(run=run).count() == 891


def test_outputs_without_the_done_mark_are_replaced(demo, settings, monkeypatch):
    run = started(demo, settings, 300, monkeypatch)
    for i in range(3):
        analysis_chunk_execute(run_id=run.pk, index=i)
    before = stored(run)
    AnalysisChunk.objects.filter(run=run, index=1).update(done=False, token="")
    AnalysisRun.objects.filter(pk=run.pk).update(chunks_done=2)
    assert analysis_chunk_execute(run_id=run.pk, index=1) == "running"
    assert Score.objects.filter(run=run).count() == 891
    assert AssignedValue.objects.filter(run=run).count() == 81
    assert analysis_run_finish(run_id=run.pk) == "succeeded"
    assert stored(run)[:2] == before[:2]


def test_finish_refuses_while_a_chunk_is_missing(demo, settings, monkeypatch):
    run = started(demo, settings, 300, monkeypatch)
    analysis_chunk_execute(run_id=run.pk, index=0)
    analysis_chunk_execute(run_id=run.pk, index=2)
    assert analysis_run_finish(run_id=run.pk) == "failed"
    run.refresh_from_db()
    assert run.error == "Chunks [1] of this run were not stored; start it again."
    assert analysis_chunk_execute(run_id=run.pk, index=1) == "failed"  # too late: no-op
    assert not AnalysisChunk.objects.get(run=run, index=1).done


def test_a_failing_chunk_fails_the_run_and_the_rest_stop(demo, settings, monkeypatch):
    run = started(demo, settings, 300, monkeypatch)
    real = services._compute

    def boom_on_second(run_, loaded):
        if loaded.point_ids[0] == AnalysisChunk.objects.get(run=run, index=1).first_point_id:
            raise RuntimeError("disk full")
        return real(run_, loaded)

    monkeypatch.setattr(services, "_compute", boom_on_second)
    assert [analysis_chunk_execute(run_id=run.pk, index=i) for i in range(3)] == [
        "running", "failed", "failed"]  # fmt: skip
    run.refresh_from_db()
    assert (run.status, run.error) == ("failed", "RuntimeError: disk full")
    assert analysis_run_finish(run_id=run.pk) == "failed"
    assert not CompatibilityMatrix.objects.filter(run=run).exists()


def test_chunks_split_whole_points_by_result_count(demo, settings, monkeypatch):
    run = started(demo, settings, 200, monkeypatch)
    chunks = list(AnalysisChunk.objects.filter(run=run).order_by("index"))
    point_ids = np.array(sorted(demo.measurement_points.values_list("pk", flat=True)))
    # 11 accepted results at every point: a new chunk starts where 200 is crossed
    starts = [int(point_ids[i]) for i in range(0, 81) if (11 * i) // 200 != (11 * (i - 1)) // 200]
    assert [c.first_point_id for c in chunks] == starts
    assert [c.last_point_id for c in chunks[:-1]] == [int(point_ids[
        np.searchsorted(point_ids, s) - 1]) for s in starts[1:]]  # fmt: skip
    assert chunks[-1].last_point_id == int(point_ids[-1])
    assert [c.n_results for c in chunks] == [209, 198, 198, 198, 88]


def test_a_result_deleted_while_the_run_works_fails_it(demo, settings, monkeypatch):
    """Score.result has no database foreign key: each chunk checks its results exist."""
    run = started(demo, settings, 300, monkeypatch)
    analysis_chunk_execute(run_id=run.pk, index=0)
    real = services._compute

    def deleted_meanwhile(run_, loaded):
        with connection.cursor() as cur:  # behind the ORM's back: no cascade
            cur.execute("DELETE FROM labs_result WHERE id = %s", [int(loaded.result_id[5])])
        return real(run_, loaded)

    monkeypatch.setattr(services, "_compute", deleted_meanwhile)
    assert analysis_chunk_execute(run_id=run.pk, index=1) == "failed"
    run.refresh_from_db()
    assert run.error == (
        "Results of this comparison were deleted while the analysis ran; start it again."
    )
    chunk1 = AnalysisChunk.objects.get(run=run, index=1)
    assert not chunk1.done  # its rows were rolled back
    assert AnalysisChunk.objects.get(run=run, index=0).done
    assert not Score.objects.filter(run=run).exists()  # a failed run keeps no outputs
    assert not AssignedValue.objects.filter(run=run).exists()


def test_deleting_a_result_through_the_orm_deletes_its_scores(demo, settings):
    from labs.models import Result

    run = run_with(demo, settings, 300)
    first = Score.objects.filter(run=run).order_by("pk").first()
    assert first is not None
    victim = first.result
    Result.objects.filter(pk=victim.pk).delete()
    assert Score.objects.filter(run=run).count() == 890


def test_peak_rss_is_this_process_high_water_mark():
    def rss_kb() -> int:
        with open("/proc/self/statm") as f:  # resident pages
            return int(f.read().split()[1]) * (resource.getpagesize() // 1024)

    before = rss_kb()
    block = np.ones(25_000_000)  # 200 MB, touched
    peak = services.peak_rss_kb()
    del block
    assert peak >= before + 190_000
    assert peak < 4 * 2**20  # KiB: the test process, not the machine


def _flush_table_statistics() -> None:
    """Make this connection's pending row counts visible in pg_stat_user_tables (they are
    flushed when the backend goes idle, at most once a second unless forced)."""
    with connection.cursor() as cur:
        cur.execute("SELECT pg_stat_force_next_flush()")
    with connection.cursor() as cur:
        cur.execute("SELECT 1")


@pytest.mark.skipif(connection.vendor != "postgresql", reason="planner statistics: PostgreSQL")
def test_planner_stats_refresh_analyses_changed_tables_once(demo):
    from analysis.bulk import planner_stats_refresh

    _flush_table_statistics()
    assert "labs_result" in planner_stats_refresh()  # the demo's results were just loaded
    _flush_table_statistics()
    assert planner_stats_refresh() == []


@pytest.mark.skipif(connection.vendor != "postgresql", reason="planner statistics: PostgreSQL")
def test_planning_a_run_refreshes_the_statistics_of_a_freshly_loaded_round(demo, settings):
    """Right after a bulk load the round's tables may have no planner statistics (autovacuum
    off, or not run yet): planning the run analyses them before the chunks read the round."""
    from analysis.bulk import planner_stats_refresh

    _flush_table_statistics()
    run_with(demo, settings, 200)
    _flush_table_statistics()
    assert "labs_result" not in planner_stats_refresh()
