"""The results pages' paging keeps the rest of the query: an earlier run's second page is
still that run's (``?run=``), a filtered list's second page still filtered."""

from __future__ import annotations

from django.test import RequestFactory

from analysis.views import _page


def test_a_page_link_keeps_the_run_and_filters_and_drops_only_the_page():
    request = RequestFactory().get(
        "/coordinator/X/results/", {"run": "3", "lab": "L07", "page": "2"}
    )
    page, query = _page(request, list(range(250)), 100)
    assert page.number == 2 and list(page.object_list) == list(range(100, 200))
    assert query == "run=3&lab=L07"


def test_a_page_past_the_end_is_the_last_one():
    page, query = _page(RequestFactory().get("/", {"page": "99"}), list(range(250)), 100)
    assert page.number == 3 and len(page.object_list) == 50 and query == ""
