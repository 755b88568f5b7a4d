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
import socket
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path

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
        # (a CI_DATABASE_URL that pytest never creates gave 503s with tracebacks)
        DATABASE_URL=f"sqlite:///{tempfile.mkdtemp(prefix='slow-clients-')}/db.sqlite3", **extra,
    )  # fmt: skip
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
