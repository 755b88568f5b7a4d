"""The world every security test probes (``tests/security/world.py``)."""

import pytest


@pytest.fixture
def world(django_capture_on_commit_callbacks, settings):
    from tests.security.world import build_world

    settings.DEBUG = False  # production error pages: no tracebacks, no settings in bodies
    return build_world(django_capture_on_commit_callbacks)
