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


def start_worker(queue: str, name: str, **env_extra: str) -> subprocess.Popen:
    test_db_url = DATABASE_URL.rsplit("/", 1)[0] + "/" + connection.settings_dict["NAME"]
    env = os.environ | {"DATABASE_URL": test_db_url, "CELERY_BROKER_URL": BROKER} | env_extra
    return subprocess.Popen(
        [sys.executable, "-m", "celery", "-A", "config", "worker", "-P", "solo",
         "-Q", queue, "-n", f"{name}@%h", "--loglevel=WARNING", "--without-heartbeat",
         "--without-gossip", "--without-mingle"],
        cwd=ROOT, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
    )  # fmt: skip


@pytest.fixture
def workers():
    """Start worker processes on one fresh queue, connected to this test's database."""
    from config.celery import app

    queue = f"test-{uuid.uuid4().hex[:8]}"
    procs: list[subprocess.Popen] = []
    old = (app.conf.task_always_eager, app.conf.task_default_queue)
    app.conf.task_always_eager, app.conf.task_default_queue = False, queue

    def start(n: int = 1, **env_extra: str) -> list[subprocess.Popen]:
        procs.extend(start_worker(queue, f"w{i}-{queue}", **env_extra) for i in range(n))
        return procs

    yield start
    app.conf.task_always_eager, app.conf.task_default_queue = old
    for proc in procs:
        proc.terminate()
    for proc in procs:
        try:
            proc.wait(timeout=20)
        except subprocess.TimeoutExpired:
            proc.kill()


@pytest.fixture
def worker(workers):
    return workers(1)[0]


def wait_for(run: AnalysisRun, procs, timeout: float = 90.0) -> AnalysisRun:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        run.refresh_from_db()
        if run.status in ("succeeded", "failed"):
            return run
        for proc in procs if isinstance(procs, list) else [procs]:
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


def test_fanned_out_run_on_two_workers_equals_the_single_task(workers, settings):
    """18 chunks of ~50 results on two worker processes, then the chord's final step;
    every stored number equals the single-task path's (run here, in-process)."""
    from django_celery_results.models import TaskResult

    from analysis.models import AnalysisChunk
    from analysis.services import analysis_run_execute
    from tests.analysis.test_fanout import stored

    call_command("load_demo", password="demo-password-1", stdout=StringIO())
    demo = Comparison.objects.get(code="IMU-2024-DEMO")
    settings.ANALYSIS_CHUNK_RESULTS = 10**9
    single = AnalysisRun.objects.create(comparison=demo, parameters={"compare": [
        "axis", "frequency", "device", "bench", "direction"]})  # fmt: skip
    assert analysis_run_execute(run_id=single.pk) == "succeeded"

    procs = workers(2, ANALYSIS_CHUNK_RESULTS="50")
    run = wait_for(analysis_run_start(comparison=demo, user=None), procs)
    assert run.status == "succeeded", run.error
    assert (run.chunks_total, run.chunks_done, run.progress, run.stage) == (18, 18, 100, "done")
    assert AnalysisChunk.objects.filter(run=run, done=True, attempts=1).count() == 18
    assert (
        run.peak_rss_kb is not None and 30_000 < run.peak_rss_kb < 1_000_000
    )  # KiB: a worker with numpy, under 1 GB
    assert stored(run) == stored(single)
    chunk_workers = TaskResult.objects.filter(task_name="analysis.tasks.analysis_chunk_task")
    hosts = {w.split("@")[0].split("-")[0] for w in chunk_workers.values_list("worker", flat=True)}
    # Both processes usually take chunks, but one may take them all when the other starts
    # late (prefetch); the point here is that the stored values equal the single task's.
    assert hosts and hosts <= {"w0", "w1"}
