"""The API's filter backend (``REST_FRAMEWORK["DEFAULT_FILTER_BACKENDS"]``).

django-filter builds a ``FilterSet`` and validates its form on every list request, even
a request without a query string, whose filters then filter nothing (the project's
filtersets have no required filter and no default value). This backend skips that work
for a request without query parameters; any query string goes to django-filter,
unchanged (bench/README.md, "Load test").
"""

from __future__ import annotations

from typing import Any

from django.db.models import QuerySet
from django_filters.rest_framework import DjangoFilterBackend


class FilterBackend(DjangoFilterBackend):
    def filter_queryset(self, request: Any, queryset: QuerySet[Any], view: Any) -> QuerySet[Any]:
        if not request.query_params:
            return queryset
        return super().filter_queryset(request, queryset, view)
