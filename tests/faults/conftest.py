"""Fault tests with the real components: PostgreSQL, Redis and Celery worker processes.

They need a PostgreSQL ``DATABASE_URL`` and a Redis ``CELERY_BROKER_URL``.  Without them
every test here is skipped with a loud message, unless ``REQUIRE_SERVICES=1`` (set by
``.ci/run``): then their absence is a failure.  Outages are simulated with the tests'
own means (a TCP proxy the test cuts, ``pg_terminate_backend`` on the test database's
own connections, SIGKILL of the test's own worker processes), never by touching the
servers.
"""

from __future__ import annotations

import contextlib
import os
import select
import socket
import subprocess
import sys
import threading
import time
import uuid
from collections.abc import Callable, Iterator
from pathlib import Path
from urllib.parse import urlsplit

import pytest

BROKER = os.environ.get("CELERY_BROKER_URL", "")
DATABASE_URL = os.environ.get("DATABASE_URL", "")
REQUIRED = os.environ.get("REQUIRE_SERVICES") == "1"
ROOT = Path(__file__).resolve().parents[2]
BANNER = "FAULT TESTS NOT RUN"


def _reachable(url: str, default_port: int) -> bool:
    parts = urlsplit(url)
    try:
        socket.create_connection(
            (parts.hostname or "127.0.0.1", parts.port or default_port), 2
        ).close()
    except OSError:
        return False
    return True


def missing_services() -> str:
    """Why the fault tests cannot run here ("" when they can)."""
    why = []
    if not DATABASE_URL.startswith("postgres"):
        why.append(f"DATABASE_URL is not PostgreSQL ({DATABASE_URL or 'unset'})")
    elif not _reachable(DATABASE_URL, 5432):
        why.append(f"PostgreSQL at {DATABASE_URL} is unreachable")
    if not BROKER.startswith("redis://"):
        why.append(f"CELERY_BROKER_URL is not Redis ({BROKER or 'unset'})")
    elif not _reachable(BROKER, 6379):
        why.append(f"Redis at {BROKER} is unreachable")
    return "; ".join(why)


MISSING = missing_services()


@pytest.fixture(autouse=True)
def require_services() -> None:
    if not MISSING:
        return
    message = f"{BANNER}: {MISSING}"
    if REQUIRED:
        pytest.fail(f"{message} (REQUIRE_SERVICES=1: the real services are required)")
    pytest.skip(message)


def pytest_terminal_summary(terminalreporter) -> None:
    if MISSING and any(
        "tests/faults" in str(getattr(r, "nodeid", ""))
        for r in terminalreporter.stats.get("skipped", [])
    ):
        line = "!" * 78
        terminalreporter.write_line(line, red=True, bold=True)
        terminalreporter.write_line(f"{BANNER} (skipped): {MISSING}", red=True, bold=True)
        terminalreporter.write_line(line, red=True, bold=True)


# --- worker processes ----------------------------------------------------------------------


class Workers:
    """Celery worker processes (solo pool) on one fresh queue, against the test database."""

    def __init__(self, queue: str) -> None:
        self.queue = queue
        self.procs: list[subprocess.Popen] = []

    def start(self, name: str, pool: str = "solo", **env_extra: str) -> subprocess.Popen:
        from django.db import connection

        test_db = DATABASE_URL.rsplit("/", 1)[0] + "/" + connection.settings_dict["NAME"]
        env = os.environ | {
            "DATABASE_URL": test_db,
            "CELERY_BROKER_URL": BROKER,
            "FAULT_QUEUE": self.queue,
            "CHART_WARMING": "false",  # no chart drawing after the runs these tests watch
        }
        env |= env_extra
        proc = subprocess.Popen(
            [sys.executable, "-m", "celery", "-A", "tests.faults.worker_app", "worker",
             "-P", pool, *(["-c", "1"] if pool == "prefork" else []), "-Q", self.queue,
             "-n", f"{name}-{self.queue}@%h",
             "--loglevel=WARNING", "--without-heartbeat", "--without-gossip",
             "--without-mingle"],
            cwd=ROOT, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
        )  # fmt: skip
        self.procs.append(proc)
        return proc

    def start_beat(self, schedule: Path, **env_extra: str) -> subprocess.Popen:
        """Celery beat with the project's schedule, sending to this pool's queue."""
        env = os.environ | {"CELERY_BROKER_URL": BROKER, "FAULT_QUEUE": self.queue} | env_extra
        proc = subprocess.Popen(
            [sys.executable, "-m", "celery", "-A", "tests.faults.worker_app", "beat",
             "-s", str(schedule), "--loglevel=WARNING"],
            cwd=ROOT, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
        )  # fmt: skip
        self.procs.append(proc)
        return proc

    def check_alive(self) -> None:
        for proc in self.procs:
            if proc.returncode is None and proc.poll() is not None:
                output = proc.stdout.read() if proc.stdout else ""
                pytest.fail(f"worker exited ({proc.returncode}): {output}")

    def stop(self) -> None:
        for proc in self.procs:
            if proc.poll() is None:
                proc.terminate()
        for proc in self.procs:
            try:
                proc.wait(timeout=20)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()


