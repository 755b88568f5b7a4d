"""Throttles: per API key (scope ``api_key``) and per session user (scope ``user``).

Rates come from ``REST_FRAMEWORK["DEFAULT_THROTTLE_RATES"]`` and are read at
request time (DRF's throttles read them once at import, which would ignore a
settings override). Excess requests answer 429 with ``Retry-After``.

With the shared Redis cache (``CACHE_URL=redis://...``, :mod:`common.cache`) a
bucket is checked and updated by one Lua script, atomically, in one round trip: DRF's
own ``get`` then ``set`` of the pickled history took two, and two workers serving the
same key at once could each overwrite the other's request (a request not counted).
The algorithm is DRF's (a sliding log of request times per bucket, the same
``Retry-After``); other caches (the per-process default) use DRF's code as it is.
"""

from __future__ import annotations

from typing import Any

from django.core.cache import caches
from rest_framework.request import Request
from rest_framework.settings import api_settings
from rest_framework.throttling import SimpleRateThrottle
from rest_framework.views import APIView

from common.cache import RedisCache
from labs.models import LabAPIKey

#: DRF's SimpleRateThrottle.allow_request on a Redis list (newest first), atomically
SLIDING_LOG = """
local key, now = KEYS[1], tonumber(ARGV[1])
local duration, limit = tonumber(ARGV[2]), tonumber(ARGV[3])
local oldest = redis.call('LINDEX', key, -1)
while oldest and tonumber(oldest) <= now - duration do
  redis.call('RPOP', key)
  oldest = redis.call('LINDEX', key, -1)
end
local n = redis.call('LLEN', key)
if n >= limit then
  return {0, oldest, n}
end
redis.call('LPUSH', key, ARGV[1])
redis.call('EXPIRE', key, duration)
return {1, oldest or ARGV[1], n + 1}
"""
_scripts: dict[int, Any] = {}


def _sliding_log_script() -> tuple[Any, Any] | None:
    """(the cache backend, its registered script) when the cache is the Redis one."""
    backend = caches["default"]
    if not isinstance(backend, RedisCache):
        return None
    client = backend._cache.get_client(write=True)  # type: ignore[attr-defined]
    script = _scripts.get(id(client))
    if script is None:
        script = _scripts[id(client)] = client.register_script(SLIDING_LOG)
    return backend, script


class _ScopedRate(SimpleRateThrottle):
    num_requests: int | None  # set by SimpleRateThrottle.__init__ (parse_rate)
    duration: int | None

    def get_rate(self) -> str | None:
        # the stubs type the rates as numbers (DRF's are "n/period") and keys as str only
        return api_settings.DEFAULT_THROTTLE_RATES.get(self.scope)  # type: ignore[return-value,arg-type]

    def allow_request(self, request: Request, view: APIView) -> bool:
        redis = _sliding_log_script() if self.rate is not None else None
        if redis is None:
            return super().allow_request(request, view)
        self.key = self.get_cache_key(request, view)
        if self.key is None:
            return True
        backend, script = redis
        self.now = self.timer()
        allowed, oldest, length = script(
            # its own key: a Redis list, never the pickled history of DRF's code
            keys=[backend.make_and_validate_key(f"{self.key}:log")],
            args=[repr(self.now), self.duration, self.num_requests],
        )
        # what DRF's wait() reads of the history: its length and its oldest time
        self.history = [float(oldest)] * int(length)
        return bool(allowed)


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
