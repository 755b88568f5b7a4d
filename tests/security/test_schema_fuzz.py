"""Schema-driven fuzzing of the REST API (schemathesis) against its own OpenAPI schema.

The schema is fetched in-process from ``/api/schema/`` through the WSGI application and
every operation is called with generated inputs as two personas: lab A's API key and the
coordinator of comparison 1 (a real session cookie with its CSRF token). Inputs are both
valid (positive) and invalid (negative: wrong types, missing fields, values out of range,
control characters) for the schema. Each response must not be a server error and must
conform to the schema (status code, content type, headers, body). The data is
``tests/security/world.py``'s, created once per test; the examples of one operation share
it (a POST may change it for the next example, as in production).

It runs on whatever ``DATABASE_URL`` names; with ``REQUIRE_SERVICES=1`` (CI) that must be
PostgreSQL, which refuses what SQLite stores (NUL in text was a 500 on PostgreSQL only).

Bounded: ``MAX_EXAMPLES`` generated examples per operation and persona (shared by both
modes, drawn from either at random), on top of schemathesis' coverage phase, which runs
in full whatever the bound: for every operation its boundary values, each parameter's
missing, wrong-typed and out-of-range variants and the methods it does not implement.
Ten: with ``CI`` set the draw is derandomized (the ``ci`` hypothesis profile of
``tests/conftest.py``), the same few examples on every run, so more of them add little
there; a local run explores new ones (``FUZZ_MAX_EXAMPLES=200`` for a longer search), and
what it finds becomes an explicit test (``test_fuzz_findings.py``).
"""

from __future__ import annotations

import os

import pytest
import schemathesis
from django.conf import settings as django_settings
from hypothesis import HealthCheck, settings
from schemathesis.checks import not_a_server_error
from schemathesis.generation import GenerationMode
from schemathesis.specs.openapi.checks import (
    content_type_conformance,
    response_headers_conformance,
    response_schema_conformance,
    status_code_conformance,
)

from config.wsgi import application
from tests.security.world import World

MAX_EXAMPLES = int(os.environ.get("FUZZ_MAX_EXAMPLES", "10"))
CSRF = "fuzzfuzzfuzzfuzzfuzzfuzzfuzzfuzz"  # a 32-character CSRF secret, sent as cookie and header

pytestmark = pytest.mark.django_db
#: no server error, and responses that conform to the schema, for valid and invalid input.
#: (Left out: "positive data acceptance" flags every business rule the schema cannot
#: express, such as an unknown laboratory name; "negative data rejection" flags the API's
#: documented leniencies: an empty query parameter is no filter (``?status=``, ``?page=``),
#: a JSON number is accepted for a text field; "ignored auth" cannot know that the session
#: cookie authenticates too.)
CHECKS = [
    not_a_server_error,
    status_code_conformance,
    content_type_conformance,
    response_headers_conformance,
    response_schema_conformance,
]

HYPOTHESIS = settings(
    max_examples=MAX_EXAMPLES,
    deadline=None,
    derandomize=bool(os.environ.get("CI")),
    suppress_health_check=[
        HealthCheck.function_scoped_fixture,
        HealthCheck.too_slow,
        HealthCheck.filter_too_much,
        HealthCheck.data_too_large,
    ],
)


@pytest.fixture
def api_schema(world):
    loaded = schemathesis.openapi.from_wsgi("/api/schema/?format=json", application)
    loaded.config.generation.update(modes=[GenerationMode.POSITIVE, GenerationMode.NEGATIVE])
    return loaded


@pytest.fixture(autouse=True)
def on_postgresql_in_ci():
    """In CI the fuzzer must meet PostgreSQL, not SQLite (which stores NUL in text)."""
    from django.db import connection

    if os.environ.get("REQUIRE_SERVICES") == "1" and connection.vendor != "postgresql":
        pytest.fail(
            f"the schema fuzzer runs on {connection.vendor}, not PostgreSQL "
            "(REQUIRE_SERVICES=1: set DATABASE_URL to PostgreSQL)"
        )


def with_world_paths(case, world: World) -> None:
    """Lab A's objects in comparison 1 in the path, so that the calls reach the views
    (generated codes and ids would only meet 404)."""
    values = world.url_values() | {"id": world.run.pk}
    for name in case.path_parameters or {}:
        if name in values:
            case.path_parameters[name] = values[name]


@pytest.fixture
def key_headers(world) -> dict[str, str]:
    return {"Authorization": f"Api-Key {world.key_a_secret}"}


@pytest.fixture
def coordinator_auth(world, client) -> dict[str, dict[str, str]]:
    client.force_login(world.users["coord1"])
    session = client.cookies[django_settings.SESSION_COOKIE_NAME].value
    return {
        "headers": {"X-CSRFToken": CSRF},
        "cookies": {django_settings.SESSION_COOKIE_NAME: session, "csrftoken": CSRF},
    }


schema = schemathesis.pytest.from_fixture("api_schema")


@schema.parametrize()
@HYPOTHESIS
def test_api_as_lab_key(case, world, key_headers, caches_cleared):
    with_world_paths(case, world)
    case.call_and_validate(headers=key_headers, checks=CHECKS)


@schema.parametrize()
@HYPOTHESIS
def test_api_as_coordinator(case, world, coordinator_auth, caches_cleared):
    with_world_paths(case, world)
    case.call_and_validate(checks=CHECKS, **coordinator_auth)


@pytest.fixture(autouse=True)
def same_db_connection():
    """The WSGI requests run in the test's transaction: do not let Django close the
    connection at the end of each request (what its test client does too)."""
    from django.core import signals
    from django.db import close_old_connections

    for signal in (signals.request_started, signals.request_finished):
        signal.disconnect(close_old_connections)
    yield
    for signal in (signals.request_started, signals.request_finished):
        signal.connect(close_old_connections)


@pytest.fixture
def caches_cleared(settings):
    """No throttling in the fuzzer: the bucket of a key or user would run out."""
    settings.CACHES = {"default": {"BACKEND": "django.core.cache.backends.dummy.DummyCache"}}
