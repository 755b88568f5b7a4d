#!/usr/bin/env python3
"""Load test of the production server: setup, ``make serve``, locust.

A script, not a test. Loopback only: the database, the broker and the server must
all be on this machine (127.0.0.1, localhost or ::1); anything else is refused.

    DATABASE_URL=postgres://postgres@127.0.0.1:5432/h8l \\
    CELERY_BROKER_URL=redis://127.0.0.1:6379/14 \\
    .venv/bin/python bench/bench_load.py run -u 52 -r 10 -t 60s

``setup`` alone (re)creates the scenario's data and writes the fixture file that
``bench/locustfile.py`` reads (keys and passwords, mode 600); ``run`` does the
setup, starts ``deploy/serve.py`` (what ``make serve`` runs: migrate,
collectstatic, check --deploy, gunicorn + Celery worker + beat, DEBUG=false) on
``127.0.0.1:PORT``, waits for ``/healthz``, runs locust headless with bounded
users and duration, stops the server and prints the overall and per-endpoint
figures (also as CSV under ``--out``).

Data (idempotent: ``LOAD-*`` comparisons are deleted and rebuilt each time):

* 50 laboratories ``Load Lab 01..50``, one fresh API key each (older keys revoked);
  ``Load Lab 01`` is the reference (pilot) laboratory of both comparisons;
* ``LOAD-OPEN``: open, the demo template ``linear_and_curvilinear`` (81 points),
  every lab a participant with one submitted version;
* ``LOAD-CLOSED``: closed, same 81 points, every lab an accepted version;
* two coordinators ``load-coord-1``/``-2`` (random passwords set at each setup)
  coordinating ``LOAD-CLOSED``.
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import resource
import secrets
import signal
import subprocess
import sys
import time
import urllib.request
from pathlib import Path
from typing import TYPE_CHECKING
from urllib.parse import urlparse

if TYPE_CHECKING:  # Django is set up in main()
    from proficiency.models import Comparison

ROOT = Path(__file__).resolve().parent.parent
LOOPBACK = {"127.0.0.1", "localhost", "::1"}
N_LABS = 50
OPEN_CODE, CLOSED_CODE = "LOAD-OPEN", "LOAD-CLOSED"
TEMPLATE = "linear_and_curvilinear"
COORDINATORS = ("load-coord-1", "load-coord-2")


def require_loopback(url: str, what: str) -> None:
    host = urlparse(url).hostname
    if host not in LOOPBACK:
        sys.exit(f"bench_load: {what} must be on this machine (loopback), got host {host!r}.")


# --- setup (Django, in process) ---------------------------------------------------------------


def setup(fixture: Path) -> dict:
    """Build the scenario's data and write the fixture file; returns its content."""
    sys.path.insert(0, str(ROOT))
    os.environ.setdefault("DJANGO_SETTINGS_MODULE", "config.settings")
    import django

    django.setup()
    from django.core.management import call_command

    call_command("migrate", "--noinput", verbosity=0)
    data = _build()
    _analyze()
    fixture.write_text(json.dumps(data, indent=1))
    fixture.chmod(0o600)
    return data


def _build() -> dict:
    from django.contrib.auth import get_user_model
    from django.db import transaction

    from labs.models import LabAPIKey, Laboratory
    from labs.services import api_key_create, participant_add, participant_set_reference
    from proficiency.models import Comparison
    from proficiency.services import comparison_create

    User = get_user_model()
    with transaction.atomic():
        _delete_previous(Comparison.objects.filter(code__in=[OPEN_CODE, CLOSED_CODE]))
        labs = [
            Laboratory.objects.get_or_create(name=f"Load Lab {i:02d}", defaults={"country": "IT"})[
                0
            ]
            for i in range(1, N_LABS + 1)
        ]
        LabAPIKey.objects.filter(laboratory__in=labs, revoked=False).update(revoked=True)
        coordinators, passwords = [], {}
        for username in COORDINATORS:
            user, _ = User.objects.get_or_create(username=username, defaults={"is_staff": True})
            passwords[username] = secrets.token_urlsafe(18)
            user.set_password(passwords[username])
            user.is_active = True
            user.save()
            coordinators.append(user)
        comparisons = {}
        for code in (OPEN_CODE, CLOSED_CODE):
            c = comparison_create(
                comparison=Comparison(code=code, title=f"Load test {code}"),
                template_key=TEMPLATE,
                user=coordinators[0],
            )
            c.coordinators.add(*coordinators)
            _points(c)
            comparisons[code] = c
        keys = []
        for lab in labs:
            _, key = api_key_create(laboratory=lab, name="load test", user=None)
            keys.append({"lab": lab.name, "key": key})
            for c in comparisons.values():
                p = participant_add(comparison=c, laboratory=lab)
                if lab == labs[0]:  # the pilot: the default assigned value is the reference lab's
                    participant_set_reference(participant=p)
    records = _records(comparisons[OPEN_CODE])
    _fill(comparisons, records)
    _reset_lockouts(COORDINATORS)
    return {
        "open": OPEN_CODE,
        "closed": CLOSED_CODE,
        "labs": keys,
        "coordinators": [{"username": u, "password": p} for u, p in passwords.items()],
        "records": records,
    }


