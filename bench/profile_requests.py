#!/usr/bin/env python3
"""CPU per request of the load test's lab requests, in process (bench/README.md, "Load test").

Every request goes through the whole WSGI stack (Django's ``WSGIHandler``, all the
middleware) with production settings (``DEBUG=false``), against the database and cache
of the environment, with the keys of the fixture written by ``bench_load.py setup``
(50 labs in turn). Prints the CPU time (``time.process_time``) per request of each
endpoint; ``--profile NAME`` adds a cProfile (CPU time) of that endpoint.

    DATABASE_URL=postgres://postgres@127.0.0.1:5432/h8l CACHE_URL=redis://127.0.0.1:6379/13 \\
    .venv/bin/python bench/profile_requests.py --fixture /tmp/pt-load/fixture.json -n 300

Run it against another checkout (``--root``) to compare two versions of the code on the
same data. The submission endpoint stores a new version per request (as the load test).
"""

from __future__ import annotations

import argparse
import cProfile
import io
import json
import os
import pstats
import random
import sys
import time
from collections.abc import Callable
from pathlib import Path

API = "/api/v1"
ENDPOINTS = ("list", "detail", "measurands", "history", "version", "submit")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("endpoints", nargs="*", help=f"some of {', '.join(ENDPOINTS)} (all)")
    parser.add_argument("--fixture", default="/tmp/pt-load/fixture.json")
    parser.add_argument("--root", default=str(Path(__file__).resolve().parent.parent))
    parser.add_argument("-n", type=int, default=300, help="requests per endpoint (POST: n/10)")
    parser.add_argument("--profile", choices=ENDPOINTS, help="cProfile this endpoint")
    parser.add_argument("--sql", choices=ENDPOINTS, help="print the SQL of one such request")
    args = parser.parse_args()
    args.endpoints = args.endpoints or list(ENDPOINTS)
    if unknown := set(args.endpoints) - set(ENDPOINTS):
        parser.error(f"unknown endpoints: {', '.join(sorted(unknown))}")

    sys.path.insert(0, args.root)
    os.environ.update(
        DEBUG="false", SECRET_KEY=os.environ.get("SECRET_KEY") or "p" * 60,
        ALLOWED_HOSTS="127.0.0.1,localhost", SECURE_SSL_REDIRECT="false",
        SESSION_COOKIE_SECURE="false", CSRF_COOKIE_SECURE="false",
        CONN_MAX_AGE=os.environ.get("CONN_MAX_AGE", "60"),
        DJANGO_SETTINGS_MODULE="config.settings",
    )  # fmt: skip
    import django

    django.setup()
    from django.core.handlers.wsgi import WSGIHandler

    app = WSGIHandler()
    fixture = json.loads(Path(args.fixture).read_text())
    code, keys = fixture["open"], [lab["key"] for lab in fixture["labs"]]
    rng = random.Random(1)
    paths = {
        "list": ("GET", f"{API}/comparisons/"),
        "detail": ("GET", f"{API}/comparisons/{code}/"),
        "measurands": ("GET", f"{API}/comparisons/{code}/measurands/"),
        "history": ("GET", f"{API}/comparisons/{code}/submissions/"),
        "version": ("GET", f"{API}/comparisons/{code}/submissions/1/"),
        "submit": ("POST", f"{API}/comparisons/{code}/submissions/"),
    }

    def body() -> bytes:
        bias = rng.gauss(0, 0.004)
        rows = [
            r | {"sensitivity": round(418 * (1 + bias + rng.gauss(0, 0.0025)), 2),
                 "expanded_uncertainty": round(418 * rng.uniform(0.012, 0.024), 2)}
            for r in fixture["records"]
        ]  # fmt: skip
        return json.dumps({"results": rows, "submit": rng.random() < 0.75}).encode()

    def request(name: str, i: int) -> None:
        method, path = paths[name]
        data = body() if method == "POST" else b""
        environ = {
            "REQUEST_METHOD": method, "PATH_INFO": path, "QUERY_STRING": "",
            "SERVER_NAME": "127.0.0.1", "SERVER_PORT": "8765", "SERVER_PROTOCOL": "HTTP/1.1",
            "wsgi.url_scheme": "http", "wsgi.input": io.BytesIO(data),
            "wsgi.errors": sys.stderr, "wsgi.version": (1, 0), "wsgi.multithread": False,
            "wsgi.multiprocess": True, "wsgi.run_once": False, "REMOTE_ADDR": "127.0.0.1",
            "HTTP_HOST": "127.0.0.1:8765", "HTTP_ACCEPT": "*/*", "HTTP_USER_AGENT": "bench",
            "HTTP_AUTHORIZATION": f"Api-Key {keys[i % len(keys)]}",
            "CONTENT_LENGTH": str(len(data)), "CONTENT_TYPE": "application/json",
        }  # fmt: skip
        status: list[str] = []

        def start_response(s: str, h: object, e: object = None) -> Callable[[bytes], object]:
            status.append(s)
            return lambda data: None  # PEP 3333's write(): the app returns its body instead

        b"".join(app(environ, start_response))
        if not status[0].startswith(("200", "201")):
            sys.exit(f"{name}: {status[0]} (a key throttled or revoked? fresh fixture?)")

    for name in args.endpoints:
        n = args.n if paths[name][0] == "GET" else max(args.n // 10, 10)
        for i in range(5):
            request(name, i)
        start, db_start = time.process_time(), backend_cpu()
        for i in range(n):
            request(name, i)
        cpu = (time.process_time() - start) / n * 1000
        db_end = backend_cpu()
        db = (
            ""
            if db_start is None or db_end is None
            else f", database {(db_end - db_start) / n * 1e3:5.2f} ms"
        )
        print(f"{name:12s} {cpu:6.2f} ms CPU per request{db} ({n} requests)", flush=True)
    if args.sql:
        from django.db import connection
        from django.test.utils import CaptureQueriesContext

        with CaptureQueriesContext(connection) as queries:
            request(args.sql, 0)
        for i, query in enumerate(queries.captured_queries, 1):
            print(f"{i:3d} {query['time']}s {query['sql']}")
    if args.profile:
        profile = cProfile.Profile(time.process_time)
        profile.enable()
        for i in range(args.n):
            request(args.profile, i)
        profile.disable()
        pstats.Stats(profile).sort_stats("cumulative").print_stats(60)


def backend_cpu() -> float | None:
    """CPU seconds of this process's PostgreSQL backend (same machine), or None."""
    from django.db import connection

    if connection.vendor != "postgresql":
        return None
    with connection.cursor() as cursor:
        cursor.execute("SELECT pg_backend_pid()")
        pid = cursor.fetchone()[0]
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except OSError:
        return None
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


if __name__ == "__main__":
    main()
