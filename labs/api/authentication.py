"""``Authorization: Api-Key <key>`` authentication for lab software (docs/interfaces.md §3).

A key belongs to one laboratory. A request authenticated by a key gets
``request.auth`` = the :class:`~labs.models.LabAPIKey` and ``request.user`` = a
:class:`LabKeyPrincipal`: authenticated, never a superuser, not a database user
(so nothing is ever attributed to a person: submissions made with a key have
``submitted_by = None`` and the key's laboratory is the participant).

A request without an ``Api-Key`` authorization header is left to the next
authentication class (the session). A header with a wrong, revoked or expired
key is refused with 401 and a message saying which, never silently ignored.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar, cast

from drf_spectacular.extensions import OpenApiAuthenticationExtension
from rest_framework import authentication, exceptions
from rest_framework.request import Request

from labs.models import LabAPIKey, Laboratory

KEYWORD = "Api-Key"


@dataclass(frozen=True, eq=False)
class LabKeyPrincipal:
    """The caller behind an API key: its laboratory, nothing more."""

    api_key: LabAPIKey
    is_authenticated = True
    is_anonymous = False
    is_active = True
    is_staff = False
    is_superuser = False
    pk: ClassVar[None] = None  # not dataclass fields
    id: ClassVar[None] = None

    @property
    def laboratory(self) -> Laboratory:
        return self.api_key.laboratory

    @property
    def username(self) -> str:
        return f"api-key:{self.api_key.prefix}"

    def __str__(self) -> str:
        return f"API key {self.api_key.prefix} ({self.api_key.name})"


def key_from_header(request: Request) -> str | None:
    """The key of ``Authorization: Api-Key <key>``; ``None`` for other schemes."""
    keyword, _, key = request.META.get("HTTP_AUTHORIZATION", "").strip().partition(" ")
    if keyword.lower() != KEYWORD.lower():
        return None
    key = key.strip()
    if not key:
        raise exceptions.AuthenticationFailed(
            "The Authorization header says Api-Key but carries no key: "
            "send 'Authorization: Api-Key <prefix>.<secret>'."
        )
    return key


def _refusal(key: str) -> str:
    """Say why a key does not authenticate (revoked, or unknown), without leaking others."""
    prefix = key.partition(".")[0]
    revoked = LabAPIKey.objects.filter(prefix=prefix, revoked=True).first()
    if revoked is not None and revoked.is_valid(key):
        return "This API key has been revoked; ask your laboratory manager for a new one."
    return "Invalid API key; check that it was copied whole (prefix.secret)."


class LabAPIKeyAuthentication(authentication.BaseAuthentication):
    """DRF authentication by a :class:`LabAPIKey` (hashed, revocable, one laboratory)."""

    def authenticate(self, request: Request) -> tuple[LabKeyPrincipal, LabAPIKey] | None:
        key = key_from_header(request)
        if key is None:
            return None
        try:
            api_key = cast(LabAPIKey, LabAPIKey.objects.get_from_key(key))
        except LabAPIKey.DoesNotExist:
            raise exceptions.AuthenticationFailed(_refusal(key)) from None
        if api_key.has_expired:
            raise exceptions.AuthenticationFailed(
                f"This API key expired on {api_key.expiry_date:%Y-%m-%d %H:%M} UTC; "
                "ask your laboratory manager for a new one."
            )
        return LabKeyPrincipal(api_key), api_key

    def authenticate_header(self, request: Request) -> str:
        # Makes unauthenticated requests answer 401 (with WWW-Authenticate), not 403.
        return KEYWORD


class LabAPIKeyScheme(OpenApiAuthenticationExtension):
    """Documents the scheme in the OpenAPI schema."""

    target_class = "labs.api.authentication.LabAPIKeyAuthentication"
    name = "labApiKey"

    def get_security_definition(self, auto_schema: Any) -> dict[str, str]:
        return {
            "type": "apiKey",
            "in": "header",
            "name": "Authorization",
            "description": "Laboratory API key, sent as `Authorization: Api-Key <key>`.",
        }
