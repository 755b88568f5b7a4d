"""One error hierarchy for business rules, mapped to HTTP by one DRF exception handler.

Services raise these; views and API views never build error responses by hand.
The JSON shape is the one promised in formats.md §3:
``{"detail": "...", "errors": [{"row": 7, "field": "...", "message": "..."}]}``.
"""

from __future__ import annotations

from typing import Any

from rest_framework.response import Response
from rest_framework.views import exception_handler


class ApplicationError(Exception):
    """A business rule was broken; ``message`` is meant for the person who caused it."""

    status_code = 400

    def __init__(self, message: str, *, errors: list[dict[str, Any]] | None = None) -> None:
        super().__init__(message)
        self.message = message
        self.errors = errors or []


class ValidationFailed(ApplicationError):
    """Input does not satisfy the rules; ``errors`` lists every bad row and field."""

    status_code = 400


class StateConflict(ApplicationError):
    """The object is not in a state that allows this (e.g. deadline passed, illegal transition)."""

    status_code = 409


class InvalidTransition(StateConflict):
    """A state machine was asked for a transition it does not allow."""


class RequestTooLarge(ApplicationError):
    """413: a body or file over the limit, refused before it is read or parsed."""

    status_code = 413


class NotVisible(ApplicationError):
    """The object does not exist for this user (also for other labs' objects)."""

    status_code = 404


def api_exception_handler(exc: Exception, context: dict[str, Any]) -> Response | None:
    """DRF exception handler: ApplicationError -> JSON with detail and errors; else DRF's."""
    if isinstance(exc, ApplicationError):
        return Response({"detail": exc.message, "errors": exc.errors}, status=exc.status_code)
    response = exception_handler(exc, context)
    if response is not None and isinstance(response.data, dict):
        response.data.setdefault("errors", [])
    return response
