"""A worker SIGKILLed in the middle of an analysis run: the task it held is queued again
to a new worker, and the run completes with exactly the numbers of an undisturbed run,
without a duplicate row.

Redelivered by Redis after a (here short) visibility timeout, ``acks_late``: the same
task takes its own claim over; fanned out, the lost chunk is redone alone.  With the
production visibility timeout (an hour), the stale-job sweep of Celery beat re-queues
the lost chunk once its heartbeat is stale, within a few sweep intervals."""

import os
import signal
import time
from io import StringIO

import pytest
from django.core.management import call_command
from django.db.models import Count

from analysis.models import AnalysisChunk, AnalysisRun, AssignedValue, Score
from analysis.services import analysis_run_execute, analysis_run_start
from proficiency.models import Comparison
from tests.analysis.test_fanout import stored
from tests.faults.conftest import wait_until

pytestmark = [
    pytest.mark.services,
    pytest.mark.real_worker,
    pytest.mark.django_db(transaction=True),
]

VISIBILITY = 4  # s: the test workers' visibility timeout (production: over 1 h, see settings)
COMPARE = ["axis", "frequency", "device", "bench", "direction"]


@pytest.fixture
def undisturbed(settings):
    """The demo analysed in one task, in this process: the reference numbers."""
    call_command("load_demo", password="demo-password-1", stdout=StringIO())
    demo = Comparison.objects.get(code="IMU-2024-DEMO")
    settings.ANALYSIS_CHUNK_RESULTS = 10**9
    run = AnalysisRun.objects.create(comparison=demo, parameters={"compare": COMPARE})
    assert analysis_run_execute(run_id=run.pk) == "succeeded"
    return run


def kill_and_recover(workers, marker, env: dict[str, str], hang: str) -> AnalysisRun:
    """Start a run on a worker that hangs at ``hang``, SIGKILL it there, start a new worker
    once the message is visible again; the finished run."""
    doomed = workers.start("w0", FAULT_HANG_CHUNK=hang, FAULT_MARKER=str(marker), **env)
    demo = Comparison.objects.get(code="IMU-2024-DEMO")
    run = analysis_run_start(comparison=demo, user=None)
    wait_until(marker.exists, f"the worker to hang in {hang}", workers)
    os.kill(doomed.pid, signal.SIGKILL)
    assert doomed.wait(10) == -signal.SIGKILL
    run.refresh_from_db()
    assert run.status == "running"
    assert (
        not Score.objects.filter(run=run)
        .exclude(result__measurement_point__lt=run_first_point_hung(run, hang))
        .exists()
    )  # the hung transaction was rolled back with the worker
    time.sleep(max(0.0, float(marker.read_text().split()[0]) + VISIBILITY + 0.5 - time.time()))
    workers.start("w1", **env)

    def finished() -> bool:
        run.refresh_from_db()
        return run.status in ("succeeded", "failed")

    wait_until(finished, "the run to finish on the new worker", workers, timeout=90)
    assert run.status == "succeeded", run.error
    return run


def run_first_point_hung(run: AnalysisRun, hang: str) -> int:
    chunks = AnalysisChunk.objects.filter(run=run)
    return (chunks.get(index=int(hang)) if hang != "run" else chunks.get()).first_point_id


def assert_same_numbers_no_duplicates(run: AnalysisRun, undisturbed: AnalysisRun) -> None:
    assert stored(run) == stored(undisturbed)
    scores = Score.objects.filter(run=run)
    assert scores.count() == 891 == scores.values("result_id").distinct().count()
    assigned = AssignedValue.objects.filter(run=run)
    dup = assigned.values("measurement_point_id").annotate(n=Count("id")).filter(n__gt=1)
    assert assigned.count() == AssignedValue.objects.filter(run=undisturbed).count() > 0
    assert not dup.exists()


def test_sigkill_mid_chunk_is_redelivered_and_gives_identical_results(
    workers, undisturbed, tmp_path
):
    env = {"ANALYSIS_CHUNK_RESULTS": "50", "CELERY_VISIBILITY_TIMEOUT": str(VISIBILITY)}
    run = kill_and_recover(workers, tmp_path / "hung", env, hang="3")
    assert (run.chunks_total, run.chunks_done, run.progress) == (18, 18, 100)
    chunks = AnalysisChunk.objects.filter(run=run)
    assert chunks.get(index=3).attempts == 2  # redone once, on the new worker
    assert (
        chunks.filter(done=True).count() == 18 == chunks.filter(done=True, attempts__lte=2).count()
    )
    assert_same_numbers_no_duplicates(run, undisturbed)


def test_sigkill_mid_single_task_run_is_taken_over(workers, undisturbed, tmp_path):
    env = {"ANALYSIS_CHUNK_RESULTS": str(10**9), "CELERY_VISIBILITY_TIMEOUT": str(VISIBILITY)}
    run = kill_and_recover(workers, tmp_path / "hung", env, hang="run")
    assert (run.chunks_total, run.chunks_done, run.progress) == (1, 1, 100)
    # the same task delivered again takes its own claims over: the plan is kept and its
    # one chunk redone
    assert AnalysisChunk.objects.get(run=run).attempts == 2
    assert_same_numbers_no_duplicates(run, undisturbed)


