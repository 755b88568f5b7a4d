"""API pagination (``REST_FRAMEWORK["DEFAULT_PAGINATION_CLASS"]``): DRF's page-number
pagination, same query parameters and the same ``{"count", "next", "previous", "results"}``
answer, without the ``COUNT(*)`` query when the first page holds every row.

Polled lists are short (a laboratory's comparisons, its versions): page 1 is read with
one row more than the page size; when that extra row is absent the page *is* the whole
list and its length is the count. Longer lists, and every other page, are counted as
before (bench/README.md, "Load test").
"""

from __future__ import annotations

from typing import Any

from django.core.paginator import Page, Paginator
from rest_framework import pagination


def _is_first_page(number: Any) -> bool:
    return number == 1 or number == "1"


class CountSparingPaginator(Paginator):
    """A Django paginator that learns the count of a one-page list from the page itself."""

    def page(self, number: Any) -> Page:
        if _is_first_page(number) and "count" not in self.__dict__ and not self.orphans:
            rows = list(self.object_list[: self.per_page + 1])
            if len(rows) <= self.per_page:
                self.__dict__["count"] = len(rows)  # the cached_property's slot
                return self._get_page(rows, 1, self)  # type: ignore[attr-defined]
            return self._get_page(rows[: self.per_page], 1, self)  # type: ignore[attr-defined]
        return super().page(number)


class PageNumberPagination(pagination.PageNumberPagination):
    django_paginator_class = CountSparingPaginator
