"""gunicorn settings for ``make serve``, the systemd unit and the container.

Everything can be overridden from the environment: ``GUNICORN_BIND`` (default
``127.0.0.1:8000``; a reverse proxy terminates TLS in front), ``WEB_CONCURRENCY``
(workers, default 2 × cores + 1, at least 2), ``GUNICORN_TIMEOUT`` (seconds),
``GUNICORN_MAX_REQUESTS`` (requests a worker serves before it is replaced, default 20000).
Sync workers: gunicorn's ``gthread`` worker with keep-alive cost less CPU per request in
the load test but pinned each client's connection to one worker, and its p95 latency was
1.5-2x the sync workers' (bench/README.md, "Load test").
Logs go to standard output as JSON lines (``LOG_FORMAT=plain`` for text), with
the access log as key=value pairs inside ``message``.
"""

import gc
import multiprocessing
import os

wsgi_app = "proficiency.wsgi:application"
bind = os.environ.get("GUNICORN_BIND", "127.0.0.1:8000").split(",")
workers = max(2, int(os.environ.get("WEB_CONCURRENCY", multiprocessing.cpu_count() * 2 + 1)))
worker_class = "sync"
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
        "json": {"()": "proficiency.logs.JsonFormatter"},
        "plain": {"format": "%(asctime)s %(levelname)s %(name)s %(message)s"},
    },
    "handlers": {
        "console": {
            "class": "logging.StreamHandler",
            "formatter": _formatter,
            "stream": "ext://sys.stdout",
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
