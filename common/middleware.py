"""Request-level protections: the Content-Security-Policy header, the body size limit and
control characters in what a request carries.

Django 5.2 has no built-in CSP; the policy is one string from settings
(``CONTENT_SECURITY_POLICY``), sent on every response that has none yet.
The size limit answers 413 from the declared ``Content-Length`` alone, so an
oversized body is never read, spooled to disk or parsed (OWASP ASVS V12.1.1).
Control characters are refused where they enter (:class:`ControlCharacterMiddleware`,
``common.parsers``): PostgreSQL cannot store NUL in text, and no field of the service
needs the other C0 characters except tab and line breaks.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Iterable
from typing import Any

from django.conf import settings
from django.core.exceptions import BadRequest
from django.http import (
    Http404,
    HttpRequest,
    HttpResponse,
    JsonResponse,
    QueryDict,
    UnreadablePostError,
)
from django.views.defaults import bad_request as django_bad_request

from common.errors import BodyNotReceived, ValidationFailed
from common.sizes import human_size

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


# --- control characters -----------------------------------------------------------------------

#: C0 control characters that no text field takes: all but tab, line feed and carriage return
#: (a note or an address pasted from a file may have those). NUL is one: PostgreSQL refuses it.
TEXT_CONTROL = re.compile("[\x00-\x08\x0b\x0c\x0e-\x1f]")
#: in a URL path: every C0 character and DEL (no route, code or token has any)
PATH_CONTROL = re.compile("[\x00-\x1f\x7f]")
CONTROL_DETAIL = "The request contains control characters; see errors."


def control_message(text: str) -> str | None:
    """Why ``text`` is refused (the first control character and where), or None."""
    found = TEXT_CONTROL.search(text)
    if found is None:
        return None
    return (
        f"contains the control character U+{ord(found.group()):04X} at position "
        f"{found.start() + 1}; only tab and line breaks are allowed"
    )


class ControlCharacters(ValidationFailed, BadRequest):
    """400 naming each field (query parameter, form field, JSON key path) with a control
    character. A ``BadRequest`` too, so that Django answers 400 wherever it is raised."""

    def __init__(self, errors: list[dict[str, Any]]) -> None:
        super().__init__(CONTROL_DETAIL, errors=errors)


def control_errors(pairs: Iterable[tuple[str, str]]) -> list[dict[str, Any]]:
    """docs/interfaces.md §3 error rows for the (field, text) pairs with a control character; a
    field's name is checked too (then the error names it with the character escaped)."""
    errors = []
    for name, value in pairs:
        if why := control_message(name):
            errors.append(
                {"field": name.encode("unicode_escape").decode(), "message": f"The name {why}."}
            )
        elif why := control_message(value):
            errors.append({"field": name, "message": f"The value {why}."})
    return errors


def query_dict_pairs(data: QueryDict) -> Iterable[tuple[str, str]]:
    for name, values in data.lists():
        for value in values:
            yield name, value if isinstance(value, str) else ""


def check_query_dict(data: QueryDict) -> None:
    """Raise :class:`ControlCharacters` for a form's or a query's fields."""
    if errors := control_errors(query_dict_pairs(data)):
        raise ControlCharacters(errors)


