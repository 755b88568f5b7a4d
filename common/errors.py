"""One error hierarchy for business rules, mapped to HTTP by one DRF exception handler.

Services raise these; views and API views never build error responses by hand.
The JSON shape is the one promised in docs/interfaces.md §3:
``{"detail": "...", "errors": [{"row": 7, "field": "...", "message": "..."}]}``.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from typing import Any

import psycopg
from django.db import OperationalError as DjangoOperationalError
from django.http import UnreadablePostError
from rest_framework.response import Response

logger = logging.getLogger(__name__)


class ApplicationError(Exception):
    """A business rule was broken; ``message`` is meant for the person who caused it."""

    status_code = 400

    def __init__(self, message: str, *, errors: list[dict[str, Any]] | None = None) -> None:
        super().__init__(message)
        self.message = message
        # docs/interfaces.md §3: every error has row, field and message (row None when not a row's)
        self.errors = [{"row": None, "field": None, **e} for e in errors or []]


class ValidationFailed(ApplicationError):
    """Input does not satisfy the rules; ``errors`` lists every bad row and field."""

    status_code = 400


class StateConflict(ApplicationError):
    """The object is not in a state that allows this (e.g. deadline passed, illegal transition)."""

    status_code = 409


def refusal(check: Callable[[], object]) -> str | None:
    """The message of the rule ``check`` raises (a page shows why its form is disabled),
    or None when it passes."""
    try:
        check()
    except ApplicationError as exc:
        return exc.message
    return None


class InvalidTransition(StateConflict):
    """A state machine was asked for a transition it does not allow."""


class RequestTooLarge(ApplicationError):
    """413: a body or file over the limit, refused before it is read or parsed."""

    status_code = 413


class BodyNotReceived(ApplicationError):
    """408: the request's body did not arrive whole — the client fell silent for the read
    timeout or sent slower than the minimum rate (``deploy/gunicorn.conf.py``) — so it was
    never parsed and nothing was stored."""

    status_code = 408

    @classmethod
    def of(cls, exc: Exception) -> BodyNotReceived:
        return cls(f"The request did not arrive whole ({exc}); nothing was stored. Send it again.")


class KeyReused(ApplicationError):
    """422: an ``Idempotency-Key`` sent again with a different request."""

    status_code = 422


class NotVisible(ApplicationError):
    """The object does not exist for this user (also for other labs' objects)."""

    status_code = 404


DATABASE_LOST = (
    "The database connection failed while handling the request, so it was not completed; "
    "operations are atomic, so nothing was stored half-way. Please try again."
)


def api_exception_handler(exc: Exception, context: dict[str, Any]) -> Response | None:
    """DRF exception handler: ApplicationError -> JSON with detail and errors; a lost
    database connection (also one raised by psycopg directly, as COPY does) -> 503; else
    DRF's."""
    # imported here: rest_framework.views loads the parsers (common.parsers), which
    # use this module's errors
    from rest_framework.views import exception_handler

    if isinstance(exc, UnreadablePostError):  # a client too slow or gone: not our error
        exc = BodyNotReceived.of(exc)
    if isinstance(exc, ApplicationError):
        return Response({"detail": exc.message, "errors": exc.errors}, status=exc.status_code)
    if isinstance(exc, DjangoOperationalError | psycopg.OperationalError):
        logger.error("database connection lost: %s", exc)
        return Response({"detail": DATABASE_LOST, "errors": []}, status=503)
    response = exception_handler(exc, context)
    if response is None:
        return None
    if isinstance(response.data, dict) and "detail" in response.data:
        response.data.setdefault("errors", [])
    else:  # DRF's field errors (a serializer's, a filter set's): the same shape as ours
        response.data = {"detail": "The request is not valid.", "errors": _rows(response.data)}
    return response


def _rows(data: Any, field: str | None = None) -> list[dict[str, Any]]:
    """``{"field": ["message", ...]}`` or ``["message"]`` -> docs/interfaces.md §3 error rows."""
    if isinstance(data, dict):
        return [e for key, value in data.items() for e in _rows(value, str(key))]
    if isinstance(data, list):
        return [e for value in data for e in _rows(value, field)]
    return [{"row": None, "field": field, "message": str(data)}]
