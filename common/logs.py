"""Structured logs: one JSON object per line (``LOG_FORMAT=json``, the production default).

Used by Django, the Celery worker and beat (``CELERY_WORKER_HIJACK_ROOT_LOGGER``
is off, so they log through the same handler) and gunicorn
(``deploy/gunicorn.conf.py``). Fields: ``time`` (UTC, ISO 8601), ``level``,
``logger``, ``message``, ``process``, the exception text when there is one,
and any ``extra={...}`` given to the logging call.
"""

from __future__ import annotations

import datetime as dt
import json
import logging

#: Attributes every LogRecord has; anything else was passed with ``extra=``.
_STANDARD = set(vars(logging.LogRecord("", 0, "", 0, "", None, None))) | {"message", "asctime"}


class JsonFormatter(logging.Formatter):
    """A log record as one line of JSON."""

    def format(self, record: logging.LogRecord) -> str:
        time = dt.datetime.fromtimestamp(record.created, tz=dt.UTC)
        entry: dict[str, object] = {
            "time": time.isoformat(timespec="milliseconds"),
            "level": record.levelname,
            "logger": record.name,
            "message": record.getMessage(),
            "process": record.process,
        }
        for key, value in vars(record).items():
            if key not in _STANDARD and not key.startswith("_"):
                entry[key] = value
        if record.exc_info:
            entry["exception"] = self.formatException(record.exc_info)
        return json.dumps(entry, default=str, ensure_ascii=False)


class ClientTimeoutFilter(logging.Filter):
    """gunicorn's gthread worker logs a socket timeout with a full traceback ("Socket error
    processing request."); for us it is the expected end of a client that fell silent for
    ``GUNICORN_READ_TIMEOUT`` seconds, or that sent its request slower than
    ``GUNICORN_MIN_RATE`` (``deploy/gunicorn.conf.py``). Such a record becomes one INFO line
    without the traceback; every other record passes unchanged."""

    def filter(self, record: logging.LogRecord) -> bool:
        exc = record.exc_info[1] if record.exc_info else None
        if isinstance(exc, TimeoutError):
            slow = "too slowly" in str(exc)  # deploy/gunicorn.conf.py, PacedSocket
            record.msg = ("Closed a connection sending its request too slowly" if slow
                          else "Closed a connection silent past the read timeout")  # fmt: skip
            record.args = ()
            record.exc_info = record.exc_text = None
            record.levelno, record.levelname = logging.INFO, "INFO"
        return True