def _analyze() -> None:
    """Refresh PostgreSQL's planner statistics of the fresh data, as autovacuum would.

    With autovacuum off (as on the bench machine: ``SHOW autovacuum``) the freshly filled
    tables have no statistics, and PostgreSQL answered every submission history by a
    sequential scan of the whole results table (18 ms per request at 31,000 rows, instead
    of 0.8 ms through the ``submission_id`` index): bench/README.md, "Load test"."""
    from django.db import connection

    if connection.vendor == "postgresql":
        with connection.cursor() as cursor:
            cursor.execute("ANALYZE")


def _delete_previous(comparisons: object) -> None:
    """The LOAD-* comparisons of an earlier setup, protected rows first (results, points)."""
    from analysis.models import Report
    from labs.models import Participant, Result
    from proficiency.models import Device, MeasurementPoint

    Report.objects.filter(comparison__in=comparisons).delete()
    Result.objects.filter(submission__participant__comparison__in=comparisons).delete()
    Participant.objects.filter(comparison__in=comparisons).delete()
    MeasurementPoint.objects.filter(comparison__in=comparisons).delete()
    Device.objects.filter(comparison__in=comparisons).delete()
    comparisons.delete()  # type: ignore[attr-defined]


def _points(comparison: Comparison) -> None:
    from proficiency.models import Device
    from proficiency.services import comparison_apply_template, comparison_transition

    devices = [
        Device.objects.create(
            comparison=comparison,
            name=f"MEMS {i}",
            model="LSM6DSR",
            serial=f"LOAD-{i:03d}",
            nominal_sensitivity=418.0,
            tolerance=1.0,
        )
        for i in (1, 2, 3)
    ]
    comparison_apply_template(comparison=comparison, template_key=TEMPLATE, devices=devices)
    comparison_transition(comparison=comparison, to="open")


def _records(comparison: Comparison) -> list[dict]:
    """The JSON rows of one complete submission (values filled in by the locustfile)."""
    from labs.selectors import results_template

    text = results_template(comparison, format="csv").decode("utf-8-sig")
    rows = list(csv.DictReader(text.splitlines()))
    return [{k: v for k, v in row.items() if v not in ("", None)} for row in rows]


def _fill(comparisons: dict, records: list[dict]) -> None:
    """One submitted version per lab in LOAD-OPEN; one accepted version per lab in LOAD-CLOSED."""
    import random

    from labs.models import Submission
    from labs.services import submission_from_records, submission_transition
    from proficiency.services import comparison_transition

    rng = random.Random(8)
    for code, c in comparisons.items():
        for participant in c.participants.all():
            bias = rng.gauss(0, 0.004)
            rows = [
                r | {"sensitivity": round(418 * (1 + bias + rng.gauss(0, 0.0025)), 2),
                     "expanded_uncertainty": round(418 * rng.uniform(0.012, 0.024), 2)}
                for r in records
            ]  # fmt: skip
            s = submission_from_records(
                participant=participant, records=rows, source=Submission.Source.API,
                user=None, submit=True,
            )  # fmt: skip
            if code == CLOSED_CODE:
                submission_transition(submission=s, to=Submission.Status.ACCEPTED)
        if code == CLOSED_CODE:
            comparison_transition(comparison=c, to="closed")


def _reset_lockouts(usernames: tuple[str, ...]) -> None:
    try:
        from axes.utils import reset
    except ImportError:  # pragma: no cover - axes is a runtime dependency
        return
    for username in usernames:
        reset(username=username)


# --- run --------------------------------------------------------------------------------------


