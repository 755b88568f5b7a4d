"""PDF report benchmark: a summary of 100 labs x 100 points, and 1,000
participant reports issued by Celery workers.

A script, not a test.  It wipes and migrates the PostgreSQL database named by
DATABASE_URL (its ``public`` schema: give it a database of its own), builds two
comparisons with accepted results, analyses them in-process, then times:

(a) the summary report of ``BENCH-S`` (``--labs`` x ``--points``, default 100 x 100):
    ``report_issue`` in this process, cold (fresh process caches) and again;
(b) participant reports of ``BENCH-P`` (``--participants`` x ``--p-points``, default
    1,000 x 5): per report in this process, then through Redis with one and with two
    Celery worker processes (``-P solo`` each): the summary task and one batch task per
    ``--batch`` participants (default 25, as publication fans them out; 0: one task per
    report), ``--one-worker`` / ``--two-workers`` reports (0: all, summary included).

    DATABASE_URL=postgres://postgres@127.0.0.1:5432/h6 CELERY_BROKER_URL=redis://127.0.0.1:6379/6 \\
        .venv/bin/python bench/bench_reports.py [--quick]

Targets: (a) < 10 s; (b) 1,000 participant reports < 5 min on two workers.
"""

from __future__ import annotations

import argparse
import hashlib
import io
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
import uuid
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DB = os.environ.get("DATABASE_URL", "")
BROKER = os.environ.get("CELERY_BROKER_URL", "")
MEDIA = Path(tempfile.mkdtemp(prefix="bench-reports-"))


def wipe_and_migrate() -> None:
    import psycopg

    with psycopg.connect(DB, autocommit=True) as conn:
        conn.execute("DROP SCHEMA public CASCADE")
        conn.execute("CREATE SCHEMA public")
    env = os.environ | {"MEDIA_ROOT": str(MEDIA)}
    subprocess.run([sys.executable, "manage.py", "migrate", "-v0"], cwd=ROOT, env=env, check=True)


def setup_django() -> None:
    os.environ["MEDIA_ROOT"] = str(MEDIA)
    # Production-like: no SQL query log (DEBUG's cursor wrapper also lacks COPY options).
    os.environ["DEBUG"] = "false"
    os.environ.setdefault("EMAIL_URL", "dummymail://")  # DEBUG off needs one; send nothing
    os.environ.setdefault("SECRET_KEY", uuid.uuid4().hex * 2)
    os.environ.setdefault("DJANGO_SETTINGS_MODULE", "config.settings")
    sys.path.insert(0, str(ROOT))
    import django

    django.setup()


def generate(code: str, n_labs: int, n_devices: int, n_freqs: int, axes: list[str]) -> int:
    """A closed comparison, every lab with one accepted submission (seeded data)."""
    import numpy as np
    from django.db import connection

    from labs.models import Laboratory, Participant, Submission
    from proficiency.models import Comparison, Device
    from proficiency.services import measurement_points_generate

    c = Comparison.objects.create(
        code=code, title=f"Report benchmark {code}", status="closed",
        assigned_value_method="weighted_mean", sigma_pt_mode="relative", sigma_pt_value=1.0,
        authorised_by_name="B. Enchmark", authorised_by_role="Quality manager",
        report_comments="Benchmark comments <not markup> & more.",
    )  # fmt: skip
    devices = [Device.objects.create(comparison=c, name=f"MEMS {i}") for i in range(n_devices)]
    freqs = [float(2 ** (i / 3) * 5) for i in range(n_freqs)]
    measurement_points_generate(
        comparison=c, devices=devices, axes=axes, frequencies_hz=freqs, benches=["linear"]
    )
    labs = Laboratory.objects.bulk_create(Laboratory(name=f"{code} lab {i}") for i in range(n_labs))
    parts = Participant.objects.bulk_create(
        Participant(comparison=c, laboratory=lab, code=f"L{i:04d}") for i, lab in enumerate(labs)
    )
    subs = Submission.objects.bulk_create(
        Submission(participant=p, version=1, status="accepted") for p in parts
    )
    point_ids = list(c.measurement_points.values_list("id", flat=True))
    rng = np.random.default_rng(11)
    buf = io.StringIO()
    for s in subs:
        x = 420 * (1 + rng.normal(0, 0.004)) + rng.normal(0, 1.0, len(point_ids))
        big_u = rng.uniform(4, 12, len(point_ids))
        for pid, v, bu in zip(point_ids, x.tolist(), big_u.tolist(), strict=True):
            buf.write(f"{s.pk}\t{pid}\t{v!r}\tD/(m/s^2)\t{bu!r}\t2.0\t\n")
    with (
        connection.cursor() as cur,
        cur.copy(
            "COPY labs_result (submission_id, measurement_point_id, value, unit, "
            "expanded_uncertainty, coverage_factor, note) FROM STDIN"
        ) as copy,
    ):
        copy.write(buf.getvalue())
    return c.pk


