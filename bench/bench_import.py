"""Coordinator bulk import benchmark (a script, not a test).

    DATABASE_URL=postgres://postgres@127.0.0.1:5432/ANY .venv/bin/python bench/bench_import.py \
        [--scratch-db pt_bench_import] [--participants 10000] [--keep]

Only the server of DATABASE_URL is used: the script drops, creates and migrates the
scratch database ``--scratch-db``, builds one open comparison with 100 measurement
points (5 devices × X, Y × 10 frequencies, linear bench) and ``--participants``
participating laboratories (bulk_create), writes a results table with one row per
participant and point (10,000 × 100 = 1,000,000 rows, values in full precision) and
times ``manage.py import_results`` on it in a child process, whose peak RSS is its own
``VmHWM`` (``ru_maxrss`` survives ``execve``: it would start at this process's peak):

  (a) the import, stored                          target < 120 s
  (b) the same file again: a second version per participant
  (c) the file with its last row broken: refused, nothing stored

then checks the rows in the database (counts, versions, a sample of exact values).
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path
from urllib.parse import urlsplit, urlunsplit

import numpy as np
import psycopg

ROOT = Path(__file__).resolve().parent.parent
CODE = "BENCH-IMPORT"
DEVICES, AXES, FREQUENCIES = 5, ("X", "Y"), range(10, 110, 10)
TARGET_S = 120.0


def with_db(url: str, name: str) -> str:
    return urlunsplit(urlsplit(url)._replace(path=f"/{name}"))


def recreate_database(server_url: str, name: str, *, drop_only: bool = False) -> None:
    with psycopg.connect(with_db(server_url, "postgres"), autocommit=True) as conn:
        conn.execute(f'DROP DATABASE IF EXISTS "{name}" WITH (FORCE)')
        if not drop_only:
            conn.execute(f'CREATE DATABASE "{name}"')


def child_env(db_url: str) -> dict[str, str]:
    return {
        **os.environ,
        "DATABASE_URL": db_url,
        "DEBUG": "false",
        "EMAIL_URL": os.environ.get("EMAIL_URL", "dummymail://"),
        "SECRET_KEY": "bench-only-not-a-secret-bench-only-not-a-secret",
        "LOG_LEVEL": "WARNING",
        "DJANGO_SETTINGS_MODULE": "config.settings",
    }


def setup_django(db_url: str) -> None:
    os.environ.update(child_env(db_url))
    sys.path.insert(0, str(ROOT))
    import django

    django.setup()
    from django.core.management import call_command

    call_command("migrate", verbosity=0)


def build_round(
    n_participants: int, *, code: str = CODE, frequencies: Sequence[int] = FREQUENCIES
) -> list[str]:
    """The comparison, its points (``DEVICES`` × ``AXES`` × ``frequencies``) and
    participants; returns the participant codes."""
    from django.contrib.auth import get_user_model

    from labs.models import Laboratory, Participant
    from proficiency.models import Comparison, Device
    from proficiency.services import measurement_points_generate

    comparison = Comparison.objects.create(code=code, title=code, status="open")
    devices = Device.objects.bulk_create(
        Device(comparison=comparison, name=f"MEMS {i}") for i in range(1, DEVICES + 1)
    )
    measurement_points_generate(
        comparison=comparison, devices=devices, axes=AXES, frequencies_hz=list(frequencies),
        benches=["linear"],
    )  # fmt: skip
    labs = Laboratory.objects.bulk_create(
        (Laboratory(name=f"Lab {n:05d}") for n in range(n_participants)), batch_size=5_000
    )
    codes = [f"L{n:05d}" for n in range(n_participants)]
    Participant.objects.bulk_create(
        (Participant(comparison=comparison, laboratory=lab, code=code)
         for lab, code in zip(labs, codes, strict=True)), batch_size=5_000,
    )  # fmt: skip
    user = get_user_model().objects.create_user("bench-coordinator")
    comparison.coordinators.add(user)
    return codes


def write_file(
    path: Path, codes: list[str], *, broken_last: bool = False,
    frequencies: Sequence[int] = FREQUENCIES,
) -> np.ndarray:  # fmt: skip
    """One row per participant and point, participant by participant; the sensitivities.
    ``broken_last``: the last row's uncertainty is -3 (the import must store nothing)."""
    rng = np.random.default_rng(13528)
    points = [(d, a, f) for d in range(1, DEVICES + 1) for a in AXES for f in frequencies]
    values = 415 + rng.normal(0, 2, (len(codes), len(points)))
    uncertainties = values * rng.uniform(0.01, 0.03, values.shape)
    if broken_last:
        uncertainties[-1, -1] = -3.0
    with open(path, "w", encoding="utf-8", newline="") as out:
        out.write("lab,device,axis,frequency_hz,bench,sensitivity,expanded_uncertainty\n")
        for code, vs, us in zip(codes, values.tolist(), uncertainties.tolist(), strict=True):
            out.writelines(
                f"{code},MEMS {d},{a},{f},linear,{v!r},{u!r}\n"
                for (d, a, f), v, u in zip(points, vs, us, strict=True)
            )
    return values


