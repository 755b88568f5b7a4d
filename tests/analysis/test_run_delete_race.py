"""Deleting a run while one of its chunks writes scores (PostgreSQL, two connections).

``Score.run`` has no database foreign key: a chunk holds its run row FOR KEY SHARE while it
writes, and deleting a run locks the row FOR UPDATE before Django's collector deletes the
scores (``analysis.models.lock_run_before_delete``).  Without that lock, whether the
collector's DELETE of the scores ran after the chunk's commit would depend on the order in
which it deletes the related tables (it waits on the chunk row only if it deletes the
chunks first); with it, every deletion path waits for the chunk before deleting anything.
"""

import threading
import time
from collections.abc import Callable

import pytest
from django.db import connection, connections, transaction

from analysis import services
from analysis.models import (
    AnalysisChunk,
    AnalysisRun,
    AssignedValue,
    Score,
)
from analysis.services import analysis_chunk_execute
from tests.analysis.test_fanout import started

pytestmark = [
    pytest.mark.django_db(transaction=True),
    pytest.mark.skipif(
        connection.vendor != "postgresql", reason="row locks between two connections"
    ),
]


def in_thread(target: Callable[[], object], out: dict, key: str) -> threading.Thread:
    """Run ``target`` on its own database connection; its result or exception in ``out``."""

    def body() -> None:
        try:
            out[key] = target()
        except BaseException as exc:  # reported by the test, not lost in the thread
            out[key] = exc
        finally:
            connections.close_all()

    thread = threading.Thread(target=body, daemon=True)
    thread.start()
    return thread


def wait_for_lock_wait(out: dict, timeout: float = 20) -> str:
    """Until another connection of this database waits for a lock; its statement."""
    deadline = time.monotonic() + timeout
    with connection.cursor() as cur:
        while time.monotonic() < deadline:
            cur.execute("SELECT pg_stat_clear_snapshot()")  # fresh inside a transaction too
            cur.execute(
                "SELECT query FROM pg_stat_activity WHERE datname = current_database() "
                "AND pid <> pg_backend_pid() AND wait_event_type = 'Lock'"
            )
            if row := cur.fetchone():
                return str(row[0])
            time.sleep(0.05)
    raise AssertionError(f"no connection waited for a lock: {out}")


def chunk_paused_before_commit(run: AnalysisRun, monkeypatch, out: dict):
    """Chunk 0 of ``run`` in a thread, stopped after its scores are written (uncommitted)."""
    written, go = threading.Event(), threading.Event()

    def pause() -> int:  # called in _save_chunk after the COPY and the results check
        written.set()
        assert go.wait(30)
        return 0

    monkeypatch.setattr(services, "peak_rss_kb", pause)
    thread = in_thread(lambda: analysis_chunk_execute(run_id=run.pk, index=0), out, "chunk")
    assert written.wait(60), out
    return thread, go


def test_deleting_a_run_while_a_chunk_writes_leaves_no_orphan_scores(demo, settings, monkeypatch):
    run = started(demo, settings, 300, monkeypatch)  # 891 results: 3 chunks
    n0 = AnalysisChunk.objects.get(run=run, index=0).n_results
    out: dict = {}
    chunk, go = chunk_paused_before_commit(run, monkeypatch, out)
    victim = AnalysisRun.objects.filter(pk=run.pk)
    deletion = in_thread(victim.delete, out, "del")
    # the deletion waits on the run row lock, before it deleted anything
    assert "FOR UPDATE" in wait_for_lock_wait(out)
    go.set()
    chunk.join(30)
    deletion.join(30)
    assert out["chunk"] == "running"  # the chunk committed its rows
    assert not isinstance(out["del"], BaseException), out["del"]
    assert not AnalysisRun.objects.filter(pk=run.pk).exists()
    assert not AssignedValue.objects.filter(run_id=run.pk).exists()
    assert not Score.objects.filter(run_id=run.pk).exists()  # no orphans
    assert out["del"][1]["analysis.Score"] == n0  # deleted after the chunk's commit


def test_a_chunk_started_during_a_deletion_writes_nothing(demo, settings, monkeypatch):
    run = started(demo, settings, 300, monkeypatch)
    out: dict = {}
    with transaction.atomic():
        assert AnalysisRun.objects.filter(pk=run.pk).delete()[0] > 0  # not committed yet
        chunk = in_thread(lambda: analysis_chunk_execute(run_id=run.pk, index=0), out, "chunk")
        wait_for_lock_wait(out)  # the chunk waits for the deletion's locks
    chunk.join(60)
    assert out["chunk"] == "missing"  # its claim found the chunk deleted with the run
    assert not Score.objects.filter(run_id=run.pk).exists()
    assert not AssignedValue.objects.filter(run_id=run.pk).exists()
