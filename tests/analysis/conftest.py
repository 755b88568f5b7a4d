"""Fixtures of the analysis tests that work on the demo round (coordination.demo)."""

from __future__ import annotations

from io import StringIO

import pytest
from django.core.management import call_command

from analysis.models import AnalysisRun
from analysis.services import analysis_run_start
from proficiency.models import Comparison, ComparisonStatus

DEMO_CODE = "IMU-2024-DEMO"


@pytest.fixture
def demo(db) -> Comparison:
    """The demo round, loaded as ``make run`` loads it (closed, 12 accepted submissions)."""
    call_command("load_demo", password="demo-password-1", stdout=StringIO())
    return Comparison.objects.get(code=DEMO_CODE)


@pytest.fixture
def run(demo, django_capture_on_commit_callbacks) -> AnalysisRun:
    """A succeeded analysis run of the demo round, which is then analysed."""
    with django_capture_on_commit_callbacks(execute=True):
        started = analysis_run_start(comparison=demo, user=None)
    started.refresh_from_db()
    assert started.status == "succeeded", started.error
    demo.refresh_from_db()
    assert demo.status == ComparisonStatus.ANALYSED
    return started
