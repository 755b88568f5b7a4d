"""Request-level protections: the Content-Security-Policy header and the body size limit.

Django 5.2 has no built-in CSP; the policy is one string from settings
(``CONTENT_SECURITY_POLICY``), sent on every response that has none yet.
The size limit answers 413 from the declared ``Content-Length`` alone, so an
oversized body is never read, spooled to disk or parsed (OWASP ASVS V12.1.1).
"""

from __future__ import annotations

from collections.abc import Callable

from django.conf import settings
from django.http import HttpRequest, HttpResponse, JsonResponse

from labs.importers.values import human_size

#: Room for the multipart envelope (boundaries, headers, the other form fields).
MULTIPART_SLACK_BYTES = 64 * 1024


class ContentSecurityPolicyMiddleware:
    """Add ``Content-Security-Policy`` (and ``Permissions-Policy``) to every response."""

    def __init__(self, get_response: Callable[[HttpRequest], HttpResponse]) -> None:
        self.get_response = get_response

    def __call__(self, request: HttpRequest) -> HttpResponse:
        response = self.get_response(request)
        policy = getattr(settings, "CONTENT_SECURITY_POLICY", "")
        if policy and "Content-Security-Policy" not in response:
            response["Content-Security-Policy"] = policy
        permissions = getattr(settings, "PERMISSIONS_POLICY", "")
        if permissions and "Permissions-Policy" not in response:
            response["Permissions-Policy"] = permissions
        return response


def declared_length(request: HttpRequest) -> int:
    """The request's ``Content-Length`` (0 when absent or not a number)."""
    try:
        return max(int(request.META.get("CONTENT_LENGTH") or 0), 0)
    except ValueError:
        return 0


def body_limit(request: HttpRequest) -> int:
    """Largest accepted body: a file upload (multipart) or any other body (JSON, forms)."""
    if request.META.get("CONTENT_TYPE", "").startswith("multipart/form-data"):
        return int(settings.MAX_UPLOAD_BYTES) + MULTIPART_SLACK_BYTES
    return int(settings.DATA_UPLOAD_MAX_MEMORY_SIZE)


class RequestSizeLimitMiddleware:
    """413 on a declared body larger than :func:`body_limit`, before the body is read.

    The views keep their own, finer checks (the upload form and the API compare
    the file itself with ``MAX_UPLOAD_BYTES``); this guard stops a huge body
    before Django's multipart parser spools it to a temporary file.
    """

    def __init__(self, get_response: Callable[[HttpRequest], HttpResponse]) -> None:
        self.get_response = get_response

    def __call__(self, request: HttpRequest) -> HttpResponse:
        length, limit = declared_length(request), body_limit(request)
        if length > limit:
            return too_large(request, length, limit)
        return self.get_response(request)


def too_large(request: HttpRequest, length: int, limit: int) -> HttpResponse:
    detail = (
        f"The request body is {human_size(length)}; the limit is {human_size(limit)}. "
        "Split the results into smaller files, or contact the coordinator."
    )
    if request.path.startswith("/api/"):
        return JsonResponse({"detail": detail}, status=413)
    return HttpResponse(detail, status=413, content_type="text/plain; charset=utf-8")


def client_ip(request: HttpRequest) -> str:
    """The client address for login lockout (django-axes).

    ``REMOTE_ADDR``, unless ``TRUSTED_PROXY_COUNT`` reverse proxies (nginx, a load
    balancer) sit in front: then the address that the outermost trusted proxy saw,
    counted from the right of ``X-Forwarded-For`` (left entries are client-controlled).
    """
    proxies = int(getattr(settings, "TRUSTED_PROXY_COUNT", 0))
    forwarded = [a.strip() for a in request.META.get("HTTP_X_FORWARDED_FOR", "").split(",")]
    forwarded = [a for a in forwarded if a]
    if proxies > 0 and len(forwarded) >= proxies:
        return forwarded[-proxies]
    return str(request.META.get("REMOTE_ADDR", ""))