class ControlCharacterMiddleware:
    """Control characters never reach a view, the ORM or the database.

    * URL path: any C0 character or DEL -> 404 (no route matches such a path);
    * query string and ``application/x-www-form-urlencoded`` body: a name or value with a
      C0 character other than tab, LF and CR -> 400 naming the parameter;
    * ``multipart/form-data``: its text fields are checked when the view parses the body
      (not here: views first install their upload size limits);
    * JSON bodies: ``common.parsers`` (the API's parsers) name the key path.

    After :class:`RequestSizeLimitMiddleware`, so that an oversized body is never read.
    """

    def __init__(self, get_response: Callable[[HttpRequest], HttpResponse]) -> None:
        self.get_response = get_response

    def __call__(self, request: HttpRequest) -> HttpResponse:
        if PATH_CONTROL.search(request.path_info):
            if request.path.startswith("/api/"):
                return JsonResponse({"detail": "Not found.", "errors": []}, status=404)
            raise Http404("No such page.")
        errors = control_errors(query_dict_pairs(request.GET))
        content_type = request.META.get("CONTENT_TYPE", "")
        if request.method == "POST" and content_type.startswith("multipart/form-data"):
            _check_when_parsed(request)
        if errors:
            return control_response(request, ControlCharacters(errors))
        return self.get_response(request)

    def process_view(
        self, request: HttpRequest, view: Callable[..., Any], args: Any, kwargs: Any
    ) -> HttpResponse | None:
        """An urlencoded form, unless the view refuses control characters itself next to
        the inputs (:func:`validates_own_text`)."""
        if request.method != "POST" or getattr(view, "validates_control_characters", False):
            return None
        content_type = request.META.get("CONTENT_TYPE", "")
        if content_type.startswith("multipart/form-data"):
            return None
        try:
            errors = control_errors(query_dict_pairs(request.POST))  # urlencoded (or nothing)
        except UnreadablePostError as exc:
            return body_lost_response(request, exc)
        return control_response(request, ControlCharacters(errors)) if errors else None

    def process_exception(self, request: HttpRequest, exc: Exception) -> HttpResponse | None:
        """A multipart field found by a (non-API) view's parsing: the same answer; a body
        that did not arrive whole: 408, as in the API."""
        if isinstance(exc, ControlCharacters):
            return control_response(request, exc)
        if isinstance(exc, UnreadablePostError):
            return body_lost_response(request, exc)
        return None


def body_lost_response(request: HttpRequest, exc: Exception) -> HttpResponse:
    """408 for a request whose body stopped arriving (docs/interfaces.md §3): the client was
    silent for the read timeout or too slow, which is no server error (it was a 500 with a
    traceback); Django logs the 408 as one warning line."""
    error = BodyNotReceived.of(exc)
    if request.path.startswith("/api/"):
        return JsonResponse({"detail": error.message, "errors": []}, status=error.status_code)
    return HttpResponse(error.message, status=error.status_code,
                        content_type="text/plain; charset=utf-8")  # fmt: skip


def validates_own_text(view: Callable[..., Any]) -> Callable[..., Any]:
    """Mark a form view whose form refuses control characters in every field it stores,
    with an error next to the input (the results grid): the middleware lets its urlencoded
    posts through instead of answering a bare 400."""
    view.validates_control_characters = True  # type: ignore[attr-defined]
    return view


def _check_when_parsed(request: HttpRequest) -> None:
    """Check a multipart body's text fields right after Django parses it (Django removes
    unprintable characters from file names; the API's parsers check what they parse)."""
    load = request._load_post_and_files

    def load_and_check() -> None:
        load()
        match = request.resolver_match  # set before any view middleware reads the body
        if not getattr(match.func if match else None, "validates_control_characters", False):
            check_query_dict(request._post)  # type: ignore[attr-defined]

    # wrapping Django's private body parsing on this one request object
    request._load_post_and_files = load_and_check  # type: ignore[method-assign]


def bad_request(request: HttpRequest, exception: Exception) -> HttpResponse:
    """``handler400``: a :class:`ControlCharacters` raised outside a view (Django's CSRF
    check reads a form before the view) gets the same answer as in a view; any other bad
    request Django's."""
    if isinstance(exception, ControlCharacters):
        return control_response(request, exception)

    return django_bad_request(request, exception)


def control_response(request: HttpRequest, exc: ControlCharacters) -> HttpResponse:
    if request.path.startswith("/api/"):
        return JsonResponse({"detail": exc.message, "errors": exc.errors}, status=400)
    lines = [exc.message, *(f"{e['field']}: {e['message']}" for e in exc.errors)]
    return HttpResponse("\n".join(lines), status=400, content_type="text/plain; charset=utf-8")
