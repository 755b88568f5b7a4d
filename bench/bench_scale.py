"""Scaling benchmark (a script, not a test): import -> analysis ->
participant reports, end to end, at several round sizes, with 1 and with 2 workers.

    DATABASE_URL=postgres://postgres@127.0.0.1:5432/ANY \\
    CELERY_BROKER_URL=redis://127.0.0.1:6379/N \\
        .venv/bin/python bench/bench_scale.py [--sizes 2000x100,...] [--workers 1,2]
            [--reports-sample 100 | --all-reports] [--keep] [--quick]

Only the server of DATABASE_URL is used: every size gets a scratch database of its own,
``<--scratch-db>_<N>x<P>`` (dropped at the end unless ``--keep``), made and measured in
a child process of this script, so that sizes do not share tables, caches or memory.
For one size (N participants x P points, P a multiple of 10: 5 devices x X, Y x P/10
frequencies, linear bench) the child

1. builds the open comparison with its participants and writes the coordinator's
   results table (N x P rows), as ``bench_import.py`` does;
2. **import**: ``manage.py import_results`` on it in a child process (the streamed
   importer; one process, no worker): wall time, the process's peak RSS;
3. accepts the submitted versions (one UPDATE: a reviewer's decision, not measured),
   sets the analysis parameters (weighted mean, sigma_pt 1 % relative, as
   ``bench_analysis.py``) and closes the comparison;
4. **analysis**, for each worker count W: W fresh ``celery worker -P solo`` processes
   on a queue of their own, one fanned-out run started by the analysis service and
   timed until it has succeeded (``bench_analysis.run_analysis``); peak RSS: the
   ``VmHWM`` the chunks store on the run, and the workers' own ``VmHWM`` at the end;
5. publishes the comparison (the status only: ``comparison_publish`` would queue every
   report at once) and, for each W, **participant reports**: W fresh workers, one
   ``report_issue_batch_task`` per ``REPORTS_BATCH_SIZE`` participants sent as one group
   (what the publication's fan-out task sends, without the summary), timed from sending
   until every report row exists; by default for a random sample of K participants
   (``--reports-sample``), after one warm-up report per worker (timed, counted once),
   the time extrapolated linearly to the other participants (printed "extrapolated
   from K"), or all of them with ``--all-reports``.  Peak RSS: the workers' ``VmHWM``.

Times are wall-clock from the moment the workers answer a ping (start-up excluded);
worker CPU seconds (from /proc) are printed beside them, since the 2-core machine may
be shared.  The parent prints a table stage x size x workers -> time, CPU, peak RSS,
ratio 1 worker / 2 workers, and fits log(time) against log(participants) at a fixed
number of points and against log(points) at a fixed number of participants.
"""

from __future__ import annotations

import argparse
import json
import os
import random
import shutil
import subprocess
import sys
import tempfile
import time
import uuid
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from django.db.models import QuerySet

BENCH = Path(__file__).resolve().parent
sys.path.insert(0, str(BENCH))

import bench_analysis  # noqa: E402
import bench_import  # noqa: E402

FULL_SIZES = "2000x100,5000x100,10000x20,10000x50,10000x100"
QUICK_SIZES = "200x10,400x10,200x20"
CODE = "BENCH-SCALE"


def load() -> float:
    return os.getloadavg()[0]


def parse_sizes(text: str) -> list[tuple[int, int]]:
    sizes = [tuple(int(v) for v in s.split("x")) for s in text.split(",")]
    for n, p in sizes:
        if p % 10 or p < 10 or n < 2:
            raise SystemExit(f"size {n}x{p}: points must be a multiple of 10, participants >= 2")
    return sizes  # type: ignore[return-value]


# --- one size, in a child process -------------------------------------------------------


