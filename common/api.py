"""Pieces of the API views shared by the apps: a list rendered from ``values_list`` rows and
a request body checked by a serializer, its problems in the error shape (docs/interfaces.md §3)."""

from __future__ import annotations

from typing import Any

from rest_framework import generics, serializers
from rest_framework.request import Request
from rest_framework.response import Response

from common.errors import ValidationFailed
from common.rendering import ValuesRendering


def _problems(field: str, problems: Any) -> list[dict[str, Any]]:
    """One error per field; a list field's errors come by index (``axes[2]``)."""
    if isinstance(problems, dict):
        return [e for i, p in problems.items() for e in _problems(f"{field}[{i}]", p)]
    return [{"row": None, "field": field, "message": str(problems[0])}]


def valid_data(serializer: serializers.Serializer) -> dict[str, Any]:
    if not serializer.is_valid():
        raise ValidationFailed(
            "The request does not fit; see errors.",
            errors=[e for f, p in serializer.errors.items() for e in _problems(f, p)],
        )
    return dict(serializer.validated_data)


class ValuesListView(generics.ListAPIView):
    """A list whose page is rendered from ``values_list`` rows (:mod:`common.rendering`):
    the same JSON as ``serializer_class``, without building model instances or fields."""

    rendering: ValuesRendering

    def list(self, request: Request, *args: Any, **kwargs: Any) -> Response:
        rows = self.rendering.rows(self.filter_queryset(self.get_queryset()))
        page = self.paginate_queryset(rows)
        if page is not None:
            return self.get_paginated_response(self.rendering.render(page))
        return Response(self.rendering.render(rows))
