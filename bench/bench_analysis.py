"""End-to-end analysis runs on real worker processes: sizes x worker counts.

A script, not a test.  It creates a scratch PostgreSQL database (dropped at the end),
fills it with one closed comparison of accepted results per size (labs x points), and
for each size and worker count starts that many Celery worker processes (``-P solo``)
on a Redis broker, runs one analysis (plan -> chunks: load -> compute -> store ->
matrices) and reports the run's wall time with its stages and the peak RSS of the
workers (``VmHWM`` recorded by the tasks on the run row), against the time
PostgreSQL itself needs to read and write the same rows with COPY (largest size).

    .venv/bin/python bench/bench_analysis.py [--sizes 1000x250,1000x500,1000x1000]
                                             [--workers 1,2] [--chunk 100000]

Environment: DATABASE_URL (server, default postgres://postgres@127.0.0.1:5432/test;
the scratch database sits beside it), CELERY_BROKER_URL (default Redis on localhost).
Targets: 1,000,000 results < 30 s; 2 workers >= 1.6x faster than 1;
worker peak memory < 1 GB.
"""

from __future__ import annotations

import argparse
import io
import os
import subprocess
import sys
import time
import uuid
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SERVER = os.environ.get("DATABASE_URL", "postgres://postgres@127.0.0.1:5432/test")
BROKER = os.environ.get("CELERY_BROKER_URL", "redis://127.0.0.1:6379/0")
SCRATCH = os.environ.get("BENCH_SCRATCH_DB", "pt_bench_analysis")
SCRATCH_URL = SERVER.rsplit("/", 1)[0] + "/" + SCRATCH


def admin_sql(sql: str) -> None:
    import psycopg

    with psycopg.connect(SERVER, autocommit=True) as conn:
        conn.execute(sql)


def setup_django() -> None:
    os.environ["DATABASE_URL"] = SCRATCH_URL
    os.environ["CELERY_BROKER_URL"] = BROKER
    os.environ.setdefault("DJANGO_SETTINGS_MODULE", "config.settings")
    sys.path.insert(0, str(ROOT))
    import django

    django.setup()