def measure_size(n: int, p: int, args: argparse.Namespace, media: Path) -> dict:
    """Everything for one size, in a scratch database of its own; a JSON-able dict."""
    server = os.environ["DATABASE_URL"]
    name = f"{args.scratch_db}_{n}x{p}"
    db_url = bench_import.with_db(server, name)
    bench_analysis.SCRATCH_URL = db_url  # the workers' database
    os.environ["MEDIA_ROOT"] = str(media)  # inherited by the workers
    os.environ["PYTHONWARNINGS"] = "ignore:You're running the worker with superuser"
    bench_import.recreate_database(server, name)
    out: dict = {"n": n, "p": p, "analysis": {}, "reports": {}}
    try:
        bench_import.setup_django(db_url)
        out |= {"import": measure_import(n, p, db_url)}
        cid = accept_and_close()
        for w in args.workers:
            last = w == args.workers[-1]
            r = bench_analysis.run_analysis(cid, w, args.chunk, keep_run=last, quiet=True)
            out["analysis"][w] = {
                "s": r["total"], "cpu_s": r["worker_cpu_s"], "rss_mb": r["worker_hwm_mb"],
                "chunk_rss_mb": r["rss_mb"], "chunks": r["chunks"], "load": load(),
            }  # fmt: skip
            print(f"  analysis, {w} worker(s): {r['total']:.1f} s wall, workers' CPU "
                  f"{r['worker_cpu_s']:.1f} s, {r['chunks']} chunks, peak RSS {r['rss_mb']:.0f} "
                  f"MiB in chunks, {r['worker_hwm_mb']:.0f} MiB VmHWM (load {load():.1f})",
                  flush=True)  # fmt: skip
        publish(cid)
        jobs = participant_jobs(cid, None if args.all_reports else args.reports_sample)
        for w in args.workers:
            out["reports"][w] = r = issue_reports(cid, jobs, w, args.chunk, n)
            k, cpu = r["k"], r["cpu_s_sample"]
            print(f"  reports, {w} worker(s): warm-up ({w} reports) {r['warm_s']:.1f} s, then "
                  f"{k} participant "
                  f"reports in {r['s_sample']:.1f} s wall ({r['s_sample'] / k:.3f} s each), "
                  f"workers' CPU {cpu:.1f} s ({cpu / k:.3f} s each), VmHWM {r['rss_mb']:.0f} MiB"
                  f" -> {n:,} reports: {r['s']:.0f} s"
                  + ("" if k == n else f" (extrapolated from {k})")
                  + f" (load {load():.1f})", flush=True)  # fmt: skip
    finally:
        from django.db import connections

        connections.close_all()
        if not args.keep:
            bench_import.recreate_database(server, name, drop_only=True)
    return out