def server_env(port: int, state: Path) -> dict[str, str]:
    env = dict(os.environ)
    env.update(
        DEBUG="false",
        EMAIL_URL=env.get("EMAIL_URL") or "dummymail://",
        SECRET_KEY=env.get("SECRET_KEY") or secrets.token_urlsafe(64),
        ALLOWED_HOSTS="127.0.0.1,localhost",
        GUNICORN_BIND=f"127.0.0.1:{port}",
        # plain http on loopback: no TLS proxy in front (README, "Running in production")
        SECURE_SSL_REDIRECT="false",
        SESSION_COOKIE_SECURE="false",
        CSRF_COOKIE_SECURE="false",
        STATIC_ROOT=str(state / "static"),
        MEDIA_ROOT=str(state / "media"),
        CONN_MAX_AGE=env.get("CONN_MAX_AGE", "60"),
    )
    return env


def wait_healthy(url: str, timeout: float = 120) -> None:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        try:
            with urllib.request.urlopen(url + "/healthz", timeout=3) as r:
                if r.status == 200:
                    return
        except OSError:
            pass
        time.sleep(1)
    sys.exit(f"bench_load: {url}/healthz did not answer 200 within {timeout:.0f} s")


def cpu_times() -> tuple[int, int]:
    """(busy, total) jiffies of all CPUs, from /proc/stat (idle = idle + iowait)."""
    fields = [int(x) for x in Path("/proc/stat").read_text().split("\n")[0].split()[1:]]
    total = sum(fields[:8])
    return total - fields[3] - fields[4], total


def process_cpu() -> dict[str, float]:
    """CPU seconds (user + system) used so far by each kind of process on the machine."""
    tick = os.sysconf("SC_CLK_TCK")
    kinds: dict[str, float] = {}
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rpartition(")")[2].split()
            cmdline = (stat.parent / "cmdline").read_bytes().replace(b"\0", b" ").decode()
        except OSError:
            continue
        kind = next(
            (k for k in ("gunicorn", "celery", "locust", "postgres", "redis", "serve.py")
             if k in cmdline), "other"
        )  # fmt: skip
        if "worker" in cmdline and kind == "celery":
            kind = "celery worker"
        kinds[kind] = kinds.get(kind, 0.0) + (int(fields[11]) + int(fields[12])) / tick
    return kinds


def warm_up(url: str, fixture: dict, rounds: int = 6) -> None:
    """Touch every lab endpoint from several threads so each gunicorn worker has loaded its
    code paths (Django imports views, templates and serializers on first use); not timed."""
    from concurrent.futures import ThreadPoolExecutor

    code = fixture["open"]
    paths = ["/accounts/login/"] + [
        f"/api/v1/comparisons/{p}"
        for p in ("", f"{code}/", f"{code}/measurands/", f"{code}/submissions/",
                  f"{code}/submissions/1/")
    ]  # fmt: skip

    def get(i: int) -> None:
        key = fixture["labs"][i % len(fixture["labs"])]["key"]
        for path in paths:
            req = urllib.request.Request(url + path, headers={"Authorization": f"Api-Key {key}"})
            with urllib.request.urlopen(req, timeout=60) as r:
                r.read()

    with ThreadPoolExecutor(max_workers=8) as pool:
        list(pool.map(get, range(8 * rounds)))


