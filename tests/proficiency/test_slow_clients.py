"""The production web server (gunicorn with ``deploy/gunicorn.conf.py``) and slow clients.

A client that sends half its headers and waits held a whole sync worker: with as many
such connections as workers (two by default on a small host), ``/healthz`` and every
other request waited for the worker timeout. The threaded workers keep answering, and a
connection silent for ``GUNICORN_READ_TIMEOUT`` seconds is closed, freeing its thread.

Each test starts gunicorn on a free port of 127.0.0.1 with production settings (the
database and broker of the environment; ``/healthz`` answers 200 or its documented 503).
"""

from __future__ import annotations

import contextlib
import http.client
import json
import os
import select
import socket
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

import pytest

ROOT = Path(__file__).resolve().parents[2]
GUNICORN = Path(sys.executable).parent / "gunicorn"
WORKERS = 2
#: a partial request: the request line and one header, never the blank line that ends them
PARTIAL = b"GET /healthz HTTP/1.1\r\nHost: 127.0.0.1\r\n"
#: the generous bound for an answer that must not wait for the slow clients
ANSWER_WITHIN = 15.0


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def healthz(port: int, timeout: float) -> tuple[int, dict]:
    conn = http.client.HTTPConnection("127.0.0.1", port, timeout=timeout)
    try:
        conn.request("GET", "/healthz", headers={"Host": "127.0.0.1"})
        response = conn.getresponse()
        return response.status, json.loads(response.read())
    finally:
        conn.close()


@contextlib.contextmanager
def gunicorn(log: Path | None = None, **extra: str) -> Iterator[int]:
    port = free_port()
    env = {k: v for k, v in os.environ.items() if not k.startswith(("DEBUG", "SECURE_"))}
    env.update(
        DEBUG="false", SECRET_KEY="x" * 60 + "-test-slow-clients", ALLOWED_HOSTS="127.0.0.1",
        EMAIL_URL="smtp://127.0.0.1:25", GUNICORN_BIND=f"127.0.0.1:{port}",
        WEB_CONCURRENCY=str(WORKERS), LOG_FORMAT="plain",
        # its own database: /healthz then answers whatever database DATABASE_URL names
        # (a CI_DATABASE_URL that pytest never creates gave 503s with tracebacks); a test
        # that uploads gives the test database instead
        DATABASE_URL=f"sqlite:///{tempfile.mkdtemp(prefix='slow-clients-')}/db.sqlite3",
    )  # fmt: skip
    env.update(extra)
    out = log.open("wb") if log else subprocess.DEVNULL
    proc = subprocess.Popen(
        [str(GUNICORN), "-c", str(ROOT / "deploy" / "gunicorn.conf.py")],
        cwd=ROOT, env=env, stdout=out, stderr=subprocess.STDOUT,
    )  # fmt: skip
    try:
        deadline = time.monotonic() + 60
        while True:  # up: both workers have imported Django (the first answer comes after)
            try:
                healthz(port, timeout=20)
                break
            except OSError:
                if proc.poll() is not None or time.monotonic() > deadline:
                    pytest.fail(f"gunicorn did not start (exit status {proc.poll()})")
                time.sleep(0.2)
        for _ in range(2 * WORKERS):  # every worker has answered once
            healthz(port, timeout=20)
        yield port
    finally:
        proc.terminate()
        try:
            proc.wait(timeout=30)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
        if not isinstance(out, int):  # the log file, not DEVNULL
            out.close()


def slow_clients(port: int, n: int) -> list[socket.socket]:
    clients = []
    for _ in range(n):
        s = socket.create_connection(("127.0.0.1", port), timeout=5)
        s.sendall(PARTIAL)
        clients.append(s)
    time.sleep(0.5)  # the server has taken them (a sync worker would now be reading one)
    return clients


def test_healthz_answers_while_more_slow_clients_than_workers_wait():
    with gunicorn() as port:
        held = slow_clients(port, WORKERS + 1)
        try:
            status, body = healthz(port, timeout=ANSWER_WITHIN)
            assert status in (200, 503)  # 503: the environment's database or broker is down
            assert set(body) == {"database", "broker"}
            # the slow clients are still connected, waiting: none was answered or closed
            for s in held:
                s.setblocking(False)
                with pytest.raises(BlockingIOError):
                    s.recv(1)
        finally:
            for s in held:
                s.close()


