"""Who may see and change what (docs/architecture.md §2): one module the web pages, the API,
report downloads and raw-data pages ask."""

from __future__ import annotations

from django.db.models import QuerySet
from django.http import Http404, HttpRequest

from proficiency.models import Comparison


def coordinated_comparisons(user) -> QuerySet[Comparison]:  # type: ignore[no-untyped-def]
    """Comparisons the user coordinates; a superuser coordinates them all."""
    if user.is_superuser:
        return Comparison.objects.all()
    return Comparison.objects.filter(coordinators=user)


def coordinated(request: HttpRequest, code: str) -> Comparison:
    """The comparison ``code`` if the user coordinates it; 404 otherwise (no existence leak)."""
    comparison = coordinated_comparisons(request.user).filter(code=code).first()
    if comparison is None:
        raise Http404(f"No comparison {code!r} that you coordinate.")
    return comparison
