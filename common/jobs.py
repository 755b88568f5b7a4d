"""Liveness of background jobs (analysis runs, raw-data recomputations, report batches).

A task working on a job row writes a heartbeat every ``JOB_HEARTBEAT_SECONDS`` from a
thread of its own (``heartbeat``), so that a slow computation or a long COPY still shows
signs of life.  A job whose heartbeat is older than ``JOB_STALE_SECONDS`` is taken to be
lost with its worker: the sweep run by Celery beat (``analysis.tasks.jobs_sweep_task``)
re-queues it, and a new task may take over its claim.  The threshold is at least three
heartbeats, so a live task is never taken over.

A heartbeat is a promise that the task is alive *and will end*, so it also stops (and the
job becomes stale) when either no longer holds: once the task has outlived the hard time
limit (``CELERY_TASK_TIME_LIMIT``; the solo pool does not enforce it), or once the worker's
main process has gone (a prefork child orphaned by a SIGKILL of its parent has nobody left
to enforce the limit or to acknowledge its message). A task that goes on after its
heartbeat stopped stores nothing: the sweep's new claim has replaced its token.
(On Linux a prefork child does not outlive its parent at all: Celery's prefork pool sets
``PR_SET_PDEATHSIG`` to SIGKILL in each child, so the kernel ends it with its parent, its
database connection drops and PostgreSQL rolls back the chunk it was writing — the fault
test ``test_sigkill_of_a_prefork_main_process...`` checks this.)

Heartbeats are written on PostgreSQL only: the embedded quick start (SQLite) runs tasks
eagerly in the web process, where no worker can be lost, and SQLite would serialise the
heartbeat's writes with the task's own.
"""

from __future__ import annotations

import contextlib
import datetime as dt
import logging
import os
import threading
import time
from collections.abc import Callable, Iterator
from typing import Any

from django.conf import settings
from django.db import connection, connections
from django.db.models import Model, Q, QuerySet
from django.utils import timezone
from kombu.exceptions import OperationalError

log = logging.getLogger(__name__)


def stale_before() -> dt.datetime:
    """A job whose last heartbeat is older than this was lost with its worker."""
    return timezone.now() - dt.timedelta(seconds=float(settings.JOB_STALE_SECONDS))


@contextlib.contextmanager
def heartbeat(beat: Callable[[], object], what: str = "job") -> Iterator[None]:
    """Call ``beat()`` every ``JOB_HEARTBEAT_SECONDS`` in a thread while the block runs.

    ``beat`` runs on the thread's own database connection (closed when the block ends)
    and must never wait for a lock (``SKIP LOCKED``): a row locked by the task itself is
    a row being written, which is a sign of life too.  Errors are logged, never raised.
    """
    every = float(settings.JOB_HEARTBEAT_SECONDS)
    if every <= 0 or connection.vendor != "postgresql":
        yield
        return
    stop = threading.Event()
    parent = os.getppid()
    deadline = time.monotonic() + float(settings.CELERY_TASK_TIME_LIMIT)

    def loop() -> None:
        try:
            while not stop.wait(every):
                if os.getppid() != parent or time.monotonic() > deadline:
                    log.warning("heartbeat of %s stopped: worker gone or time limit passed", what)
                    return
                try:
                    beat()
                except Exception:  # a lost database connection: the next beat tries again
                    log.warning("heartbeat of %s failed", what, exc_info=True)
        finally:
            connections.close_all()  # this thread's connections only

    thread = threading.Thread(target=loop, name=f"heartbeat {what}", daemon=True)
    thread.start()
    try:
        yield
    finally:
        stop.set()
        thread.join(timeout=every + 30)


# --- the claim protocol shared by every job row ---------------------------------------------
# A job row has ``status`` (pending → running → succeeded | failed), ``heartbeat_at`` and
# ``claimed_by`` (the Celery id of the task holding it).  Analysis runs and their chunks,
# raw recomputations and report batches are claimed, kept alive and re-queued by these
# functions only (docs/architecture.md §3, docs/lifecycles.md §3, §4 and §5).


def silent(since: str | None = None) -> Q:
    """Rows whose last heartbeat (or, before the first, the time field ``since``) is stale."""
    stale = stale_before()
    quiet = Q(heartbeat_at__lt=stale)
    return quiet | Q(heartbeat_at__isnull=True, **{f"{since}__lt": stale}) if since else quiet


def redelivered(delivery: str) -> Q:
    """Rows this very task had claimed (``delivery``, its Celery id, redelivered after its
    worker was lost); none for a task without an id."""
    return Q(claimed_by=delivery) if delivery else Q(pk__in=[])


def claim(
    rows: QuerySet[Any],
    *,
    delivery: str,
    fresh: dict[str, Any],
    takeover: dict[str, Any],
    since: str = "started_at",
) -> bool:
    """pending → running with ``fresh`` (plus the heartbeat and ``claimed_by``); or take
    over a running row that is silent or was this task's own, writing ``takeover``.  One
    conditional UPDATE each, so two workers never hold the same row."""
    mine = {"heartbeat_at": timezone.now(), "claimed_by": delivery}
    if rows.filter(status="pending").update(**fresh, **mine):
        return True
    lost = silent(since) | redelivered(delivery)
    return bool(rows.filter(lost, status="running").update(**takeover, **mine))


def beat(model: type[Model], row_id: int, *, lock: str = "NO KEY UPDATE", **where: Any) -> None:
    """The row's heartbeat while ``where`` still holds (its claim); skipped, never waited
    for, while the row is locked (by its own task storing outputs, or a cancellation)."""
    table = connection.ops.quote_name(model._meta.db_table)
    conditions = "".join(f" AND {connection.ops.quote_name(k)} = %s" for k in where)
    with connection.cursor() as cur:
        cur.execute(
            f"UPDATE {table} SET heartbeat_at = %s WHERE id = (SELECT id FROM {table} "
            f"WHERE id = %s{conditions} FOR {lock} SKIP LOCKED)",
            [timezone.now(), row_id, *where.values()],
        )


def lease(rows: QuerySet[Any], *, pk: int, status: str, heartbeat_at: Any, **fields: Any) -> bool:
    """Move a silent row's heartbeat to now (and write ``fields``) unless another sweep or
    a task did since it was read: the sweep's guard against sending a task twice."""
    return bool(
        rows.filter(pk=pk, status=status, heartbeat_at=heartbeat_at).update(
            heartbeat_at=timezone.now(), **fields
        )
    )


def send(
    task: Any,
    args: tuple[Any, ...],
    *,
    task_id: str | None = None,
    queue: str | None = None,
    what: str,
    on_unreachable: Callable[[], object] | None = None,
) -> bool:
    """Send ``task`` with ``args`` (under ``task_id``, to ``queue``, when given): whether it
    was sent.  The one place where the broker being unreachable (kombu's
    ``OperationalError``, or the socket's ``OSError``) is caught: it is logged with
    ``what`` (the job the task is for), ``on_unreachable`` runs (the caller's fallback, e.g.
    failing a new analysis run) and False is returned; the job's row, or the published
    comparison, is what a sweep later sends again.  Any other error is raised."""
    options = {name: value for name, value in (("task_id", task_id), ("queue", queue)) if value}
    try:  # delay() with nothing to set: what these callers always called (and tests stub)
        task.apply_async(args, **options) if options else task.delay(*args)
    except (OperationalError, OSError) as exc:
        name = getattr(task, "name", task)
        log.error("%s: %s not queued, broker unreachable: %s", what, name, exc)
        if on_unreachable is not None:
            on_unreachable()
        return False
    return True
