"""Throttles: per API key (scope ``api_key``) and per session user (scope ``user``).

Rates come from ``REST_FRAMEWORK["DEFAULT_THROTTLE_RATES"]`` and are read at
request time (DRF's throttles read them once at import, which would ignore a
settings override). Excess requests answer 429 with ``Retry-After``.
"""

from __future__ import annotations

from rest_framework.request import Request
from rest_framework.settings import api_settings
from rest_framework.throttling import SimpleRateThrottle
from rest_framework.views import APIView

from labs.models import LabAPIKey


class _ScopedRate(SimpleRateThrottle):
    def get_rate(self) -> str | None:
        return api_settings.DEFAULT_THROTTLE_RATES.get(self.scope)


class LabAPIKeyRateThrottle(_ScopedRate):
    """One bucket per key, identified by its prefix (the hash is never used as a cache key)."""

    scope = "api_key"

    def get_cache_key(self, request: Request, view: APIView) -> str | None:
        if not isinstance(request.auth, LabAPIKey):
            return None
        return self.cache_format % {"scope": self.scope, "ident": request.auth.prefix}


class SessionUserRateThrottle(_ScopedRate):
    """One bucket per signed-in person; requests made with a key are left to the key's bucket."""

    scope = "user"

    def get_cache_key(self, request: Request, view: APIView) -> str | None:
        if isinstance(request.auth, LabAPIKey) or not request.user.is_authenticated:
            return None
        return self.cache_format % {"scope": self.scope, "ident": request.user.pk}