def generate(n_labs: int, n_points: int) -> int:
    """One closed comparison: n_points linear-bench points, n_labs accepted submissions."""
    import numpy as np
    from django.db import connection

    from labs.models import Laboratory, Participant, Submission
    from proficiency.models import Comparison, Device
    from proficiency.services import measurement_points_generate

    code = f"BENCH-{n_labs}x{n_points}"
    c = Comparison.objects.create(
        code=code, title="bench", status="closed", assigned_value_method="weighted_mean",
        sigma_pt_mode="relative", sigma_pt_value=1.0,
    )  # fmt: skip
    n_dev = 10
    devices = [Device.objects.create(comparison=c, name=f"MEMS {i}") for i in range(n_dev)]
    freqs = [float(f) for f in range(1, n_points // n_dev + 1)]
    measurement_points_generate(
        comparison=c, devices=devices, axes=["X"], frequencies_hz=freqs, benches=["linear"]
    )
    labs = Laboratory.objects.bulk_create(Laboratory(name=f"Lab {code} {i}") for i in range(n_labs))
    parts = Participant.objects.bulk_create(
        Participant(comparison=c, laboratory=lab, code=f"L{i:05d}") for i, lab in enumerate(labs)
    )
    subs = Submission.objects.bulk_create(
        Submission(participant=p, version=1, status="accepted") for p in parts
    )
    point_ids = np.array(c.measurement_points.values_list("id", flat=True))
    rng = np.random.default_rng(7)
    sub_ids = np.array([s.pk for s in subs])
    x = 420 * (1 + rng.normal(0, 0.004, (n_labs, 1))) + rng.normal(0, 1.0, (n_labs, n_points))
    big_u = rng.uniform(4, 12, (n_labs, n_points))
    sub = np.repeat(sub_ids, n_points)
    pid = np.tile(point_ids, n_labs)
    lines = "".join(
        f"{s}\t{p}\t{v!r}\tD/(m/s^2)\t{u!r}\t2.0\t\n"
        for s, p, v, u in zip(sub.tolist(), pid.tolist(), x.ravel().tolist(),
                              big_u.ravel().tolist(), strict=True)
    )  # fmt: skip
    with (
        connection.cursor() as cur,
        cur.copy(
            "COPY labs_result (submission_id, measurement_point_id, value, unit, "
            "expanded_uncertainty, coverage_factor, note) FROM STDIN"
        ) as copy,
    ):
        copy.write(lines)
    with connection.cursor() as cur:
        cur.execute("VACUUM ANALYZE labs_result")
    return c.pk


def copy_baseline(comparison_id: int) -> tuple[float, float]:
    """Seconds for PostgreSQL to COPY out one comparison's results and COPY in as many
    score rows (into a temporary table: no foreign keys, no index)."""
    from django.db import connection

    with connection.cursor() as cur:
        t0 = time.perf_counter()
        out = io.BytesIO()
        with cur.copy(
            "COPY (SELECT r.id, r.measurement_point_id, p.code, r.value, r.expanded_uncertainty,"
            " r.coverage_factor FROM labs_result r JOIN labs_submission s ON s.id = r.submission_id"
            " JOIN labs_participant p ON p.id = s.participant_id"
            f" WHERE p.comparison_id = {int(comparison_id)}) TO STDOUT"
        ) as copy:
            for chunk in copy:
                out.write(chunk)
        read = time.perf_counter() - t0
        cur.execute("CREATE TEMP TABLE score_copy (LIKE analysis_score INCLUDING DEFAULTS)")
        lines = out.getvalue().decode().splitlines()
        data = "".join(f"{i}\t1\t{ln.split(chr(9))[0]}\t0.1\t0.1\t0.5\t0.5\t0.1\t0.1\tsatisfactory"
                       f"\tsatisfactory\tf\n" for i, ln in enumerate(lines, 1))  # fmt: skip
        t0 = time.perf_counter()
        with cur.copy(
            "COPY score_copy (id, run_id, result_id, d, d_percent, en, zeta, z, z_prime, flag,"
            " z_flag, correlation_applied) FROM STDIN"
        ) as copy:
            copy.write(data)
        write = time.perf_counter() - t0
        cur.execute("DROP TABLE score_copy")
    return read, write


def start_workers(n: int, queue: str, chunk: int, quiet: bool = False) -> list[subprocess.Popen]:
    """``n`` worker processes on ``queue``; ``quiet``: without their banner (stdout)."""
    env = os.environ | {"DATABASE_URL": SCRATCH_URL, "CELERY_BROKER_URL": BROKER,
                        "ANALYSIS_CHUNK_RESULTS": str(chunk), "DEBUG": "false",
                        "EMAIL_URL": os.environ.get("EMAIL_URL", "dummymail://"),
                        "SECRET_KEY": f"bench-{uuid.uuid4().hex}"}  # fmt: skip
    cmd = [sys.executable, "-m", "celery", "-A", "config", "worker", "-P", "solo",
           "-Q", queue, "--loglevel=WARNING", "--without-gossip", "--without-mingle",
           "--without-heartbeat"]  # fmt: skip
    out = subprocess.DEVNULL if quiet else None
    return [
        subprocess.Popen([*cmd, "-n", f"bench{i}@%h"], cwd=ROOT, env=env, stdout=out)
        for i in range(n)
    ]


def wait_ready(n: int, timeout: float = 60) -> None:
    from config.celery import app

    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if len(app.control.ping(timeout=0.5) or []) >= n:
            return
    raise SystemExit(f"{n} worker(s) did not answer a ping within {timeout} s")


def worker_stats(workers: list[subprocess.Popen]) -> tuple[float, int]:
    """CPU seconds (user + system) of the worker processes so far, and the largest
    ``VmHWM`` (KiB) among them, from /proc (Linux; ``-P solo``: the task runs in the
    process started).  (0.0, 0) elsewhere."""
    cpu, hwm = 0.0, 0
    tick = os.sysconf("SC_CLK_TCK") if hasattr(os, "sysconf") else 100
    for w in workers:
        try:
            stat = Path(f"/proc/{w.pid}/stat").read_text().rsplit(")", 1)[1].split()
            cpu += (int(stat[11]) + int(stat[12])) / tick
            for line in Path(f"/proc/{w.pid}/status").read_text().splitlines():
                if line.startswith("VmHWM:"):
                    hwm = max(hwm, int(line.split()[1]))
        except OSError:
            pass
    return cpu, hwm


class DatabaseCpu:
    """CPU seconds of the PostgreSQL backends serving the scratch database while it runs:
    a thread lists the backends (``pg_stat_activity``) every 20 ms and reads their CPU
    time from /proc (server on this machine, Linux).  A backend already there at the start
    counts from then; one that lives less than 20 ms is missed.  0.0 where /proc is not
    readable."""

    def __init__(self) -> None:
        import threading

        self.first: dict[int, float] = {}
        self.last: dict[int, float] = {}
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self._poll, daemon=True)

    @staticmethod
    def _cpu(pid: int) -> float | None:
        try:
            stat = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
        except OSError:
            return None
        return (int(stat[11]) + int(stat[12])) / os.sysconf("SC_CLK_TCK")

    def _poll(self) -> None:
        import psycopg

        with psycopg.connect(SCRATCH_URL, autocommit=True) as conn:
            me = conn.info.backend_pid
            started = False
            while not self.stop.is_set():
                rows = conn.execute(
                    "SELECT pid FROM pg_stat_activity WHERE datname = current_database()"
                ).fetchall()
                for (pid,) in rows:
                    if pid == me or (cpu := self._cpu(pid)) is None:
                        continue
                    self.first.setdefault(pid, cpu if not started else 0.0)
                    self.last[pid] = cpu
                started = True
                self.stop.wait(0.02)

    def __enter__(self) -> DatabaseCpu:
        self.thread.start()
        time.sleep(0.1)  # the first listing: the backends already there
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop.set()
        self.thread.join(5)

    @property
    def seconds(self) -> float:
        return sum(self.last[p] - self.first[p] for p in self.last)


def run_analysis(
    comparison_id: int, n_workers: int, chunk: int, keep_run: bool = False, quiet: bool = False
) -> dict:
    """One run on ``n_workers`` fresh worker processes: wall time, stages, peak RSS (the
    run's, recorded by its chunks, and the workers' ``VmHWM`` at the end), the workers'
    CPU seconds during the run.  ``keep_run``: keep the run (and its scores); ``quiet``:
    the workers' banners not shown."""
    from django.db import connection

    from analysis.models import AnalysisRun, Score
    from analysis.services import analysis_run_start
    from config.celery import app
    from proficiency.models import Comparison

    queue = f"bench-{uuid.uuid4().hex[:6]}"
    app.conf.task_default_queue = queue
    workers = start_workers(n_workers, queue, chunk, quiet)
    try:
        wait_ready(n_workers)
        cpu0, _ = worker_stats(workers)
        comparison = Comparison.objects.get(pk=comparison_id)
        Comparison.objects.filter(pk=comparison_id).update(status="closed")
        load_before = os.getloadavg()[0]
        with DatabaseCpu() as db_cpu:
            t0 = time.perf_counter()
            run = analysis_run_start(comparison=comparison, user=None)
            stages: dict[str, float] = {}
            last = None
            while True:
                run.refresh_from_db()
                if run.stage != last:
                    stages[run.stage or "queued"] = time.perf_counter() - t0
                    last = run.stage
                if run.status in ("succeeded", "failed"):
                    break
                time.sleep(0.05)
            total = time.perf_counter() - t0
        cpu1, hwm = worker_stats(workers)
        if run.status != "succeeded":
            raise SystemExit(f"run failed: {run.error}")
        n = comparison.measurement_points.count() * comparison.participants.count()
        assert Score.objects.filter(run=run).count() == n
        chunks = list(run.chunks.order_by("index").values_list("seconds", "peak_rss_kb"))
        chunk_rss_kb = [kb for _, kb in chunks if kb is not None]
        # the run's last step and every stored chunk record their peak RSS
        assert run.peak_rss_kb is not None and len(chunk_rss_kb) == len(chunks)
        if not keep_run:
            AnalysisRun.objects.filter(pk=run.pk).delete()  # keep the score table small
        with connection.cursor() as cur:  # and every run starts from the same table state
            cur.execute("VACUUM analysis_score")
        return {"total": total, "stages": stages, "rss_mb": run.peak_rss_kb / 1024,
                "load": (load_before, os.getloadavg()[0]),
                "run_id": run.pk, "worker_cpu_s": cpu1 - cpu0, "db_cpu_s": db_cpu.seconds,
                "worker_hwm_mb": hwm / 1024,
                "chunks": len(chunks), "chunk_s": sum(c[0] for c in chunks),
                "chunk_rss_mb": [kb // 1024 for kb in chunk_rss_kb]}  # fmt: skip
    finally:
        for w in workers:
            w.terminate()
        for w in workers:
            w.wait(timeout=30)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--sizes", default="1000x250,1000x500,1000x1000", help="LABSxPOINTS,...")
    ap.add_argument("--workers", default="1,2", help="worker counts in order, repeats allowed")
    ap.add_argument("--chunk", type=int, default=100_000, help="ANALYSIS_CHUNK_RESULTS")
    ap.add_argument("--keep", action="store_true", help="keep the scratch database")
    args = ap.parse_args()
    sizes = [tuple(int(v) for v in s.split("x")) for s in args.sizes.split(",")]
    worker_counts = [int(w) for w in args.workers.split(",")]
    admin_sql(f"DROP DATABASE IF EXISTS {SCRATCH} WITH (FORCE)")
    admin_sql(f"CREATE DATABASE {SCRATCH}")
    rows = []
    try:
        env = os.environ | {"DATABASE_URL": SCRATCH_URL}
        subprocess.run([sys.executable, "manage.py", "migrate", "-v0"], cwd=ROOT, env=env,
                       check=True)  # fmt: skip
        setup_django()
        for labs, points in sizes:
            t0 = time.perf_counter()
            cid = generate(labs, points)
            print(f"generated {labs} labs x {points} points in {time.perf_counter() - t0:.1f} s",
                  flush=True)  # fmt: skip
            for w in worker_counts:
                r = run_analysis(cid, w, args.chunk)
                rows.append((labs, points, w, r))
                print(f"  {labs * points:>9,} results, {w} worker(s): {r['total']:.1f} s, "
                      f"{r['chunks']} chunks ({r['chunk_s']:.1f} s in chunk tasks; CPU: "
                      f"workers {r['worker_cpu_s']:.1f} s, database {r['db_cpu_s']:.1f} s), "
                      "peak RSS "
                      f"{r['rss_mb']:.0f} MiB; stages: "
                      + ", ".join(f"{k} {v:.1f}" for k, v in r["stages"].items())
                      + f"; chunk peak RSS (MiB) {r['chunk_rss_mb']}; load average "
                      f"{r['load'][0]:.2f} -> {r['load'][1]:.2f}",
                      flush=True)  # fmt: skip
        read, write = copy_baseline(cid)
        print(f"COPY baseline ({labs * points:,} results): read {read:.1f} s + write {write:.1f} s")
    finally:
        if "django" in sys.modules:
            from django.db import connections

            connections.close_all()
        if not args.keep:
            admin_sql(f"DROP DATABASE IF EXISTS {SCRATCH} WITH (FORCE)")
    summarise(rows, worker_counts)


def summarise(rows: list, worker_counts: list[int]) -> None:
    import numpy as np

    runs: dict[tuple[int, int], list[float]] = {}
    for labs, points, w, r in rows:  # a worker count may be repeated: --workers 1,2,1,2
        runs.setdefault((labs * points, w), []).append(round(r["total"], 1))
    by = {key: float(np.median(times)) for key, times in runs.items()}
    worker_counts = sorted(set(worker_counts))
    sizes = sorted({n for n, _ in by})
    for w in worker_counts:
        t = [by[(n, w)] for n in sizes]
        if len(sizes) > 1:
            slope = np.polyfit(np.log(sizes), np.log(t), 1)[0]
            print(f"{w} worker(s): time ~ results^{slope:.2f}")
    if 1 in worker_counts and 2 in worker_counts:
        for n in sizes:
            print(f"{n:>9,} results: 2 workers {by[(n, 1)] / by[(n, 2)]:.2f}x faster than 1 "
                  f"(medians of {runs[(n, 1)]} and {runs[(n, 2)]} s)")  # fmt: skip
    big = max(sizes)
    best = min(by[(big, w)] for w in worker_counts)
    rss = max(r["rss_mb"] for *_, r in rows)
    print(f"largest round {big:,} results: best {best:.1f} s (target < 30 s: "
          f"{'PASS' if best < 30 else 'FAIL'}); worker peak RSS max {rss:.0f} MiB "
          f"(target < 1024: {'PASS' if rss < 1024 else 'FAIL'})")  # fmt: skip


if __name__ == "__main__":
    main()
