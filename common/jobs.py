"""Liveness of background jobs (analysis runs, raw-data recomputations).

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

from django.conf import settings
from django.db import connection, connections
from django.utils import timezone

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
