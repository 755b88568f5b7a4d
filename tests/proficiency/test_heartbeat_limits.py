"""A heartbeat stops when its task can no longer be trusted to end: past the hard time
limit, or when the worker's main process is gone (an orphaned prefork child). The job
then goes stale and the sweep takes it over (tests/analysis/test_sweep.py)."""

from __future__ import annotations

import os
import threading
import time

import pytest

from common import jobs

pytestmark = pytest.mark.django_db(transaction=True)


@pytest.fixture(autouse=True)
def _postgresql_only(needs_postgres):
    """Heartbeats are written on PostgreSQL only (jobs.heartbeat)."""


def _beats_during(seconds: float) -> int:
    count = []
    with jobs.heartbeat(lambda: count.append(1), "test"):
        time.sleep(seconds)
    return len(count)


def test_beats_while_the_task_runs(settings):
    settings.JOB_HEARTBEAT_SECONDS = 0.05
    settings.CELERY_TASK_TIME_LIMIT = 60
    assert _beats_during(0.6) >= 5


def test_no_beat_after_the_hard_time_limit(settings):
    settings.JOB_HEARTBEAT_SECONDS = 0.05
    settings.CELERY_TASK_TIME_LIMIT = 0.2
    beats = _beats_during(0.8)
    assert 1 <= beats <= 5  # about 0.2 / 0.05, never the 16 of the whole block


def test_no_beat_once_the_parent_process_is_gone(settings, monkeypatch):
    settings.JOB_HEARTBEAT_SECONDS = 0.05
    settings.CELERY_TASK_TIME_LIMIT = 60
    parent, orphaned = os.getppid(), threading.Event()
    monkeypatch.setattr(jobs.os, "getppid", lambda: 1 if orphaned.is_set() else parent)
    count = []
    with jobs.heartbeat(lambda: count.append(1), "test"):
        time.sleep(0.3)
        before = len(count)
        orphaned.set()  # the worker's main process was killed: init adopts the child
        time.sleep(0.5)
    assert before >= 3
    assert len(count) <= before + 1
