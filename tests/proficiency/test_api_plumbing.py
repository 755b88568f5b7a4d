"""The API's plumbing classes (bench/README.md, "Load test"): the pagination that spares
the COUNT of a one-page list, the filter backend that skips an empty query string, and
the shared Redis cache that reuses its client. Same answers as DRF's and Django's own."""

from __future__ import annotations

import os
import uuid

import pytest
from django.core.cache import cache, caches
from django.db import connection
from django.test.utils import CaptureQueriesContext

from common.pagination import CountSparingPaginator
from labs.models import Submission
from tests.labs.api import build_world

pytestmark = pytest.mark.django_db


@pytest.fixture(autouse=True)
def _fresh_throttle_buckets():
    cache.clear()


@pytest.fixture
def world():
    return build_world()


def _versions(world, n: int) -> None:
    """Lab A's comparison gets versions 2..n+1 (drafts) beside its submitted version 1."""
    Submission.objects.bulk_create(
        Submission(participant=world.part_a, version=v) for v in range(2, n + 2)
    )


def _counts(sql: list[str]) -> int:
    """The paginator's ``SELECT COUNT(*)`` queries (the page itself counts results per row)."""
    return sum(q.upper().startswith("SELECT COUNT(*)") for q in sql)


def _get(world, path: str):
    with CaptureQueriesContext(connection) as ctx:
        response = world.client("key_a").get(path)
    return response, [q["sql"] for q in ctx.captured_queries]


@pytest.mark.parametrize(
    ("extra", "page", "count", "n_rows", "has_next", "counted"),
    [
        (0, "", 1, 1, False, False),  # one row: no COUNT
        (99, "", 100, 100, False, False),  # exactly one full page: no COUNT
        (100, "", 101, 100, True, True),  # one row more: counted as before
        (100, "?page=1", 101, 100, True, True),
        (100, "?page=2", 101, 1, False, True),  # other pages: counted as before
        (100, "?page=last", 101, 1, False, True),
    ],
)
def test_history_pages_and_counts(world, extra, page, count, n_rows, has_next, counted):
    _versions(world, extra)
    response, sql = _get(world, f"/api/v1/comparisons/{world.cmp.code}/submissions/{page}")
    assert response.status_code == 200
    body = response.json()
    assert list(body) == ["count", "next", "previous", "results"]
    assert body["count"] == count
    assert len(body["results"]) == n_rows
    assert (body["next"] is not None) is has_next
    assert _counts(sql) == (1 if counted else 0), "\n".join(sql)


def test_page_two_follows_page_one_exactly(world):
    _versions(world, 150)
    first = world.client("key_a").get(f"/api/v1/comparisons/{world.cmp.code}/submissions/")
    second = world.client("key_a").get(first.json()["next"])
    versions = [r["version"] for r in first.json()["results"] + second.json()["results"]]
    assert versions == list(range(151, 0, -1))
    assert second.json()["previous"] is not None and second.json()["count"] == 151


@pytest.mark.parametrize("page", ["0", "3", "x", "1.0"])
def test_invalid_pages_are_404_as_before(world, page):
    response = world.client("key_a").get(
        f"/api/v1/comparisons/{world.cmp.code}/submissions/?page={page}"
    )
    assert response.status_code == 404


def test_paginator_matches_django_on_short_and_long_lists(world):
    from django.core.paginator import Paginator

    _versions(world, 30)
    qs = Submission.objects.filter(participant=world.part_a).order_by("-version")
    for per_page in (10, 31, 50):
        ours, theirs = CountSparingPaginator(qs, per_page), Paginator(qs, per_page)
        a, b = ours.page(1), theirs.page(1)
        assert [s.pk for s in a] == [s.pk for s in b]
        assert (ours.count, ours.num_pages, a.has_next()) == (
            theirs.count, theirs.num_pages, b.has_next())  # fmt: skip
        assert ours.count == 31


def test_filters_still_apply_and_refuse(world):
    _versions(world, 2)  # versions 2 and 3 are drafts, version 1 is submitted
    base = f"/api/v1/comparisons/{world.cmp.code}/submissions/"
    client = world.client("key_a")
    assert [r["version"] for r in client.get(base).json()["results"]] == [3, 2, 1]
    drafts = client.get(base + "?status=draft").json()["results"]
    assert [r["version"] for r in drafts] == [3, 2]
    assert client.get(base + "?status=nonsense").status_code == 400
    assert [r["version"] for r in client.get(base + "?page=1").json()["results"]] == [3, 2, 1]