def test_a_silent_client_is_closed_after_the_read_timeout_freeing_its_thread(tmp_path):
    threads = 2
    log = tmp_path / "gunicorn.log"
    with gunicorn(log, GUNICORN_THREADS=str(threads), GUNICORN_READ_TIMEOUT="1") as port:
        held = slow_clients(port, WORKERS * threads + 1)  # more than all the threads
        try:
            status, _ = healthz(port, timeout=ANSWER_WITHIN)
            assert status in (200, 503)
            closed = 0
            for s in held:  # the server closed each of them (no answer to half a request)
                s.settimeout(ANSWER_WITHIN)
                with contextlib.suppress(ConnectionResetError):
                    closed += s.recv(1024) == b""
            assert closed == len(held)
        finally:
            for s in held:
                s.close()
    # each cut client is one INFO line, never a traceback
    text = log.read_text()
    assert text.count("Closed a connection silent past the read timeout") == len(held), text
    assert "Traceback" not in text and "Socket error processing request" not in text


# --- a results upload with the quantity column, sent slowly -----------------------------------

UPLOAD_CSV = (
    b"device,axis,frequency_hz,bench,direction,quantity,sensitivity,expanded_uncertainty\n"
    b"MEMS 1,X,10,curvilinear,tangential,magnitude,418.5,1.5%\n"
    b"MEMS 1,X,10,curvilinear,tangential,phase,540,0.5\n"
)
BOUNDARY = "slow-client-boundary"


def upload_request(code: str, key: str, csv: bytes = UPLOAD_CSV) -> tuple[bytes, bytes]:
    """The headers and the multipart body of a draft upload through the API, as a lab's
    software behind the reverse proxy sends it (``X-Forwarded-Proto: https``)."""
    body = (
        (
            f'--{BOUNDARY}\r\nContent-Disposition: form-data; name="submit"\r\n\r\nfalse\r\n'
            f'--{BOUNDARY}\r\nContent-Disposition: form-data; name="file"; filename="r.csv"\r\n'
            "Content-Type: text/csv\r\n\r\n"
        ).encode()
        + csv
        + f"\r\n--{BOUNDARY}--\r\n".encode()
    )
    head = (
        f"POST /api/v1/comparisons/{code}/submissions/upload/ HTTP/1.1\r\nHost: 127.0.0.1\r\n"
        f"X-Forwarded-Proto: https\r\nAuthorization: Api-Key {key}\r\n"
        f"Content-Type: multipart/form-data; boundary={BOUNDARY}\r\n"
        f"Content-Length: {len(body)}\r\nConnection: close\r\n\r\n"
    ).encode()
    return head, body


