"""gunicorn settings for ``make serve``, the systemd unit and the container.

Everything can be overridden from the environment: ``GUNICORN_BIND`` (default
``127.0.0.1:8000``; a reverse proxy terminates TLS in front), ``WEB_CONCURRENCY``
(workers, default 2 × cores + 1, at least 2), ``GUNICORN_TIMEOUT`` (seconds),
``GUNICORN_MAX_REQUESTS`` (requests a worker serves before it is replaced, default 20000),
``GUNICORN_THREADS`` (threads per worker, default 4), ``GUNICORN_READ_TIMEOUT`` (seconds,
default 30), ``GUNICORN_MIN_RATE`` (bytes per second, default 10000), ``GUNICORN_KEEPALIVE``
(seconds, default 0).

Threaded workers (``gthread``), so that slow clients cannot stall the service: a sync
worker reads one connection at a time, so as many clients as workers that send half
their headers and wait (no buffering proxy in front, or a slow network) kept every
worker, and ``/healthz``, waiting. Here a connection that sends nothing costs no thread;
one that is partly sent holds one thread of its worker, for at most
``GUNICORN_READ_TIMEOUT`` seconds of silence (then it is closed), and a request must arrive
at ``GUNICORN_MIN_RATE`` on average: a client that trickles it, a byte now and then but
never silent for long, is closed after twice ``GUNICORN_READ_TIMEOUT`` plus
size/``GUNICORN_MIN_RATE`` seconds (the application answers a body cut short with 408).
Keep-alive is off by default: with it, gthread pinned each client's connection to one
worker and the load test's p95 latency was 1.5-2x the sync workers' (bench/README.md,
"Load test"); without it every request is a new connection, spread over the workers as
with sync workers.
Logs go to standard output as JSON lines (``LOG_FORMAT=plain`` for text), with
the access log as key=value pairs inside ``message``.
"""

import gc
import multiprocessing
import os
import socket
import time

from gunicorn.workers.gthread import ThreadWorker

#: seconds of silence allowed to a client while its request is read or its answer written
READ_TIMEOUT = float(os.environ.get("GUNICORN_READ_TIMEOUT", "30"))


#: bytes per second a request must arrive at, on average (Apache mod_reqtimeout's MinRate)
MIN_RATE = float(os.environ.get("GUNICORN_MIN_RATE", "10000"))


class PacedSocket:
    """A connection's socket whose reads of one request end at a deadline that grows with
    what arrives: twice ``READ_TIMEOUT`` after the first read, plus 1/``MIN_RATE`` s per byte
    (so a client that falls silent meets the read timeout first). A client sending a byte
    every few seconds, never silent for ``READ_TIMEOUT``, held a thread for as long as it
    liked (hours for an upload of a few kilobytes). Everything but ``recv`` is the socket's."""

    def __init__(self, sock: socket.socket) -> None:
        self._sock = sock
        self.deadline: float | None = None

    def start(self) -> None:
        """A new request: its deadline starts at its first read (not while it waits for a
        thread, which would cut it before a byte was read)."""
        self.deadline = None

    def recv(self, size: int, *flags: int) -> bytes:
        now = time.monotonic()
        if self.deadline is None:
            self.deadline = now + 2 * READ_TIMEOUT
        left = self.deadline - now
        if left <= 0:
            raise TimeoutError("the request arrived too slowly")
        self._sock.settimeout(min(READ_TIMEOUT, left))
        try:
            data = self._sock.recv(size, *flags)
        except TimeoutError:
            if left >= READ_TIMEOUT:
                raise  # silent for the read timeout
            raise TimeoutError("the request arrived too slowly") from None
        finally:
            self._sock.settimeout(READ_TIMEOUT)  # the answer's writes keep the plain timeout
        self.deadline += len(data) / MIN_RATE
        return data

    def __getattr__(self, name: str) -> object:
        return getattr(self._sock, name)


class SlowClientThreadWorker(ThreadWorker):
    """gunicorn's gthread worker, with a timeout on each read and write of a connection
    (gthread's own sockets block without one: a client that stops half-way through its
    headers would hold a thread until it disconnects) and a minimum rate for reading a
    request (:class:`PacedSocket`; not with TLS in gunicorn, which the proxy terminates)."""

    def enqueue_req(self, conn):  # gthread's, with the timeout and the pace
        if not self.cfg.is_ssl and not isinstance(conn.sock, PacedSocket):
            conn.sock = PacedSocket(conn.sock)  # before init(), which gives it to the parser
        conn.init()  # blocking socket, parser
        conn.sock.settimeout(READ_TIMEOUT)
        if isinstance(conn.sock, PacedSocket):
            conn.sock.start()  # each request of a kept-alive connection has its own deadline
        future = self.tpool.submit(self.handle, conn)
        self._wrap_future(future, conn)


wsgi_app = "config.wsgi:application"
bind = os.environ.get("GUNICORN_BIND", "127.0.0.1:8000").split(",")
workers = max(2, int(os.environ.get("WEB_CONCURRENCY", multiprocessing.cpu_count() * 2 + 1)))
worker_class = SlowClientThreadWorker
threads = max(2, int(os.environ.get("GUNICORN_THREADS", "4")))
keepalive = int(os.environ.get("GUNICORN_KEEPALIVE", "0"))
timeout = int(os.environ.get("GUNICORN_TIMEOUT", "60"))
graceful_timeout = 20
# Recycle workers now and then (memory held by numpy/matplotlib). Not too often: a new
# worker spends ≈ 2.4 s of CPU importing Django and the views before its first answer
# (bench/README.md, "Load test"); every 2,000 requests that was ≈ 1 ms per request.
max_requests = int(os.environ.get("GUNICORN_MAX_REQUESTS", "20000"))
max_requests_jitter = max_requests // 10
# X-Forwarded-Proto is trusted from these addresses only (the reverse proxy).
forwarded_allow_ips = os.environ.get("FORWARDED_ALLOW_IPS", "127.0.0.1,::1")
# Uploads are limited in Django (before parsing); this bounds the request line and headers.
limit_request_line = 8190
limit_request_fields = 100

accesslog = "-"
errorlog = "-"
access_log_format = (
    'remote=%(h)s method=%(m)s path="%(U)s" query="%(q)s" status=%(s)s bytes=%(B)s '
    'duration_ms=%(M)s agent="%(a)s"'
)
_formatter = os.environ.get("LOG_FORMAT", "json")
logconfig_dict = {
    "version": 1,
    "disable_existing_loggers": False,
    "formatters": {
        "json": {"()": "common.logs.JsonFormatter"},
        "plain": {"format": "%(asctime)s %(levelname)s %(name)s %(message)s"},
    },
    # a client cut at the read timeout: one INFO line, not a traceback
    "filters": {"client_timeout": {"()": "common.logs.ClientTimeoutFilter"}},
    "handlers": {
        "console": {
            "class": "logging.StreamHandler",
            "formatter": _formatter,
            "stream": "ext://sys.stdout",
            "filters": ["client_timeout"],
        }
    },
    "loggers": {
        "gunicorn.error": {"handlers": ["console"], "level": "INFO", "propagate": False},
        "gunicorn.access": {"handlers": ["console"], "level": "INFO", "propagate": False},
    },
}


def post_worker_init(worker: object) -> None:
    """The application is loaded: move what it allocated at start-up out of the
    collector's reach (``gc.freeze``), so full collections walk only what requests make."""
    gc.collect()
    gc.freeze()
