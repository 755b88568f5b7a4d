"""The stale-job sweep and the claim protocol of analysis runs (eager Celery, PostgreSQL:
heartbeats and SKIP LOCKED are PostgreSQL's).

A chunk whose heartbeat went stale is queued again and redone once; a live one, slow or
in the middle of storing, is never taken over; a chunk that finishes while it is being
re-queued is stored once; a run whose task was lost before or after planning, or whose
final step was lost, is completed.  Every sweep is idempotent."""

import datetime as dt
import threading
import time

import pytest
from django.db import connection
from django.utils import timezone

from analysis import services
from analysis.models import AnalysisChunk, AnalysisRun, Score
from analysis.services import analysis_chunk_execute, analysis_run_execute, analysis_sweep
from tests.analysis.test_fanout import run_with, started, stored
from tests.analysis.test_run_delete_race import chunk_paused_before_commit

pytestmark = [
    pytest.mark.django_db(transaction=True),
    pytest.mark.skipif(connection.vendor != "postgresql", reason="heartbeats: PostgreSQL"),
]
NOTHING = {"runs": 0, "chunks": 0, "finish": 0}


@pytest.fixture
def reference(demo, settings):
    return stored(run_with(demo, settings, 10**9))


def long_ago() -> dt.datetime:
    return timezone.now() - dt.timedelta(hours=2)


def claim_then_lose(run: AnalysisRun, index: int) -> AnalysisChunk:
    """Chunk ``index`` claimed by a task whose worker died before it stored anything."""
    token = services._claim_chunk(AnalysisChunk.objects.get(run=run, index=index).pk, "dead")
    assert token
    AnalysisChunk.objects.filter(run=run, index=index).update(heartbeat_at=long_ago())
    return AnalysisChunk.objects.get(run=run, index=index)


def finish(run: AnalysisRun) -> AnalysisRun:
    """The other chunks, run by live workers (the last one queues the final step)."""
    for c in AnalysisChunk.objects.filter(run=run, done=False, token=""):
        analysis_chunk_execute(run_id=run.pk, index=c.index, delivery=f"live-{c.index}")
    run.refresh_from_db()
    return run


def test_a_stale_chunk_is_queued_again_and_redone_once(demo, settings, monkeypatch, reference):
    run = started(demo, settings, 300, monkeypatch)  # 3 chunks
    monkeypatch.undo()  # the sweep's tasks run (eagerly)
    claim_then_lose(run, 1)
    assert analysis_sweep() == NOTHING | {"chunks": 1}  # chunk 1 redone: 1 of 3 stored
    lost = AnalysisChunk.objects.get(run=run, index=1)
    assert lost.done and lost.attempts == 2 and lost.claimed_by not in ("", "dead")
    assert analysis_sweep() == NOTHING  # idempotent: nothing more to do
    run = finish(run)
    assert (run.status, run.chunks_done) == ("succeeded", 3)
    assert stored(run) == reference
    # the lost task's own redelivery, an hour later (visibility timeout): a no-op
    assert analysis_chunk_execute(run_id=run.pk, index=1, delivery="dead") == "succeeded"
    assert AnalysisChunk.objects.get(run=run, index=1).attempts == 2


def test_a_live_chunk_is_never_taken_over(demo, settings, monkeypatch):
    run = started(demo, settings, 300, monkeypatch)
    chunk = AnalysisChunk.objects.get(run=run, index=0)
    assert services._claim_chunk(chunk.pk, "alive")  # heartbeat: now
    assert analysis_sweep() == NOTHING
    # another delivery (a duplicate message) finds it held and does nothing
    assert analysis_chunk_execute(run_id=run.pk, index=0, delivery="other") == "running"
    chunk.refresh_from_db()
    assert (chunk.attempts, chunk.claimed_by, chunk.done) == (1, "alive", False)
    assert not Score.objects.filter(run=run).exists()


def test_a_slow_chunk_keeps_its_claim_by_its_heartbeat(demo, settings, monkeypatch):
    settings.JOB_HEARTBEAT_SECONDS, settings.JOB_STALE_SECONDS = 0.1, 0.6
    run = started(demo, settings, 300, monkeypatch)
    real, sweeps = services._compute_checked, []

    def slow(run_, loaded):  # 2.5 stale periods of work, swept in the middle of it
        time.sleep(1.2)
        sweeps.append(analysis_sweep())
        time.sleep(0.3)
        return real(run_, loaded)

    monkeypatch.setattr(services, "_compute_checked", slow)
    assert analysis_chunk_execute(run_id=run.pk, index=0, delivery="slow") == "running"
    assert sweeps == [NOTHING]
    chunk = AnalysisChunk.objects.get(run=run, index=0)
    assert (chunk.done, chunk.attempts, chunk.claimed_by) == (True, 1, "slow")


def test_a_chunk_being_stored_is_skipped_by_the_sweep(demo, settings, monkeypatch):
    """Its row is locked while it stores: SKIP LOCKED, even with a stale heartbeat."""
    settings.JOB_HEARTBEAT_SECONDS, settings.JOB_STALE_SECONDS = 0.05, 0.3
    run = started(demo, settings, 300, monkeypatch)
    out: dict = {}
    thread, go = chunk_paused_before_commit(run, monkeypatch, out)
    time.sleep(0.5)  # the chunk's heartbeat is stale now (skipped while its row is locked)
    chunk = AnalysisChunk.objects.get(run=run, index=0)  # not locked for a plain read
    assert chunk.heartbeat_at is not None
    assert chunk.heartbeat_at < timezone.now() - dt.timedelta(seconds=0.3)
    run.refresh_from_db()  # the run's heartbeat goes on
    assert run.heartbeat_at > timezone.now() - dt.timedelta(seconds=0.3)
    assert analysis_sweep() == NOTHING
    go.set()
    thread.join(30)
    assert out["chunk"] == "running"
    chunk = AnalysisChunk.objects.get(run=run, index=0)
    assert chunk.done and chunk.attempts == 1
    assert Score.objects.filter(run=run).count() == chunk.n_results


