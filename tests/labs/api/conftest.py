"""Fixtures shared by the API tests: throttle buckets emptied before each test (a test's
requests must not count against the next one's limits) and the default world of
``tests.labs.api.build_world`` (modules that need another world define their own)."""

import pytest
from django.core.cache import cache

from tests.labs.api import build_world


@pytest.fixture(autouse=True)
def _fresh_throttle_buckets():
    cache.clear()


@pytest.fixture
def world():
    return build_world()