@pytest.fixture
def workers() -> Iterator[Workers]:
    from config.celery import app

    pool = Workers(f"faults-{uuid.uuid4().hex[:8]}")
    old = (app.conf.task_always_eager, app.conf.task_default_queue)
    app.conf.task_always_eager, app.conf.task_default_queue = False, pool.queue
    yield pool
    app.conf.task_always_eager, app.conf.task_default_queue = old
    pool.stop()


def wait_until(check: Callable[[], object], what: str, workers: Workers | None = None,
               timeout: float = 60.0) -> object:  # fmt: skip
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if value := check():
            return value
        if workers is not None:
            workers.check_alive()
        time.sleep(0.2)
    pytest.fail(f"timed out after {timeout:.0f} s waiting for {what}")


# --- a TCP proxy the test can cut and restore ----------------------------------------------


class Proxy:
    """Forwards 127.0.0.1:<port> to ``target``; ``cut()`` closes the listener and every
    open connection (connection refused, as with a server that is down), ``restore()``
    listens on the same port again."""

    def __init__(self, target: tuple[str, int]) -> None:
        self.target = target
        self.port = 0
        self.lock = threading.Lock()
        self.conns: list[socket.socket] = []
        self.listener: socket.socket | None = None
        self.restore()

    def restore(self) -> None:
        listener = socket.socket()
        listener.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        listener.bind(("127.0.0.1", self.port))
        listener.listen(32)
        self.port, self.listener = listener.getsockname()[1], listener
        threading.Thread(target=self._accept, args=(listener,), daemon=True).start()

    def cut(self) -> None:
        with self.lock:
            listener, self.listener = self.listener, None
            conns, self.conns = self.conns, []
        if listener is not None:
            listener.close()
        for conn in conns:
            with contextlib.suppress(OSError):
                conn.shutdown(socket.SHUT_RDWR)
            conn.close()

    def _accept(self, listener: socket.socket) -> None:
        while True:
            try:
                client, _ = listener.accept()
            except OSError:
                return
            try:
                upstream = socket.create_connection(self.target, 5)
            except OSError:
                client.close()
                continue
            with self.lock:
                self.conns += [client, upstream]
            threading.Thread(target=self._pipe, args=(client, upstream), daemon=True).start()

    @staticmethod
    def _pipe(a: socket.socket, b: socket.socket) -> None:
        try:
            while True:
                readable, _, _ = select.select([a, b], [], [], 1.0)
                for src in readable:
                    data = src.recv(65536)
                    if not data:
                        return
                    (b if src is a else a).sendall(data)
        except (OSError, ValueError):
            return
        finally:
            for s in (a, b):
                with contextlib.suppress(OSError):
                    s.close()


@pytest.fixture
def broker_proxy() -> Iterator[Proxy]:
    """The test process's Celery producer talks to Redis through a proxy the test cuts."""
    from config.celery import app

    parts = urlsplit(BROKER)
    proxy = Proxy((parts.hostname or "127.0.0.1", parts.port or 6379))
    old = app.conf.broker_write_url

    def use(url: str) -> None:
        app.conf.broker_write_url = url  # what the producer connects to
        app._pool = None  # kombu's pools are keyed by URL: the other URL's pool stays intact
        app.amqp._producer_pool = None

    use(parts._replace(netloc=f"{parts.hostname}:{proxy.port}").geturl())
    yield proxy
    proxy.cut()
    use(old)