def slow_upload(port: int, head: bytes, body: bytes, how: str) -> tuple[float, bytes]:
    """One slow client: ``silent`` sends its headers and half the body, then nothing;
    ``trickle`` sends its headers, then the body a byte every 0.3 s, never silent for a
    second; ``trickle-head`` the headers too. How long the server kept it, and the first
    bytes of its answer (empty: closed without one)."""
    first, rest = {
        "silent": (head + body[: len(body) // 2], b""),
        "trickle": (head, body),
        "trickle-head": (b"", head + body),
    }[how]
    start = time.monotonic()
    with socket.create_connection(("127.0.0.1", port), timeout=5) as s:
        s.sendall(first)
        pending = iter(rest)
        while time.monotonic() - start < 60:
            readable, _, _ = select.select([s], [], [], 0.3)
            if readable:
                try:
                    return time.monotonic() - start, s.recv(200)
                except ConnectionResetError:
                    return time.monotonic() - start, b""
            byte = next(pending, None)
            if byte is not None:
                with contextlib.suppress(OSError):
                    s.sendall(bytes([byte]))
    return time.monotonic() - start, b"still held"


def whole_request(port: int, request: bytes) -> bytes:
    with socket.create_connection(("127.0.0.1", port), timeout=ANSWER_WITHIN) as s:
        s.sendall(request)
        return s.recv(200)


@pytest.mark.django_db(transaction=True)
def test_a_slow_upload_is_cut_in_bounded_time_and_stores_nothing(tmp_path, needs_postgres):
    """More slow uploads than threads — trickling the body or the headers a byte at a time
    without ever falling silent for the read timeout, or silent half-way through the body —
    and a complete upload meanwhile. A trickling client held its thread for as long as it
    kept trickling (the read timeout bounds silence only), so as many as threads stalled
    the service; a body cut short was a 500 with a traceback. Now every slow client is cut
    within the read timeout plus its bytes at GUNICORN_MIN_RATE, a body cut short is a 408,
    nothing of it is stored, and the complete upload is answered and stored."""
    from django.db import connection

    from labs.models import Result, Submission
    from labs.services import api_key_create
    from proficiency.services import measurement_points_generate
    from tests.factories import ComparisonFactory, DeviceFactory, ParticipantFactory

    comparison = ComparisonFactory.create(code="SLOW-Q", status="open", protocol="custom")
    device = DeviceFactory.create(comparison=comparison, name="MEMS 1", unit="D/(m/s^2)")
    measurement_points_generate(
        comparison=comparison, devices=[device], axes=["X"], frequencies_hz=[10],
        benches=["curvilinear"], directions=["tangential"], quantities=["magnitude", "phase"],
    )  # fmt: skip
    participant = ParticipantFactory.create(comparison=comparison, code="L09")
    key = api_key_create(laboratory=participant.laboratory, name="daq", user=None)[1]
    db = connection.settings_dict  # the test database: gunicorn sees what the test wrote
    password = f":{db['PASSWORD']}" if db["PASSWORD"] else ""
    url = f"postgres://{db['USER']}{password}@{db['HOST']}:{db['PORT']}/{db['NAME']}"
    head, body = upload_request("SLOW-Q", key)
    log = tmp_path / "gunicorn.log"
    threads = 2
    kinds = ["trickle"] * (WORKERS * threads) + ["trickle-head", "silent"]
    with (
        gunicorn(log, DATABASE_URL=url, GUNICORN_THREADS=str(threads),
                 GUNICORN_READ_TIMEOUT="1", GUNICORN_MIN_RATE="2000") as port,
        ThreadPoolExecutor(len(kinds)) as pool,
    ):  # fmt: skip
        slow = [pool.submit(slow_upload, port, head, body, how) for how in kinds]
        time.sleep(0.5)  # every thread of the server is reading a slow client
        status, _ = healthz(port, timeout=ANSWER_WITHIN)
        assert status in (200, 503)
        answer = whole_request(port, head + body)
        assert answer.startswith(b"HTTP/1.1 201 Created"), answer
        ended = [f.result(timeout=90) for f in slow]
    for how, (held, answered) in zip(kinds, ended, strict=True):
        assert held < 10, (how, held, answered)  # not the 60 s a trickle would have lasted
        if how == "trickle-head":  # no request to answer: closed
            assert answered == b"", answered
        else:
            assert answered.startswith(b"HTTP/1.1 408 Request Timeout"), (how, answered)
    (submission,) = Submission.objects.all()  # the complete upload's draft, nothing else
    phase = Result.objects.get(submission=submission, measurement_point__quantity="phase")
    assert (phase.value, phase.unit) == (180.0, "deg")
    text = log.read_text()
    assert "Traceback" not in text and "Internal Server Error" not in text, text
    assert text.count("Closed a connection sending its request too slowly") == 1, text
    assert text.count("status=408") == len(kinds) - 1, text


class _CutShort:
    """A request body whose client stopped sending: the socket's timeout, as gunicorn's
    reader raises it (deploy/gunicorn.conf.py)."""

    def read(self, *args: object) -> bytes:
        raise TimeoutError("the request arrived too slowly")

    readline = read


@pytest.mark.django_db
@pytest.mark.parametrize(
    ("path", "content_type", "expected"),
    [
        ("/accounts/login/", "application/x-www-form-urlencoded", "text/plain; charset=utf-8"),
        ("/api/v1/comparisons/IMU-A-01/submissions/", "application/json", "application/json"),
        ("/api/v1/comparisons/IMU-A-01/submissions/upload/",
         "multipart/form-data; boundary=x", "application/json"),
    ],
)  # fmt: skip
def test_a_body_cut_short_is_408_not_a_server_error(settings, caplog, path, content_type, expected):
    """It was a 500 with a traceback, for a client's fault; now 408, one warning line."""
    from django.test import Client

    from tests.labs.api import build_world

    settings.DEBUG = False
    key = build_world().keys["key_a"]
    extra: dict[str, Any] = {"wsgi.input": _CutShort()}  # the body the client stopped sending
    answer = Client().generic(
        "POST", path, b"x" * 500, content_type, secure=True,
        headers={"Authorization": f"Api-Key {key}"}, **extra,
    )  # fmt: skip
    assert answer.status_code == 408, answer.content
    assert answer["Content-Type"] == expected
    text = answer.content.decode()
    if expected == "application/json":
        assert json.loads(text) == {
            "detail": "The request did not arrive whole (the request arrived too slowly); "
            "nothing was stored. Send it again.",
            "errors": [],
        }
    else:
        assert text.startswith("The request did not arrive whole")
    assert not [r for r in caplog.records if r.levelname == "ERROR" or r.exc_info], caplog.text