def run(args: argparse.Namespace) -> int:
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    fixture = out / "fixture.json"
    print(f"bench_load: setup -> {fixture}", flush=True)
    data = setup(fixture)
    url = f"http://127.0.0.1:{args.port}"
    log = (out / "serve.log").open("w")
    env = server_env(args.port, out)
    server = subprocess.Popen(
        [sys.executable, str(ROOT / "deploy" / "serve.py")], cwd=ROOT, env=env,
        stdout=log, stderr=subprocess.STDOUT, start_new_session=True,
    )  # fmt: skip
    try:
        wait_healthy(url)
        print(f"bench_load: server up at {url} (log {out / 'serve.log'}); warming up", flush=True)
        warm_up(url, data)
        cmd = [
            str(Path(sys.executable).parent / "locust"),
            "-f", str(ROOT / "bench" / "locustfile.py"),
            "--headless", "-u", str(args.users), "-r", str(args.spawn_rate), "-t", args.time,
            "--host", url, "--csv", str(out / "load"), "--only-summary", "--stop-timeout", "10",
        ]  # fmt: skip
        print("bench_load: " + " ".join(cmd), flush=True)
        lenv = dict(os.environ, LOAD_FIXTURE=str(fixture))
        before, procs_before = cpu_times(), process_cpu()
        children_before = resource.getrusage(resource.RUSAGE_CHILDREN)
        status = subprocess.run(cmd, cwd=ROOT, env=lenv).returncode
        children = resource.getrusage(resource.RUSAGE_CHILDREN)
        busy, total = (a - b for a, b in zip(cpu_times(), before, strict=True))
        print(f"bench_load: machine CPU busy during the test: {100 * busy / total:.0f} %")
        after = process_cpu()
        spent = {k: after.get(k, 0) - procs_before.get(k, 0) for k in after}
        # locust itself (waited for, so its CPU is in RUSAGE_CHILDREN; the sampler misses it)
        spent["locust"] = (children.ru_utime + children.ru_stime) - (
            children_before.ru_utime + children_before.ru_stime
        )
        print("bench_load: CPU seconds by process kind: " + ", ".join(
            f"{k} {v:.1f}" for k, v in sorted(spent.items(), key=lambda kv: -kv[1]) if v > 0.05
        ))  # fmt: skip
        requests = _total_requests(out / "load_stats.csv")
        if requests:
            per = {k: 1000 * spent.get(k, 0) / requests for k in ("gunicorn", "locust")}
            print(
                f"bench_load: CPU per request: gunicorn {per['gunicorn']:.1f} ms, "
                f"locust {per['locust']:.1f} ms ({requests} requests)"
            )
    finally:
        server.send_signal(signal.SIGTERM)
        try:
            server.wait(timeout=60)
        except subprocess.TimeoutExpired:
            server.kill()
        log.close()
    summarise(out / "load_stats.csv")
    return status


def _total_requests(stats_csv: Path) -> int:
    if not stats_csv.exists():
        return 0
    rows = [r for r in csv.DictReader(stats_csv.open()) if r["Name"] == "Aggregated"]
    return int(rows[0]["Request Count"]) if rows else 0


def summarise(stats_csv: Path) -> None:
    """Per endpoint and overall: requests, failures, req/s, p50/p95/p99, as a markdown table."""
    rows = list(csv.DictReader(stats_csv.open()))
    print("\n| endpoint | requests | failures | req/s | p50 ms | p95 ms | p99 ms | max ms |")
    print("| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: |")
    for r in rows:
        name = "**all**" if r["Name"] == "Aggregated" else f"{r['Type']} {r['Name']}"
        print(
            f"| {name} | {r['Request Count']} | {r['Failure Count']} | "
            f"{float(r['Requests/s']):.1f} | {r['50%']} | {r['95%']} | {r['99%']} | "
            f"{float(r['Max Response Time']):.0f} |"
        )


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = parser.add_subparsers(dest="command", required=True)
    p_setup = sub.add_parser("setup", help="(re)create the data and write the fixture file")
    p_setup.add_argument("--fixture", default="/tmp/pt-load/fixture.json")
    p_run = sub.add_parser("run", help="setup, start the production server, run locust")
    p_run.add_argument("-u", "--users", type=int, default=52, help="50 labs + 2 coordinators")
    p_run.add_argument("-r", "--spawn-rate", type=float, default=10)
    p_run.add_argument("-t", "--time", default="60s", help="duration, at most 10m")
    p_run.add_argument("--port", type=int, default=8765)
    p_run.add_argument("--out", default="/tmp/pt-load", help="fixture, server log, locust CSV")
    args = parser.parse_args(argv)
    for name in ("DATABASE_URL", "CELERY_BROKER_URL"):
        if not os.environ.get(name):
            sys.exit(f"bench_load: set {name} (loopback PostgreSQL / Redis)")
        require_loopback(os.environ[name], name)
    if args.command == "setup":
        Path(args.fixture).parent.mkdir(parents=True, exist_ok=True)
        data = setup(Path(args.fixture))
        print(
            f"bench_load: {len(data['labs'])} labs, {len(data['records'])} points -> {args.fixture}"
        )
        return 0
    if not 1 <= args.users <= 200:
        sys.exit("bench_load: --users must be 1..200 (bounded load)")
    if _seconds(args.time) > 600:
        sys.exit("bench_load: --time must be at most 10m (bounded duration)")
    return run(args)


def _seconds(text: str) -> float:
    units = {"s": 1, "m": 60, "h": 3600}
    return float(text[:-1]) * units[text[-1]] if text[-1] in units else float(text)


if __name__ == "__main__":
    sys.exit(main())