# The sweep's timing in the next tests (production: 30 s, 300 s, 60 s).
HEARTBEAT, STALE, SWEEP = 0.5, 3.0, 1.0
# Chunks of 50 results, and a visibility timeout of an hour (as in production): only the
# sweep can bring a lost chunk back in time.
SWEEP_ENV = {
    "ANALYSIS_CHUNK_RESULTS": "50",
    "CELERY_VISIBILITY_TIMEOUT": "3600",
    "JOB_HEARTBEAT_SECONDS": str(HEARTBEAT),
    "JOB_STALE_SECONDS": str(STALE),
    "JOB_SWEEP_SECONDS": str(SWEEP),
}


def recover_with_sweep(workers, run: AnalysisRun, tmp_path, env: dict[str, str]) -> float:
    """A new worker and beat; the run finished on them, and the seconds from the new
    worker's readiness to the run's end."""
    ready = tmp_path / "ready"
    workers.start("w1", FAULT_READY=str(ready), **env)
    workers.start_beat(tmp_path / "beat-schedule", **env)
    wait_until(ready.exists, "the new worker to be ready", workers)
    t_ready = float(ready.read_text())

    def finished() -> bool:
        run.refresh_from_db()
        return run.status in ("succeeded", "failed")

    wait_until(finished, "the run to finish", workers, timeout=STALE + 30 * SWEEP)
    assert run.status == "succeeded", run.error
    assert run.finished_at is not None
    return run.finished_at.timestamp() - t_ready


def test_sigkill_of_the_worker_main_process_is_recovered_by_the_sweep(
    workers, undisturbed, tmp_path
):
    """The lost chunk waits in Redis' unacked set for the whole visibility timeout (an hour
    here, as in production); the beat sweep sees its heartbeat go stale and queues it
    again, and the run finishes within a few sweep intervals of the new worker's start."""
    env = SWEEP_ENV
    marker = tmp_path / "hung"
    doomed = workers.start("w0", FAULT_HANG_CHUNK="3", FAULT_MARKER=str(marker), **env)
    demo = Comparison.objects.get(code="IMU-2024-DEMO")
    run = analysis_run_start(comparison=demo, user=None)
    wait_until(marker.exists, "the worker to hang in chunk 3", workers)
    lost_claim = AnalysisChunk.objects.get(run=run, index=3).claimed_by
    os.kill(doomed.pid, signal.SIGKILL)  # the solo pool's worker is its main process
    assert doomed.wait(10) == -signal.SIGKILL
    run.refresh_from_db()
    assert (run.status, run.chunks_done) == ("running", 3)  # chunks 0-2, then it hung in 3
    # a coordinator starting a run meanwhile gets the same run, which will finish
    assert analysis_run_start(comparison=demo, user=None).pk == run.pk

    elapsed = recover_with_sweep(workers, run, tmp_path, env)
    # stale by then at the latest, seen by the next sweep, redone with the 14 left: a few
    # sweep intervals, and nothing like the visibility timeout
    assert elapsed < STALE + 10 * SWEEP, elapsed
    assert (run.chunks_total, run.chunks_done, run.progress) == (18, 18, 100)
    chunks = AnalysisChunk.objects.filter(run=run)
    lost = chunks.get(index=3)
    assert lost.attempts == 2 and lost.claimed_by not in ("", lost_claim)  # the sweep's task
    assert chunks.filter(done=True).count() == 18 == chunks.filter(attempts=1).count() + 1
    assert_same_numbers_no_duplicates(run, undisturbed)


def alive(pid: int) -> bool:
    """The process exists and is not a zombie."""
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().rsplit(")", 1)[1].split()[0] != "Z"
    except FileNotFoundError:
        return False


def test_sigkill_of_a_prefork_main_process_ends_the_orphan_and_the_sweep_recovers(
    workers, undisturbed, tmp_path
):
    """A prefork worker's main process SIGKILLed while its child hangs inside chunk 3's
    transaction. An orphan living on would hold the chunk's locks and uncommitted rows,
    and the chunk re-queued by the sweep would wait on them for as long as it lives;
    Celery's prefork pool sets PR_SET_PDEATHSIG(SIGKILL) in its children, so the kernel
    ends the child with its parent and PostgreSQL rolls its transaction back. This test
    holds that promise (and the recovery after it) against a Celery upgrade."""
    env = SWEEP_ENV
    marker = tmp_path / "hung"
    doomed = workers.start("w0", pool="prefork", FAULT_HANG_CHUNK="3", FAULT_MARKER=str(marker),
                           **env)  # fmt: skip
    demo = Comparison.objects.get(code="IMU-2024-DEMO")
    run = analysis_run_start(comparison=demo, user=None)
    wait_until(marker.exists, "the prefork child to hang in chunk 3", workers)
    child = int(marker.read_text().split()[1])
    assert child != doomed.pid and alive(child)
    os.kill(doomed.pid, signal.SIGKILL)  # the main process only: the child is orphaned
    assert doomed.wait(10) == -signal.SIGKILL
    wait_until(lambda: not alive(child), "the orphaned child to end itself", timeout=10 * HEARTBEAT)

    assert recover_with_sweep(workers, run, tmp_path, env) < STALE + 10 * SWEEP
    assert AnalysisChunk.objects.get(run=run, index=3).attempts == 2
    assert_same_numbers_no_duplicates(run, undisturbed)
