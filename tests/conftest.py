"""Shared fixtures."""

import pytest

from tests.factories import (
    ComparisonFactory,
    DeviceFactory,
    MeasurementPointFactory,
    ResultFactory,
)


@pytest.fixture(autouse=True)
def fast_password_hasher(settings):
    """Password hashing is deliberately slow; tests do not need that strength."""
    settings.PASSWORD_HASHERS = ["django.contrib.auth.hashers.MD5PasswordHasher"]


@pytest.fixture
def comparison(db):
    return ComparisonFactory()


@pytest.fixture
def device(comparison):
    return DeviceFactory(comparison=comparison)


@pytest.fixture
def point(device):
    return MeasurementPointFactory(device=device)


@pytest.fixture
def result(db):
    return ResultFactory()
