"""An analysis run on a real Celery worker process, real broker, real PostgreSQL.

Runs when CELERY_BROKER_URL (Redis or RabbitMQ) and a PostgreSQL DATABASE_URL are set,
as in CI; skipped on the embedded quick start (SQLite, eager)."""

import os
import subprocess
import sys
import time
import uuid
from io import StringIO
from pathlib import Path

import pytest
from django.core.management import call_command
from django.db import connection

from analysis.models import AnalysisRun, Score
from analysis.services import analysis_run_start
from proficiency.models import Comparison

BROKER = os.environ.get("CELERY_BROKER_URL", "")
DATABASE_URL = os.environ.get("DATABASE_URL", "")
ROOT = Path(__file__).resolve().parents[2]

pytestmark = [
    pytest.mark.services,
    pytest.mark.real_worker,
    pytest.mark.django_db(transaction=True),
    pytest.mark.skipif(
        not (BROKER and DATABASE_URL.startswith("postgres")),
        reason="needs CELERY_BROKER_URL and a PostgreSQL DATABASE_URL",
    ),
]


@pytest.fixture
def worker():
    """A worker on its own queue, connected to this test's database."""
    from proficiency.celery import app

    queue = f"test-{uuid.uuid4().hex[:8]}"
    test_db_url = DATABASE_URL.rsplit("/", 1)[0] + "/" + connection.settings_dict["NAME"]
    env = os.environ | {"DATABASE_URL": test_db_url, "CELERY_BROKER_URL": BROKER}
    proc = subprocess.Popen(
        [sys.executable, "-m", "celery", "-A", "proficiency", "worker", "-P", "solo",
         "-Q", queue, "--loglevel=WARNING", "--without-heartbeat", "--without-gossip",
         "--without-mingle"],
        cwd=ROOT, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
    )  # fmt: skip
    old = (app.conf.task_always_eager, app.conf.task_default_queue)
    app.conf.task_always_eager, app.conf.task_default_queue = False, queue
    yield proc
    app.conf.task_always_eager, app.conf.task_default_queue = old
    proc.terminate()
    try:
        proc.wait(timeout=20)
    except subprocess.TimeoutExpired:
        proc.kill()


def wait_for(run: AnalysisRun, proc, timeout: float = 90.0) -> AnalysisRun:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        run.refresh_from_db()
        if run.status in ("succeeded", "failed"):
            return run
        if proc.poll() is not None:
            pytest.fail(f"worker exited: {proc.stdout.read()}")
        time.sleep(0.25)
    pytest.fail(f"run still {run.status} after {timeout} s")


def test_run_on_a_real_worker(worker):
    call_command("load_demo", password="demo-password-1", stdout=StringIO())
    demo = Comparison.objects.get(code="IMU-2024-DEMO")
    run = analysis_run_start(comparison=demo, user=None)
    assert run.status == "pending"
    run = wait_for(run, worker)
    assert run.status == "succeeded", run.error
    assert run.progress == 100
    assert Score.objects.filter(run=run).count() == 891
    # a second run supersedes the first; both stay
    second = wait_for(analysis_run_start(comparison=demo, user=None), worker)
    assert second.status == "succeeded"
    assert sorted(Score.objects.filter(run=run).values_list("result_id", "en")) == sorted(
        Score.objects.filter(run=second).values_list("result_id", "en")
    )