REDIS_URL = os.environ.get("TEST_REDIS_CACHE_URL", "redis://127.0.0.1:6379/12")


def _redis_cache():
    from common.cache import RedisCache

    backend = RedisCache(REDIS_URL, {"KEY_PREFIX": f"t{uuid.uuid4().hex[:8]}"})
    try:
        backend.get("ping")
    except Exception as exc:  # any connection problem: no Redis here
        pytest.skip(f"no Redis at {REDIS_URL}: {exc}")
    return backend


def test_redis_cache_reuses_one_client_and_behaves_like_djangos():
    backend = _redis_cache()
    client = backend._cache.get_client()
    assert backend._cache.get_client(write=True) is client
    assert backend._cache.get_client("some key") is client
    backend.set("history", [3.0, 2.0, 1.0], 30)
    assert backend.get("history") == [3.0, 2.0, 1.0]
    assert backend.add("history", [0.0], 30) is False
    backend.set("n", 1, 30)
    assert backend.incr("n") == 2
    backend.delete("history")
    assert backend.get("history", "gone") == "gone"
    backend.delete("n")


def test_production_settings_pick_the_reusing_backend():
    import subprocess
    import sys
    from pathlib import Path

    root = Path(__file__).resolve().parents[2]
    show = "from django.conf import settings as s; print(s.CACHES['default']['BACKEND'])"
    env = dict(os.environ, CACHE_URL="redis://127.0.0.1:6379/12")
    out = subprocess.run(
        [sys.executable, "manage.py", "shell", "-c", show],
        cwd=root, env=env, capture_output=True, text=True, check=True,
    ).stdout.strip().splitlines()[-1]  # fmt: skip
    assert out == "common.cache.RedisCache"


def test_redis_throttle_is_drfs_sliding_log_shared_and_atomic(settings, world, monkeypatch):
    """The Lua bucket decides as DRF's own code does, request by request, with the same
    Retry-After; two throttle objects (two workers) share one bucket."""
    from rest_framework.test import APIRequestFactory
    from rest_framework.throttling import SimpleRateThrottle
    from rest_framework.views import APIView

    from labs.api import throttling
    from labs.models import LabAPIKey

    backend = _redis_cache()
    monkeypatch.setattr(throttling, "caches", {"default": backend})
    settings.REST_FRAMEWORK = {**settings.REST_FRAMEWORK,
                               "DEFAULT_THROTTLE_RATES": {"api_key": "3/min"}}  # fmt: skip
    key = LabAPIKey.objects.get_from_key(world.keys["key_a"])
    request = APIRequestFactory().get("/api/v1/comparisons/")
    request.auth = key

    reference_key = f"reference-{uuid.uuid4().hex}"

    class Reference(SimpleRateThrottle):  # DRF's own code, on the per-process cache
        scope = "api_key"
        rate = "3/min"
        cache = caches["default"]

        def get_cache_key(self, request, view):
            return reference_key

    clock = [1000.0]
    ours = [throttling.LabAPIKeyRateThrottle(), throttling.LabAPIKeyRateThrottle()]
    ref = Reference()
    for t in (*ours, ref):
        t.timer = lambda: clock[0]
    decisions = []
    view = APIView()  # the throttles key on the request's API key, not the view
    for step, dt in enumerate([0, 1, 2, 3, 20, 40, 1, 0.5, 0.5, 59.4]):
        clock[0] += dt
        mine = ours[step % 2]  # alternate "workers"
        got, want = mine.allow_request(request, view), ref.allow_request(request, view)
        decisions.append(got)
        assert got == want, step
        if not got:
            assert mine.wait() == pytest.approx(ref.wait()), step
    # 1000, 1001, 1003 pass; 1006 and 1026: three in the last minute; 1066 (the first three
    # have left the window), 1067, 1067.5 pass; 1068 is the fourth; 1127.4: 1066 and 1067
    # have left
    assert decisions == [True, True, True, False, False, True, True, True, False, True]
    client = backend._cache.get_client()
    bucket = backend.make_and_validate_key(f"throttle_api_key_{key.prefix}:log")
    stored = client.lrange(bucket, 0, -1)
    assert len(stored) == 2  # 1127.4 and 1067.5, newest first
    assert float(stored[0]) == clock[0]
    client.delete(bucket)
