"""Request types for the views (annotations only: nothing here runs differently)."""

from __future__ import annotations

from django.contrib.auth.models import User
from django.http import HttpRequest
from django_htmx.middleware import HtmxDetails


class AuthenticatedHttpRequest(HttpRequest):
    """The request of a ``login_required`` view: its user is a signed-in person, and
    ``HtmxMiddleware`` (in MIDDLEWARE) has set ``htmx``."""

    user: User
    htmx: HtmxDetails
