"""``GET /healthz``: is this web process able to reach the database and the Celery broker?

For load balancers, systemd and container health checks: no authentication, no
session, no data. The answer is 200 ``{"database": "ok", "broker": "ok"}`` or 503
with ``"error"`` against what failed; the reason is logged, never returned.
Each check is one round trip with a short timeout (``HEALTHZ_TIMEOUT`` seconds).
"""

from __future__ import annotations

import logging
from collections.abc import Callable

from celery import current_app
from django.conf import settings
from django.db import connection
from django.http import HttpRequest, JsonResponse
from django.views.decorators.cache import never_cache
from django.views.decorators.http import require_safe

log = logging.getLogger(__name__)


def check_database() -> None:
    """One ``SELECT 1`` on the default connection."""
    with connection.cursor() as cursor:
        cursor.execute("SELECT 1")
        cursor.fetchone()


def check_broker() -> None:
    """Open (and close) one connection to ``CELERY_BROKER_URL``, without retries."""
    timeout = float(getattr(settings, "HEALTHZ_TIMEOUT", 2.0))
    url = settings.CELERY_BROKER_URL
    with current_app.connection_for_write(url, connect_timeout=timeout) as conn:
        conn.ensure_connection(max_retries=1, interval_start=0, interval_step=0, timeout=timeout)
        # Redis connects lazily: a channel runs a real command against the broker.
        conn.default_channel  # noqa: B018


CHECKS: dict[str, Callable[[], None]] = {"database": check_database, "broker": check_broker}


def run_checks() -> dict[str, str]:
    status = {}
    for name, check in CHECKS.items():
        try:
            check()
        except Exception:  # any failure means "not healthy"; the reason goes to the log
            log.exception("healthz: %s check failed", name)
            status[name] = "error"
        else:
            status[name] = "ok"
    return status


@never_cache
@require_safe  # GET and HEAD (some load balancers probe with HEAD)
def healthz(request: HttpRequest) -> JsonResponse:
    status = run_checks()
    healthy = all(value == "ok" for value in status.values())
    return JsonResponse(status, status=200 if healthy else 503)
