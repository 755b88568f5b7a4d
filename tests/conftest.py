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
