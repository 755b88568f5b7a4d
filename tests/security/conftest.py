"""The world every security test probes (``tests/security/world.py``), built once per test
module and rolled back after it.

Building the world (three laboratories, two rounds, an analysis run, two reports and an
archive) takes a second and a half; the tests of a module only read it or change it inside
their own transaction. So the module's first test that asks for ``world`` builds it inside
a transaction that stays open until the module ends (pytest-django's non-transactional tests
run in a savepoint inside it, rolled back after each test); every test then gets the world
read afresh from the database, so a change one test makes to the objects it was handed
cannot reach the next. The world is for non-transactional tests only (a transactional
test's flush would empty the open transaction).
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import fields, replace
from typing import Any

import pytest

#: the settings the autouse fixtures of tests/conftest.py give a test, which the module's
#: world is built under (it is built before them, outside any one test); DEBUG off as below
BUILD_SETTINGS = {
    "DEBUG": False,
    "PASSWORD_HASHERS": ["django.contrib.auth.hashers.MD5PasswordHasher"],
    "CHART_WARMING": False,
}


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """Within each module, the tests that use the shared world after those that do not:
    a test without it then never sees the world's rows, whichever tests were selected (the
    other tests' places in the session stay as they were)."""
    places: dict[Any, list[int]] = {}
    for item in items:
        if "world" in getattr(item, "fixturenames", ()):
            places.setdefault(item.path, [])
    for i, item in enumerate(items):
        if item.path in places:
            places[item.path].append(i)
    for where in places.values():
        module = [items[i] for i in where]
        module.sort(key=lambda item: "world" in getattr(item, "fixturenames", ()))
        for i, item in zip(where, module, strict=True):
            items[i] = item


@pytest.fixture(scope="module")
def module_world(django_db_setup, django_db_blocker, tmp_path_factory) -> Iterator[Any]:
    """The world, built once for the module in a transaction rolled back at its end; with
    the MEDIA_ROOT its reports and archive were written to."""
    from django.test import TestCase
    from django.test.utils import override_settings

    from config.celery import app
    from tests.security.world import build_world

    media = tmp_path_factory.mktemp("world") / "media"
    eager = app.conf.task_always_eager
    with django_db_blocker.unblock():
        # Django's TestCase atomics (durable blocks inside them pass); not in django-stubs
        atomics = TestCase._enter_atomics()  # type: ignore[attr-defined]
        try:
            app.conf.task_always_eager = True
            with override_settings(MEDIA_ROOT=media, **BUILD_SETTINGS):
                built = build_world(TestCase.captureOnCommitCallbacks)
        except BaseException:
            TestCase._rollback_atomics(atomics)  # type: ignore[attr-defined]
            raise
        finally:
            app.conf.task_always_eager = eager
    try:
        yield built, media
    finally:
        with django_db_blocker.unblock():
            TestCase._rollback_atomics(atomics)  # type: ignore[attr-defined]


def _transactional(request: pytest.FixtureRequest) -> bool:
    marker = request.node.get_closest_marker("django_db")
    return bool(marker and (marker.kwargs.get("transaction") or marker.args[:1] == (True,))) or (
        "transactional_db" in request.fixturenames or "live_server" in request.fixturenames
    )


def _reloaded(saved: Any) -> Any:
    """``saved`` (a World) with every model instance read again from the database."""
    from django.db.models import Model

    def fresh(value: Any) -> Any:
        if isinstance(value, Model):
            return type(value)._default_manager.get(pk=value.pk)
        if isinstance(value, dict):
            return {k: fresh(v) for k, v in value.items()}
        return value

    return replace(saved, **{f.name: fresh(getattr(saved, f.name)) for f in fields(saved)})


@pytest.fixture
def world(request, module_world, settings):
    if _transactional(request):  # its flush would empty the module's open transaction
        pytest.fail(
            "the security world is for non-transactional tests (tests/security/conftest.py)"
        )
    request.getfixturevalue("db")
    saved, media = module_world
    settings.DEBUG = False  # production error pages: no tracebacks, no settings in bodies
    settings.MEDIA_ROOT = media  # where the world's reports and archive are
    return _reloaded(saved)