def test_a_chunk_finishing_while_re_queued_is_stored_once(demo, settings, monkeypatch, reference):
    """A worker taken for lost (no heartbeat for a while) comes back and stores: its claim
    was dropped and redone by the sweep's task, so its own outputs are discarded."""
    run = started(demo, settings, 300, monkeypatch)
    real = services._compute_checked
    calls = []

    def stalls_then_swept(run_, loaded):
        calls.append(1)
        if len(calls) == 1:  # the first task: silent long enough to be taken for lost
            AnalysisChunk.objects.filter(run=run, index=1).update(heartbeat_at=long_ago())
            assert analysis_sweep()["chunks"] == 1  # redone meanwhile (eager), stored
        return real(run_, loaded)

    monkeypatch.setattr(services, "_compute_checked", stalls_then_swept)
    monkeypatch.setattr("analysis.tasks.analysis_finish_task.delay", lambda run_id: None)
    assert analysis_chunk_execute(run_id=run.pk, index=1, delivery="slow") == "running"
    chunk = AnalysisChunk.objects.get(run=run, index=1)
    assert chunk.done and chunk.attempts == 2 and chunk.claimed_by != "slow"
    run.refresh_from_db()
    assert run.chunks_done == 1  # counted once
    assert Score.objects.filter(run=run).count() == chunk.n_results
    monkeypatch.undo()
    run = finish(run)
    assert (run.status, run.chunks_done) == ("succeeded", 3)
    assert stored(run) == reference


def test_a_run_lost_before_planning_is_taken_over(demo, settings, reference):
    settings.ANALYSIS_CHUNK_RESULTS = 300
    run = AnalysisRun.objects.create(comparison=demo, parameters=services._parameters(demo))
    assert services._claim(run.pk, "dead")  # claimed, then its worker died
    assert analysis_run_execute(run_id=run.pk, delivery="someone-else") == "running"  # held
    assert analysis_sweep() == NOTHING
    AnalysisRun.objects.filter(pk=run.pk).update(heartbeat_at=long_ago())
    assert analysis_sweep() == NOTHING | {"runs": 1}  # the run task again, eagerly
    run.refresh_from_db()
    assert (run.status, run.chunks_done) == ("succeeded", 3)
    assert run.claimed_by not in ("", "dead")
    assert stored(run) == reference
    assert analysis_sweep() == NOTHING


def test_a_pending_run_whose_message_was_lost_is_sent_again(demo, settings, reference):
    settings.ANALYSIS_CHUNK_RESULTS = 10**9
    run = AnalysisRun.objects.create(
        comparison=demo, parameters=services._parameters(demo), heartbeat_at=long_ago()
    )
    assert analysis_sweep() == NOTHING | {"runs": 1}
    run.refresh_from_db()
    assert run.status == "succeeded" and stored(run) == reference


def test_a_lost_final_step_is_sent_again(demo, settings, monkeypatch, reference):
    run = started(demo, settings, 300, monkeypatch)
    for i in range(3):
        analysis_chunk_execute(run_id=run.pk, index=i)
    assert run.finish_sent == [run.pk]  # sent, and lost
    monkeypatch.undo()
    assert analysis_sweep() == NOTHING  # not silent yet: the last chunk was just stored
    AnalysisRun.objects.filter(pk=run.pk).update(heartbeat_at=long_ago())
    assert analysis_sweep() == NOTHING | {"finish": 1}
    run.refresh_from_db()
    assert run.status == "succeeded" and stored(run) == reference


def test_a_run_lost_after_planning_gets_its_unclaimed_chunks_sent(
    demo, settings, monkeypatch, reference
):
    """The run task died between planning and sending the chunks."""
    run = started(demo, settings, 300, monkeypatch)
    monkeypatch.undo()
    AnalysisRun.objects.filter(pk=run.pk).update(heartbeat_at=long_ago())
    assert analysis_sweep() == NOTHING | {"chunks": 3}
    run.refresh_from_db()
    assert (run.status, run.chunks_done) == ("succeeded", 3)
    assert set(AnalysisChunk.objects.filter(run=run).values_list("attempts", flat=True)) == {1}
    assert stored(run) == reference


def test_two_sweeps_at_once_send_each_task_once(demo, settings, monkeypatch):
    run = started(demo, settings, 300, monkeypatch)
    sent = []

    def enqueue(task, *a, **kw):
        sent.append(a)
        return True

    monkeypatch.setattr(services, "_enqueue", enqueue)
    claim_then_lose(run, 0)
    AnalysisRun.objects.filter(pk=run.pk).update(heartbeat_at=long_ago())
    barrier, results = threading.Barrier(2), []

    def sweep() -> None:
        barrier.wait()
        results.append(analysis_sweep())
        from django.db import connections

        connections.close_all()

    threads = [threading.Thread(target=sweep) for _ in range(2)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(30)
    assert sorted(sent) == [(run.pk, 0), (run.pk, 1), (run.pk, 2)]  # each chunk once
    assert sum(r["chunks"] for r in results) == 3