def measure_import(n: int, p: int, db_url: str) -> dict:
    frequencies = range(10, 10 * (p // 10) + 1, 10)
    t0 = time.perf_counter()
    codes = bench_import.build_round(n, code=CODE, frequencies=frequencies)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "round.csv"
        values = bench_import.write_file(path, codes, frequencies=frequencies)
        assert values.shape == (n, p), values.shape
        print(f"{n:,} participants x {p} points: round and {path.stat().st_size / 2**20:.0f} "
              f"MiB CSV made in {time.perf_counter() - t0:.1f} s", flush=True)  # fmt: skip
        seconds, peak, status, output = bench_import.run_import(db_url, path, CODE)
    if status != 0:
        raise SystemExit(f"import refused (exit {status}):\n{output[-2000:]}")
    from labs.models import Result

    stored = Result.objects.filter(submission__participant__comparison__code=CODE).count()
    assert stored == n * p, (stored, n * p)
    print(f"  import: {n * p:,} rows in {seconds:.1f} s wall, peak RSS {peak:.0f} MiB "
          f"(load {load():.1f})", flush=True)  # fmt: skip
    return {"s": seconds, "rss_mb": peak, "load": load()}


def accept_and_close() -> int:
    """The reviewer accepts every imported version (one UPDATE, not measured), the
    coordinator sets the analysis parameters; open -> closed through the life cycle."""
    from django.utils import timezone

    from labs.models import Submission
    from proficiency.models import Comparison
    from proficiency.services import comparison_transition

    Comparison.objects.filter(code=CODE).update(
        assigned_value_method="weighted_mean", sigma_pt_mode="relative", sigma_pt_value=1.0
    )
    c = Comparison.objects.get(code=CODE)
    Submission.objects.filter(participant__comparison=c, status="submitted").update(
        status="accepted", decided_at=timezone.now()
    )
    comparison_transition(comparison=c, to="closed")
    return c.pk


def publish(comparison_id: int) -> None:
    """analysed -> published with the authorisation a final report needs; the reports are
    sent by :func:`issue_reports`, not by the publication's fan-out."""
    from proficiency.models import Comparison
    from proficiency.services import comparison_transition

    Comparison.objects.filter(pk=comparison_id).update(
        authorised_by_name="B. Enchmark", authorised_by_role="Quality manager"
    )
    comparison_transition(comparison=Comparison.objects.get(pk=comparison_id), to="published")


def participant_jobs(comparison_id: int, sample: int | None) -> tuple[int, list[int]]:
    """The run id and the participant ids of the publication's batches
    (``report_batches``, which also refreshes the planner's statistics), or a seeded random
    sample of ``sample`` of them, in code order."""
    from analysis.reports.services import report_batches
    from proficiency.models import Comparison

    run_id, batches = report_batches(Comparison.objects.get(pk=comparison_id))
    ids = [pk for batch in batches for pk in batch]
    if sample is not None and sample < len(ids):
        chosen = set(random.Random(9).sample(ids, sample))
        ids = [pk for pk in ids if pk in chosen]
    return run_id, ids


def issue_reports(comparison_id: int, jobs: tuple[int, list[int]], n_workers: int, chunk: int,
                  n: int) -> dict:  # fmt: skip
    """The participant reports as the publication fans them out: one
    ``report_issue_batch_task`` per ``REPORTS_BATCH_SIZE`` participants, as one group, on
    ``n_workers`` fresh workers.

    All reports (``len(ids) == n``): timed from sending until the last report row exists.
    A sample of K: first one warm-up report per worker, timed apart (a worker's first
    report imports the rendering libraries and builds what it caches of the run: the
    shared data and the point charts, a cost paid once per worker, which scaling the
    sample up would multiply), then the K reports; all N are estimated as warm-up + K
    reports' time x (N - W) / K."""
    from celery import group
    from django.conf import settings

    from analysis.models import Report
    from analysis.reports.tasks import report_issue_batch_task
    from config.celery import app

    run_id, ids = jobs
    size = getattr(settings, "REPORTS_BATCH_SIZE", 25)
    Report.objects.filter(comparison_id=comparison_id).delete()
    queue = f"bench-scale-{uuid.uuid4().hex[:6]}"
    app.conf.task_default_queue = queue
    workers = bench_analysis.start_workers(n_workers, queue, chunk, quiet=True)
    k = len(ids)
    warm = ids[:n_workers] if k < n else []
    try:
        bench_analysis.wait_ready(n_workers)
        done = Report.objects.filter(comparison_id=comparison_id, kind="participant")
        cpu0, _ = bench_analysis.worker_stats(workers)
        t0 = time.perf_counter()
        if warm:
            group(report_issue_batch_task.s(run_id, [pk]) for pk in warm).apply_async(queue=queue)
            wait_reports(done, len(warm), workers)
            Report.objects.filter(comparison_id=comparison_id).delete()
        warm_s, (warm_cpu, _) = time.perf_counter() - t0, bench_analysis.worker_stats(workers)
        t0 = time.perf_counter()
        batches = [ids[i : i + size] for i in range(0, k, size)]
        group(report_issue_batch_task.s(run_id, b) for b in batches).apply_async(queue=queue)
        wait_reports(done, k, workers)
        wall = time.perf_counter() - t0
        cpu1, hwm = bench_analysis.worker_stats(workers)
    finally:
        for w in workers:
            w.terminate()
        for w in workers:
            w.wait(timeout=60)
    scale = max(n - len(warm), 0) / k
    return {"k": k, "s_sample": wall, "warm_s": warm_s, "s": warm_s + wall * scale,
            "cpu_s": warm_cpu - cpu0 + (cpu1 - warm_cpu) * scale,
            "cpu_s_sample": cpu1 - warm_cpu, "rss_mb": hwm / 1024, "load": load()}  # fmt: skip


def wait_reports(done: QuerySet, count: int, workers: list[subprocess.Popen]) -> None:
    while done.count() < count:
        if any(w.poll() is not None for w in workers):
            raise SystemExit("a report worker died")
        time.sleep(0.2)


# --- the parent: sizes, table, fits ---------------------------------------------------------


def fit(xs: list[float], ys: list[float]) -> float:
    import numpy as np

    return float(np.polyfit(np.log(xs), np.log(ys), 1)[0])


def exponents(results: list[dict], stage: str, w: str) -> list[str]:
    """log-log slopes of the stage's time against participants (sizes sharing a number of
    points) and against points (sizes sharing a number of participants)."""
    out = []
    for along, fixed, label, other in (("n", "p", "participants", "points"),
                                       ("p", "n", "points", "participants")):  # fmt: skip
        for value in sorted({r[fixed] for r in results}):
            rows = sorted((r for r in results if r[fixed] == value), key=lambda r: r[along])
            if len({r[along] for r in rows}) < 2:
                continue
            t = [time_of(r, stage, w) for r in rows]
            span = f"{rows[0][along]:,}-{rows[-1][along]:,}"
            out.append(f"time ~ {label}^{fit([r[along] for r in rows], t):.2f} "
                       f"({label} {span}, {len(rows)} sizes, at {value:,} {other})")  # fmt: skip
    return out


def time_of(r: dict, stage: str, w: str) -> float:
    return r["import"]["s"] if stage == "import" else r[stage][w]["s"]


def print_table(results: list[dict], workers: list[int], all_reports: bool) -> None:
    ws = [str(w) for w in workers]
    print(
        "\nstage     | size (N x P = results)      | workers | time (s) | CPU (s) | "
        "peak RSS (MiB) | 2 vs 1 (t1/t2) | load"
    )
    print("-" * 112)
    for stage in ("import", "analysis", "reports"):
        for r in results:
            size = f"{r['n']:,} x {r['p']} = {r['n'] * r['p']:,}"
            if stage == "import":
                i = r["import"]
                print(f"{stage:<9} | {size:<27} | command | {i['s']:>8.1f} | {'-':>7} | "
                      f"{i['rss_mb']:>14.0f} | {'-':>14} | {i['load']:.1f}")  # fmt: skip
                continue
            for w in ws:
                m = r[stage][w]
                ratio = "-"
                if w == "2" and "1" in r[stage]:
                    ratio = f"{r[stage]['1']['s'] / m['s']:.2f}x"
                note = ""
                if stage == "reports" and m["k"] != r["n"]:
                    note = f"  extrapolated from {m['k']} (+ warm-up)"
                print(f"{stage:<9} | {size:<27} | {w:>7} | {m['s']:>8.1f} | {m['cpu_s']:>7.1f} | "
                      f"{m['rss_mb']:>14.0f} | {ratio:>14} | {m['load']:.1f}{note}")  # fmt: skip
    print(
        "\nreports: participant reports only (no summary); peak RSS is the workers' VmHWM"
        + (
            ""
            if all_reports
            else "; time and CPU: one warm-up report per worker + a sample"
            " of K extrapolated linearly to the other N - W"
        )
    )
    print("\ngrowth (log-log least-squares slope of wall time):")
    for stage in ("import", "analysis", "reports"):
        for w in ["command"] if stage == "import" else ws:
            for line in exponents(results, stage, w):
                print(f"  {stage}, {w}{'' if w == 'command' else ' worker(s)'}: {line}")
    if "1" in ws and "2" in ws:
        big = max(results, key=lambda r: r["n"] * r["p"])
        a = big["analysis"]
        rss = {
            s: max(r[s][w]["rss_mb"] for r in results for w in ws) for s in ("analysis", "reports")
        }
        print(f"\nlargest round ({big['n'] * big['p']:,} results): analysis "
              f"{min(a[w]['s'] for w in ws):.1f} s (target < 30 s), 2 workers "
              f"{a['1']['s'] / a['2']['s']:.2f}x faster (target >= 1.6x), worker peak RSS "
              f"{rss['analysis']:.0f} MiB in analysis, {rss['reports']:.0f} MiB in reports "
              "(target < 1024)")  # fmt: skip


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--sizes", default=FULL_SIZES, help=f"NxP,... (default {FULL_SIZES})")
    ap.add_argument("--workers", default="1,2", help="worker counts (default 1,2)")
    ap.add_argument("--reports-sample", type=int, metavar="K",
                    help="participant reports issued per size and worker count, extrapolated "
                         "linearly to all participants (default 100; 20 with --quick)")  # fmt: skip
    ap.add_argument("--all-reports", action="store_true", help="issue every participant report")
    ap.add_argument("--chunk", type=int, default=100_000, help="ANALYSIS_CHUNK_RESULTS")
    ap.add_argument(
        "--scratch-db", default="pt_bench_scale", help="prefix of the scratch databases"
    )
    ap.add_argument("--keep", action="store_true", help="keep the scratch databases")
    ap.add_argument("--quick", action="store_true",
                    help=f"smoke run: sizes {QUICK_SIZES}, 20 reports sampled")  # fmt: skip
    ap.add_argument("--json", help="also write the measurements to this file")
    ap.add_argument("--one", help=argparse.SUPPRESS)  # internal: one size, in a child
    ap.add_argument("--out", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.quick:
        args.sizes = QUICK_SIZES if args.sizes == FULL_SIZES else args.sizes
    if args.reports_sample is None:
        args.reports_sample = 20 if args.quick else 100
    args.workers = [int(w) for w in args.workers.split(",")]
    if not os.environ.get("DATABASE_URL", "").startswith("postgres") or not os.environ.get(
        "CELERY_BROKER_URL", ""
    ).startswith("redis"):
        raise SystemExit("set DATABASE_URL (a PostgreSQL server) and CELERY_BROKER_URL (Redis)")
    if args.one:
        (n, p), media = parse_sizes(args.one)[0], Path(tempfile.mkdtemp(prefix="bench-scale-"))
        try:
            Path(args.out).write_text(json.dumps(measure_size(n, p, args, media)))
        finally:
            shutil.rmtree(media, ignore_errors=True)
        return
    sizes = parse_sizes(args.sizes)
    print(f"sizes {args.sizes}; workers {args.workers}; reports: "
          f"{'all' if args.all_reports else f'sample of {args.reports_sample}'}; "
          f"load {load():.1f}", flush=True)  # fmt: skip
    results, started = [], time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        for n, p in sizes:
            out = Path(tmp) / f"{n}x{p}.json"
            child = [a for a in sys.argv[1:] if a != "--quick"]
            subprocess.run(
                [sys.executable, __file__, *child, "--reports-sample", str(args.reports_sample),
                 "--one", f"{n}x{p}", "--out", str(out)], check=True,
            )  # fmt: skip
            results.append(json.loads(out.read_text()))
    print(f"\nall sizes measured in {(time.perf_counter() - started) / 60:.1f} min")
    if args.json:
        Path(args.json).write_text(json.dumps(results, indent=1))
    print_table(results, args.workers, args.all_reports)


if __name__ == "__main__":
    main()
