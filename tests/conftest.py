"""Shared fixtures. Factories are imported inside the fixtures so that the Django-free
tests (tests/analysis/core, tests/labs/test_importers.py) also run with ``-p no:django``."""

import pytest


@pytest.fixture(autouse=True)
def fast_password_hasher(request):
    """Password hashing is deliberately slow; tests do not need that strength."""
    if "settings" not in request.fixturenames and not request.config.pluginmanager.hasplugin(
        "django"
    ):
        return
    settings = request.getfixturevalue("settings")
    settings.PASSWORD_HASHERS = ["django.contrib.auth.hashers.MD5PasswordHasher"]


@pytest.fixture(autouse=True)
def celery_eager(request):
    """Tasks run in-process unless a test asks for the real worker (``real_worker`` mark),
    also when CELERY_BROKER_URL points at a real broker (as in CI)."""
    if "real_worker" in request.keywords or not request.config.pluginmanager.hasplugin("django"):
        yield
        return
    from proficiency.celery import app

    old = app.conf.task_always_eager
    app.conf.task_always_eager = True
    yield
    app.conf.task_always_eager = old


@pytest.fixture
def comparison(db):
    from tests.factories import ComparisonFactory

    return ComparisonFactory()


@pytest.fixture
def device(comparison):
    from tests.factories import DeviceFactory

    return DeviceFactory(comparison=comparison)


@pytest.fixture
def point(device):
    from tests.factories import MeasurementPointFactory

    return MeasurementPointFactory(device=device)