def analyse_and_publish(comparison_id: int) -> None:
    """Analyse in this process (eager), then mark published (no e-mails, no fan-out)."""
    from analysis.selectors import current_run
    from analysis.services import analysis_run_start
    from config.celery import app
    from proficiency.models import Comparison

    app.conf.task_always_eager = True
    try:
        analysis_run_start(comparison=Comparison.objects.get(pk=comparison_id), user=None)
    finally:
        app.conf.task_always_eager = False
    c = Comparison.objects.get(pk=comparison_id)
    assert current_run(c) is not None, "analysis failed"
    Comparison.objects.filter(pk=comparison_id).update(status="published")


def time_summary(comparison_id: int) -> tuple[list[float], int, int]:
    from analysis.reports.services import report_issue
    from proficiency.models import Comparison

    c = Comparison.objects.get(pk=comparison_id)
    times, digests, report = [], set(), None
    for _ in range(2):
        t0, c0 = time.perf_counter(), time.process_time()
        report = report_issue(comparison=c, kind="summary")
        times += [time.perf_counter() - t0, time.process_time() - c0]
        digests.add(report.sha256)
    assert report is not None and len(digests) == 1, "summary not byte-identical when reissued"
    from pypdf import PdfReader

    return times, report.size, len(PdfReader(report.file.path).pages)


def time_participants_in_process(comparison_id: int, n: int) -> list[float]:
    from analysis.reports.services import report_issue
    from proficiency.models import Comparison

    c = Comparison.objects.get(pk=comparison_id)
    times = []
    for p in c.participants.order_by("code")[:n]:
        t0 = time.process_time()
        report_issue(comparison=c, kind="participant", participant=p)
        times.append(time.process_time() - t0)
    return times


def clear_reports(comparison_id: int) -> None:
    from analysis.models import Report

    Report.objects.filter(comparison_id=comparison_id).delete()


def start_workers(n: int, queue: str) -> list[subprocess.Popen]:
    env = os.environ | {"MEDIA_ROOT": str(MEDIA), "CELERY_TASK_ALWAYS_EAGER": "false"}
    cmd = [sys.executable, "-m", "celery", "-A", "config", "worker", "-P", "solo", "-Q",
           queue, "--loglevel=WARNING", "--without-gossip", "--without-mingle",
           "--without-heartbeat"]  # fmt: skip
    workers = [
        subprocess.Popen([*cmd, "-n", f"bench{i}-{queue}@%h"], cwd=ROOT, env=env) for i in range(n)
    ]
    time.sleep(6)  # let them import Django and connect
    return workers


