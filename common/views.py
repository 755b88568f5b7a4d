"""The OpenAPI schema and documentation pages' guard (``API_DOCS_PUBLIC``)."""

from collections.abc import Callable
from functools import wraps
from typing import Any

from django.conf import settings
from django.contrib.auth.views import redirect_to_login
from django.http import HttpRequest, HttpResponse, JsonResponse


def api_docs_guard(view: Callable[..., HttpResponse]) -> Callable[..., HttpResponse]:
    """The OpenAPI schema and Swagger UI: for signed-in people unless ``API_DOCS_PUBLIC``
    (read per request). Not signed in: the schema is 403 in the API's error shape, the
    documentation page sends to the sign-in page."""

    @wraps(view)
    def guarded(request: HttpRequest, *args: Any, **kwargs: Any) -> HttpResponse:
        if settings.API_DOCS_PUBLIC or request.user.is_authenticated:
            return view(request, *args, **kwargs)
        if request.resolver_match and request.resolver_match.url_name == "schema":
            detail = "Sign in to read the API schema."
            return JsonResponse({"detail": detail, "errors": []}, status=403)
        return redirect_to_login(request.get_full_path())

    return guarded
