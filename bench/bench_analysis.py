"""End-to-end analysis run on a real worker: 1,000 labs x 1,000 measurement points.

A script, not a test.  It creates a scratch PostgreSQL database (dropped at the end),
fills it with one closed comparison of 1,000,000 accepted results, starts one Celery
worker process on a Redis broker, runs one analysis (load -> compute -> store) and
reports the run's wall time with its stages, against the time PostgreSQL itself needs
to read and write the same rows with COPY, measured in the same run.

    .venv/bin/python bench/bench_analysis.py [--labs 1000] [--points 1000]

Environment: DATABASE_URL (server, default postgres://postgres@127.0.0.1:5432/test;
the scratch database sits beside it), CELERY_BROKER_URL (default Redis on localhost).
Target (issue 5): < 60 s on a 2-core machine.
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
SCRATCH = "pt_bench_analysis"
SCRATCH_URL = SERVER.rsplit("/", 1)[0] + "/" + SCRATCH


def admin_sql(sql: str) -> None:
    import psycopg

    with psycopg.connect(SERVER, autocommit=True) as conn:
        conn.execute(sql)


def setup_django() -> None:
    os.environ["DATABASE_URL"] = SCRATCH_URL
    os.environ["CELERY_BROKER_URL"] = BROKER
    os.environ.setdefault("DJANGO_SETTINGS_MODULE", "proficiency.settings")
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

    c = Comparison.objects.create(
        code="BENCH-1", title="bench", status="closed", assigned_value_method="weighted_mean",
        sigma_pt_mode="relative", sigma_pt_value=1.0,
    )  # fmt: skip
    n_dev = 10
    devices = [Device.objects.create(comparison=c, name=f"MEMS {i}") for i in range(n_dev)]
    freqs = [float(f) for f in range(1, n_points // n_dev + 1)]
    measurement_points_generate(
        comparison=c, devices=devices, axes=["X"], frequencies_hz=freqs, benches=["linear"]
    )
    labs = Laboratory.objects.bulk_create(Laboratory(name=f"Lab {i}") for i in range(n_labs))
    parts = Participant.objects.bulk_create(
        Participant(comparison=c, laboratory=lab, code=f"L{i:04d}") for i, lab in enumerate(labs)
    )
    subs = Submission.objects.bulk_create(
        Submission(participant=p, version=1, status="accepted") for p in parts
    )
    point_ids = list(c.measurement_points.values_list("id", flat=True))
    rng = np.random.default_rng(7)
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


def copy_baseline() -> tuple[float, float]:
    """Seconds for PostgreSQL to COPY out all results and COPY in as many score rows."""
    from django.db import connection

    with connection.cursor() as cur:
        t0 = time.perf_counter()
        out = io.BytesIO()
        with cur.copy(
            "COPY (SELECT r.id, r.measurement_point_id, p.code, r.value, r.expanded_uncertainty,"
            " r.coverage_factor FROM labs_result r JOIN labs_submission s ON s.id = r.submission_id"
            " JOIN labs_participant p ON p.id = s.participant_id) TO STDOUT"
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
    return read, write


def run_analysis(comparison_id: int) -> tuple[float, dict]:
    from analysis.models import AnalysisRun, Score
    from analysis.services import analysis_run_start
    from proficiency.celery import app
    from proficiency.models import Comparison

    queue = f"bench-{uuid.uuid4().hex[:6]}"
    app.conf.task_default_queue = queue
    env = os.environ | {"DATABASE_URL": SCRATCH_URL, "CELERY_BROKER_URL": BROKER}
    worker = subprocess.Popen(
        [sys.executable, "-m", "celery", "-A", "proficiency", "worker", "-P", "solo", "-Q", queue,
         "--loglevel=WARNING", "--without-gossip", "--without-mingle", "--without-heartbeat"],
        cwd=ROOT, env=env,
    )  # fmt: skip
    try:
        time.sleep(3)  # let the worker connect
        t0 = time.perf_counter()
        run = analysis_run_start(comparison=Comparison.objects.get(pk=comparison_id), user=None)
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
        if run.status != "succeeded":
            raise SystemExit(f"run failed: {run.error}")
        assert (
            Score.objects.filter(run=run).count()
            == AnalysisRun.objects.get(pk=run.pk).comparison.measurement_points.count()
            * run.comparison.participants.count()
        )
        return total, stages
    finally:
        worker.terminate()
        worker.wait(timeout=30)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--labs", type=int, default=1000)
    ap.add_argument("--points", type=int, default=1000)
    args = ap.parse_args()
    admin_sql(f"DROP DATABASE IF EXISTS {SCRATCH} WITH (FORCE)")
    admin_sql(f"CREATE DATABASE {SCRATCH}")
    try:
        env = os.environ | {"DATABASE_URL": SCRATCH_URL}
        subprocess.run([sys.executable, "manage.py", "migrate", "-v0"], cwd=ROOT, env=env,
                       check=True)  # fmt: skip
        setup_django()
        t0 = time.perf_counter()
        cid = generate(args.labs, args.points)
        print(f"generated {args.labs} labs x {args.points} points in "
              f"{time.perf_counter() - t0:.1f} s")  # fmt: skip
        read, write = copy_baseline()
        total, stages = run_analysis(cid)
    finally:
        if "django" in sys.modules:
            from django.db import connections

            connections.close_all()
        admin_sql(f"DROP DATABASE IF EXISTS {SCRATCH} WITH (FORCE)")
    n = args.labs * args.points
    print(f"analysis run, {n:,} results, one worker: {total:.1f} s "
          f"(target < 60 s: {'PASS' if total < 60 else 'FAIL'})")  # fmt: skip
    print("  stage reached at (s): " + ", ".join(f"{k} {v:.1f}" for k, v in stages.items()))
    print(f"COPY baseline: read {read:.1f} s + write {write:.1f} s = {read + write:.1f} s; "
          f"run / COPY = {total / (read + write):.1f}x")  # fmt: skip


if __name__ == "__main__":
    main()