def proc_cpu(pid: int) -> float:
    """CPU seconds (user + system) of a running process, from /proc."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def sched(pid: int) -> tuple[float, float]:
    """Seconds on a CPU and seconds runnable but waiting for one (the scheduler's run
    queue: other jobs held the cores) of a process's main thread, which runs the tasks
    of a ``-P solo`` worker (/proc/<pid>/schedstat)."""
    on_cpu, waiting, _ = Path(f"/proc/{pid}/schedstat").read_text().split()
    return int(on_cpu) / 1e9, int(waiting) / 1e9


def issue_with_workers(
    comparison_id: int, n_workers: int, limit: int | None, batch: int, summary: bool = True
) -> tuple[float, int, float, tuple[float, float]]:
    """Wall seconds from enqueueing the jobs until every report row exists, the number of
    reports, the workers' CPU seconds over that time (read from /proc: start-up not
    included) and the load average (1 min) before and after; ``summary`` False: the
    participant reports only.  ``batch`` > 0: the summary
    task then one ``report_issue_batch_task`` per ``batch`` participants, as publication
    fans them out; 0: one ``report_issue_task`` per report (the older fan-out).
    The machine may be shared: the workers' CPU-busy fraction, CPU / (wall x workers),
    is the figure that depends least on the other jobs."""
    from analysis.models import Report
    from analysis.reports.services import report_batches, report_jobs
    from analysis.reports.tasks import report_issue_batch_task, report_issue_task
    from config.celery import app
    from proficiency.models import Comparison

    clear_reports(comparison_id)
    comparison = Comparison.objects.get(pk=comparison_id)
    jobs = report_jobs(comparison)[0 if summary else 1 :][:limit]
    run_id, batches = report_batches(comparison, batch or 1)  # also refreshes planner stats
    ids = [pk for b in batches for pk in b][: len(jobs) - summary]
    queue = f"bench-reports-{uuid.uuid4().hex[:6]}"
    app.conf.task_default_queue = queue
    workers = start_workers(n_workers, queue)
    try:
        load0 = os.getloadavg()[0]
        cpu0 = sum(proc_cpu(w.pid) for w in workers)
        sched0 = [sched(w.pid) for w in workers]
        t0 = time.perf_counter()
        if batch:
            if summary:
                report_issue_task.apply_async(jobs[0], queue=queue)
            for i in range(0, len(ids), batch):
                report_issue_batch_task.apply_async((run_id, ids[i : i + batch]), queue=queue)
        else:
            for job in jobs:
                report_issue_task.apply_async(job, queue=queue)
        while Report.objects.filter(comparison_id=comparison_id).count() < len(jobs):
            if any(w.poll() is not None for w in workers):
                raise SystemExit("a worker died")
            time.sleep(0.2)
        wall = time.perf_counter() - t0
        cpu = sum(proc_cpu(w.pid) for w in workers) - cpu0
        load1 = os.getloadavg()[0]
        sched1 = [sched(w.pid) for w in workers]
        for i, (a, b) in enumerate(zip(sched0, sched1, strict=True)):
            run, queued = b[0] - a[0], b[1] - a[1]
            print(f"      worker {i}: on CPU {run / wall:.0%}, runnable waiting for a core "
                  f"{queued / wall:.0%}, blocked (database, broker, files) "
                  f"{1 - (run + queued) / wall:.0%} of {wall:.1f} s", flush=True)  # fmt: skip
    finally:
        for w in workers:
            w.terminate()
        for w in workers:
            w.wait(timeout=60)
    return wall, len(jobs), cpu, (load0, load1)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--labs", type=int, default=100)
    ap.add_argument("--points", type=int, default=100, help="multiple of 10 (10 devices)")
    ap.add_argument("--participants", type=int, default=1000)
    ap.add_argument("--p-points", type=int, default=5, help="frequencies of one device, X axis")
    ap.add_argument("--in-process", type=int, default=20, help="participant reports timed here")
    ap.add_argument("--one-worker", type=int, default=100, help="reports on one worker")
    ap.add_argument("--two-workers", type=int, default=0, help="reports on two (0: all)")
    ap.add_argument(
        "--batch", type=int, default=25, help="participants per worker task (0: one per report)"
    )
    ap.add_argument("--skip-summary", action="store_true", help="skip (a)")
    ap.add_argument("--quick", action="store_true", help="small sizes, a smoke test")
    args = ap.parse_args()
    if args.quick:
        args.labs, args.points, args.participants = 10, 20, 30
        args.in_process, args.one_worker = 3, 10
    if not DB.startswith("postgres") or not BROKER.startswith("redis"):
        raise SystemExit("set DATABASE_URL (PostgreSQL, a database of its own) and "
                         "CELERY_BROKER_URL (Redis)")  # fmt: skip
    wipe_and_migrate()
    setup_django()
    try:
        run(args)
    finally:
        shutil.rmtree(MEDIA, ignore_errors=True)


def run(args: argparse.Namespace) -> None:
    t0 = time.perf_counter()
    s_id = generate("BENCH-S", args.labs, 10, args.points // 10, ["X"])
    p_id = generate("BENCH-P", args.participants, 1, args.p_points, ["X"])
    analyse_and_publish(s_id)
    analyse_and_publish(p_id)
    print(f"generated and analysed in {time.perf_counter() - t0:.1f} s", flush=True)

    if not args.skip_summary:
        times, size, pages = time_summary(s_id)
        verdict = "PASS" if times[0] < 10 else "FAIL"
        print(f"(a) summary {args.labs} labs x {args.points} points: cold {times[0]:.2f} s "
              f"(CPU {times[1]:.2f} s), again {times[2]:.2f} s (CPU {times[3]:.2f} s); "
              f"{pages} pages, {size / 1e6:.2f} MB, byte-identical when reissued "
              f"(target < 10 s: {verdict})", flush=True)  # fmt: skip

    per = time_participants_in_process(p_id, args.in_process)
    steady = statistics.median(per[1:]) if len(per) > 1 else per[0]
    print(f"(b) participant report, {args.participants} participants x {args.p_points} "
          f"points, in process, CPU time: first {per[0]:.2f} s, median of the next {len(per) - 1}: "
          f"{steady:.3f} s", flush=True)  # fmt: skip

    one, n1, cpu1, load = issue_with_workers(p_id, 1, args.one_worker, args.batch)
    print(f"    one worker (batches of {args.batch}): {n1} reports in {one:.1f} s "
          f"({one / n1:.3f} s each), worker CPU {cpu1:.1f} s ({cpu1 / n1:.3f} s each), "
          f"CPU-busy {cpu1 / one:.0%}; load {load[0]:.1f} -> {load[1]:.1f}",
          flush=True)  # fmt: skip
    two, n2, cpu2, load = issue_with_workers(p_id, 2, args.two_workers or None, args.batch)
    total = two * (args.participants + 1) / n2
    verdict = "PASS" if total < 300 else "FAIL"
    print(
        f"    two workers (batches of {args.batch}): {n2} reports in {two:.1f} s "
        f"({two / n2:.3f} s each; {(n2 / two) / (n1 / one):.2f}x one worker's rate), worker CPU "
        f"{cpu2:.1f} s, CPU-busy {cpu2 / two / 2:.0%} per worker; load {load[0]:.1f} -> "
        f"{load[1]:.1f}; {args.participants + 1} reports: {total:.0f} s wall (target "
        f"< 300 s: {verdict})",
        flush=True,
    )
    check_determinism(p_id)


def check_determinism(comparison_id: int) -> None:
    """A worker's PDF equals the one this process renders for the same participant."""
    from analysis.models import Report
    from analysis.reports.assemble import report_data
    from analysis.reports.render import render_report

    report = Report.objects.filter(comparison_id=comparison_id, kind="participant").first()
    assert report is not None and report.run is not None and report.participant is not None
    data = report_data(run=report.run, participant=report.participant, edition=1)
    same = hashlib.sha256(render_report(data)).hexdigest() == report.sha256
    print(f"    worker PDF == in-process PDF for {report.participant.code}: {same}")


if __name__ == "__main__":
    main()