#: Runs the command in the child and reports the child's own peak RSS on stderr
#: (``VmHWM`` on Linux; ``ru_maxrss`` elsewhere, which includes the parent's peak).
CHILD = """
import resource, runpy, sys
sys.argv = ["manage.py", "import_results", *sys.argv[1:]]
try:
    runpy.run_path("manage.py", run_name="__main__")
finally:
    try:
        with open("/proc/self/status") as status:
            peak = next(int(x.split()[1]) for x in status if x.startswith("VmHWM:"))
    except OSError:
        peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    print("peak-rss-kib", peak, file=sys.stderr)
"""


def run_import(db_url: str, path: Path, code: str = CODE) -> tuple[float, float, int, str]:
    """``manage.py import_results`` in a child: wall seconds, its peak RSS (MiB), status,
    output."""
    started = time.perf_counter()
    done = subprocess.run(
        [sys.executable, "-c", CHILD, code, str(path), "--user", "bench-coordinator"],
        cwd=ROOT, env=child_env(db_url), capture_output=True, text=True, check=False,
    )  # fmt: skip
    seconds = time.perf_counter() - started
    lines = (done.stdout + done.stderr).strip().splitlines()
    peak = next(int(line.split()[1]) for line in lines if line.startswith("peak-rss-kib"))
    output = "\n".join(line for line in lines if not line.startswith("peak-rss-kib"))
    return seconds, peak / 1024, done.returncode, output


def baseline_rss(db_url: str) -> float:
    """Peak RSS (MiB) of the same child doing no import (Django, numpy, pandas loaded)."""
    done = subprocess.run(
        [sys.executable, "-c", CHILD.replace('"import_results", ', '"check", "--fail-level", '
                                             '"ERROR", "--database", "default", "-v", "0", ')
         .replace("*sys.argv[1:]", "")],
        cwd=ROOT, env=child_env(db_url), capture_output=True, text=True, check=False,
    )  # fmt: skip
    line = next(x for x in done.stderr.splitlines() if x.startswith("peak-rss-kib"))
    return int(line.split()[1]) / 1024


def check_database(codes: list[str], values: np.ndarray, versions: int) -> None:
    from labs.models import Result, Submission

    n = len(codes) * values.shape[1]
    assert Result.objects.count() == n * versions, Result.objects.count()
    assert Submission.objects.count() == len(codes) * versions
    assert set(Submission.objects.values_list("version", flat=True)) == set(range(1, versions + 1))
    rng = np.random.default_rng(1)
    for p in rng.choice(len(codes), 5, replace=False):
        stored = sorted(
            Result.objects.filter(submission__participant__code=codes[p], submission__version=1)
            .order_by("measurement_point__device__name", "measurement_point__axis",
                      "measurement_point__frequency_hz")
            .values_list("value", flat=True)
        )  # fmt: skip
        assert stored == sorted(values[p].tolist()), codes[p]
    print(f"  database: {n * versions:,} results, {len(codes) * versions:,} submissions, "
          "sampled values exact")  # fmt: skip


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--scratch-db", default="pt_bench_import")
    parser.add_argument("--participants", type=int, default=10_000)
    parser.add_argument("--keep", action="store_true", help="keep the scratch database")
    args = parser.parse_args()
    server = os.environ.get("DATABASE_URL", "postgres://postgres@127.0.0.1:5432/test")
    db_url = with_db(server, args.scratch_db)
    recreate_database(server, args.scratch_db)
    try:
        setup_django(db_url)
        started = time.perf_counter()
        codes = build_round(args.participants)
        with tempfile.TemporaryDirectory() as tmp:
            path, broken = Path(tmp) / "round.csv", Path(tmp) / "round-broken.csv"
            values = write_file(path, codes)
            write_file(broken, codes, broken_last=True)
            size, took = path.stat().st_size / 2**20, time.perf_counter() - started
            print(f"setup: {len(codes):,} participants × {values.shape[1]} points, "
                  f"{values.size:,} rows, {size:.0f} MiB CSV, {took:.1f} s")  # fmt: skip
            print(f"child baseline (manage.py check): peak RSS {baseline_rss(db_url):.0f} MiB")
            for label, file, versions in (("(a) import", path, 1), ("(b) again", path, 2),
                                          ("(c) last row broken", broken, 2)):  # fmt: skip
                seconds, peak, status, output = run_import(db_url, file)
                verdict = "PASS" if seconds < TARGET_S else "FAIL"
                if file is broken:
                    verdict = "PASS" if status == 2 and "-3" in output else "FAIL"
                print(f"{label}: {seconds:.1f} s wall, peak RSS {peak:.0f} MiB, exit {status}, "
                      f"{verdict}")  # fmt: skip
                print("  " + (output.splitlines()[-1][:200] if output else "(no output)"))
                check_database(codes, values, versions)
    finally:
        from django.db import connections

        connections.close_all()
        if not args.keep:
            recreate_database(server, args.scratch_db, drop_only=True)


if __name__ == "__main__":
    main()
