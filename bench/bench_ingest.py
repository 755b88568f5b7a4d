"""Ingest benchmark of the REST API (a script, not a test).

    .venv/bin/python bench/bench_ingest.py [--repeat 3] [--keep]

Creates a scratch PostgreSQL database ``pt_bench`` on the server of DATABASE_URL
(default postgres://postgres@127.0.0.1:5432/test; that database itself is not touched),
migrates it, builds two open comparisons (10,000 and 100,000 measurement points, one
participating laboratory with an API key), starts ``manage.py runserver --noreload`` on a
free 127.0.0.1 port against it and times, over HTTP with the key:

  (a) one POST /submissions/ with 10,000 JSON results, submitted   target < 3 s
  (b) one upload of a 100,000-row CSV, submitted                    target < 20 s

then, in this process, the same two inputs through the service with the parse and the
store timed separately. Prints times and PASS/FAIL, stops the server, drops ``pt_bench``
(unless --keep). The server runs with DEBUG off (no SQL query log), like production.
"""

from __future__ import annotations

import argparse
import json
import os
import socket
import statistics
import subprocess
import sys
import time
from pathlib import Path
from typing import Any
from urllib.parse import urlsplit, urlunsplit

import psycopg
import requests

ROOT = Path(__file__).resolve().parent.parent
SCRATCH_DB = "pt_bench"
TARGET_A_S, TARGET_B_S = 3.0, 20.0
# (a) 25 devices × 2 axes × 200 frequencies; (b) 100 devices × 2 axes × 500 frequencies
GRID_A = ("BENCH-10K", 25, 200)
GRID_B = ("BENCH-100K", 100, 500)


def scratch_url(admin_url: str) -> str:
    parts = urlsplit(admin_url)
    return urlunsplit(parts._replace(path=f"/{SCRATCH_DB}"))


def recreate_database(admin_url: str, *, drop_only: bool = False) -> None:
    with psycopg.connect(admin_url, autocommit=True) as conn:
        conn.execute(f"DROP DATABASE IF EXISTS {SCRATCH_DB} WITH (FORCE)")
        if not drop_only:
            conn.execute(f"CREATE DATABASE {SCRATCH_DB}")


def server_env(db_url: str) -> dict[str, str]:
    return {
        **os.environ,
        "DATABASE_URL": db_url,
        "DEBUG": "false",
        "EMAIL_URL": os.environ.get("EMAIL_URL", "dummymail://"),
        "SECRET_KEY": "bench-only-not-a-secret-bench-only-not-a-secret",
        "SECURE_SSL_REDIRECT": "false",
        "LOG_LEVEL": "WARNING",
        "THROTTLE_API_KEY": "100000/min",
    }


def setup_django(db_url: str) -> None:
    os.environ.update(server_env(db_url))
    os.environ.setdefault("DJANGO_SETTINGS_MODULE", "config.settings")
    sys.path.insert(0, str(ROOT))
    import django

    django.setup()


def build_data() -> str:
    """Two open comparisons and one participating lab; returns the lab's API key."""
    from labs.models import Laboratory
    from labs.services import api_key_create, participant_add
    from proficiency.models import Comparison, Device
    from proficiency.services import measurement_points_generate

    lab = Laboratory.objects.create(name="Bench Laboratory")
    for code, n_devices, n_freqs in (GRID_A, GRID_B):
        comparison = Comparison.objects.create(code=code, title=code, status="open")
        devices = Device.objects.bulk_create(
            Device(comparison=comparison, name=f"MEMS {i}") for i in range(1, n_devices + 1)
        )
        measurement_points_generate(
            comparison=comparison, devices=devices, axes=["X", "Y"],
            frequencies_hz=range(1, n_freqs + 1), benches=["linear"],
        )  # fmt: skip
        participant_add(comparison=comparison, laboratory=lab)
    return api_key_create(laboratory=lab, name="bench", user=None)[1]


def records(n_devices: int, n_freqs: int) -> list[dict[str, object]]:
    return [
        {"device": f"MEMS {d}", "axis": a, "frequency_hz": f, "bench": "linear",
         "sensitivity": round(415 + (d * 7 + f) % 100 / 10, 2), "expanded_uncertainty": 8.4}
        for d in range(1, n_devices + 1) for a in ("X", "Y") for f in range(1, n_freqs + 1)
    ]  # fmt: skip


def as_csv(rows: list[dict[str, object]]) -> bytes:
    names = list(rows[0])
    lines = [",".join(names), *(",".join(str(r[n]) for n in names) for r in rows)]
    return ("\n".join(lines) + "\n").encode()


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def start_server(db_url: str, port: int) -> subprocess.Popen:
    cmd = [sys.executable, "manage.py", "runserver", "--noreload", f"127.0.0.1:{port}"]
    # The access log goes nowhere; errors reach the client as JSON anyway.
    quiet: dict[str, Any] = {"stdout": subprocess.DEVNULL, "stderr": subprocess.DEVNULL}
    return subprocess.Popen(cmd, cwd=ROOT, env=server_env(db_url), **quiet)


