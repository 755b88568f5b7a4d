"""Database work per API request (bench/README.md, load test): the hot polling endpoints
answer in a fixed, small number of queries, whatever the number of rows behind them."""

import pytest
from django.db import connection
from django.test.utils import CaptureQueriesContext

from labs.models import LabAPIKey

pytestmark = pytest.mark.django_db


def test_key_lookup_brings_its_laboratory_in_the_same_query(world):
    key = world.keys["key_a"]
    with CaptureQueriesContext(connection) as ctx:
        found = LabAPIKey.objects.get_from_key(key)
        lab_name = found.laboratory.name
    assert lab_name == world.lab_a.name
    assert len(ctx.captured_queries) == 1
    assert "labs_laboratory" in ctx.captured_queries[0]["sql"]


def test_revoked_key_is_still_not_usable(world):
    with pytest.raises(LabAPIKey.DoesNotExist):
        LabAPIKey.objects.get_from_key(world.keys["revoked_key_a"])


def _queries(client, path: str) -> tuple[int, int, list[str]]:
    with CaptureQueriesContext(connection) as ctx:
        response = client.get(path)
    return response.status_code, len(ctx.captured_queries), [q["sql"] for q in ctx.captured_queries]


@pytest.mark.parametrize(
    ("path", "expected"),
    [
        # key + laboratory, the page (no COUNT: page 1 holds the whole list)
        ("/api/v1/comparisons/", 2),
        # key + laboratory, participant + comparison, devices, point count
        ("/api/v1/comparisons/{code}/", 4),
        # key + laboratory, participant + comparison, page (n_results annotated; no COUNT)
        ("/api/v1/comparisons/{code}/submissions/", 3),
        # key + laboratory, participant + comparison, the version, its results with points
        ("/api/v1/comparisons/{code}/submissions/1/", 4),
    ],
)
def test_lab_polling_endpoints_query_count(world, path, expected):
    status, n, sql = _queries(world.client("key_a"), path.format(code=world.cmp.code))
    assert status == 200
    assert n == expected, "\n".join(sql)
    # the laboratory is never fetched on its own (it comes with the key)
    assert not any(s.startswith('SELECT "labs_laboratory"') for s in sql)