def wait_ready(session: requests.Session, base: str, server: subprocess.Popen) -> None:
    for _ in range(300):
        if server.poll() is not None:
            raise SystemExit(f"runserver exited with {server.returncode}")
        try:
            if session.get(f"{base}/api/v1/comparisons/", timeout=2).status_code == 200:
                return
        except requests.ConnectionError:
            pass
        time.sleep(0.1)
    raise SystemExit("runserver did not answer within 30 s")


def timed(call, expect: int = 201) -> float:
    start = time.perf_counter()
    response = call()
    elapsed = time.perf_counter() - start
    if response.status_code != expect:
        raise SystemExit(f"HTTP {response.status_code}: {response.text[:500]}")
    return elapsed


def http_runs(key: str, port: int, body_a: bytes, csv_b: bytes, repeat: int) -> dict:
    base = f"http://127.0.0.1:{port}"
    session = requests.Session()
    session.headers["Authorization"] = f"Api-Key {key}"
    url_a = f"{base}/api/v1/comparisons/{GRID_A[0]}/submissions/"
    url_b = f"{base}/api/v1/comparisons/{GRID_B[0]}/submissions/upload/"
    headers = {"Content-Type": "application/json"}

    def post_a():
        return session.post(url_a, data=body_a, headers=headers, timeout=120)

    def post_b():
        return session.post(url_b, files={"file": ("results.csv", csv_b)}, timeout=600)

    return {
        "a": [timed(post_a) for _ in range(repeat)],
        "b": [timed(post_b) for _ in range(repeat)],
    }


def service_breakdown(code: str, parse) -> tuple[float, float]:
    """(parse, store) seconds of the service path, in this process."""
    from labs.models import Participant
    from labs.selectors import table_context
    from labs.services import submission_save

    participant = Participant.objects.select_related("comparison").get(comparison__code=code)
    start = time.perf_counter()
    rows = parse(table_context(participant.comparison))
    parsed = time.perf_counter()
    submission_save(participant=participant, rows=rows, source="api", user=None, submit=True)
    return parsed - start, time.perf_counter() - parsed


def breakdowns(rows_a: list, csv_b: bytes) -> dict[str, tuple[float, float]]:
    from labs.importers import parse_rows, parse_table

    return {
        "a": service_breakdown(
            GRID_A[0], lambda ctx: parse_rows(rows_a, lab_column="forbidden", context=ctx)
        ),
        "b": service_breakdown(
            GRID_B[0],
            lambda ctx: parse_table(
                csv_b, filename="results.csv", lab_column="forbidden", context=ctx
            ),
        ),
    }


def report(http: dict, split: dict, sizes: dict) -> bool:
    ok = True
    for name, label, target in (
        ("a", "(a) POST 10,000 JSON results", TARGET_A_S),
        ("b", "(b) upload 100,000-row CSV", TARGET_B_S),
    ):
        times = http[name]
        best, median = min(times), statistics.median(times)
        verdict = "PASS" if median < target else "FAIL"
        ok &= verdict == "PASS"
        runs = ", ".join(f"{t:.2f}" for t in times)
        print(f"{label} ({sizes[name] / 2**20:.2f} MiB): median {median:.2f} s, best {best:.2f} s "
              f"[{runs}]  target < {target:g} s  {verdict}")  # fmt: skip
        parse, store = split[name]
        print(f"    service in-process: parse+validate {parse:.2f} s, store {store:.2f} s")
    return ok


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeat", type=int, default=3, help="timed requests per case")
    parser.add_argument("--keep", action="store_true", help="keep the pt_bench database")
    args = parser.parse_args()
    admin_url = os.environ.get("DATABASE_URL", "postgres://postgres@127.0.0.1:5432/test")
    db_url = scratch_url(admin_url)
    recreate_database(admin_url)
    server = None
    try:
        env = server_env(db_url)
        subprocess.run([sys.executable, "manage.py", "migrate", "--noinput", "-v0"], cwd=ROOT,
                       env=env, check=True)  # fmt: skip
        setup_django(db_url)
        key = build_data()
        rows_a, rows_b = records(*GRID_A[1:]), records(*GRID_B[1:])
        body_a, csv_b = json.dumps({"results": rows_a, "submit": True}).encode(), as_csv(rows_b)
        port = free_port()
        server = start_server(db_url, port)
        session = requests.Session()
        session.headers["Authorization"] = f"Api-Key {key}"
        wait_ready(session, f"http://127.0.0.1:{port}", server)
        http = http_runs(key, port, body_a, csv_b, args.repeat)
        split = breakdowns(rows_a, csv_b)
        ok = report(http, split, {"a": len(body_a), "b": len(csv_b)})
    finally:
        if server is not None:
            server.terminate()
            server.wait(timeout=30)
        from django.db import connections

        connections.close_all()
        if not args.keep:
            recreate_database(admin_url, drop_only=True)
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
