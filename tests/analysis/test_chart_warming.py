"""A succeeded run's charts are drawn in the background (docs/architecture.md §3.1): the
coordinator's first view of the charts page draws nothing, every chart it shows is in the
cache under the page's own keys, and a second delivery of the task draws nothing new."""

from __future__ import annotations

import re

import pytest
from django.core.cache import cache

from analysis import charts
from analysis.chart_cache import chart_key
from analysis.models import AnalysisRun
from analysis.services import analysis_run_start
from analysis.tasks import charts_warm_task
from proficiency.models import MeasurementPoint
from tests.analysis.test_web_numbers import C, login


class Draws:
    """Every chart drawn passes through ``charts._svg`` (inline SVG): counted; once
    ``forbid`` is set, a draw fails the test."""

    def __init__(self, real) -> None:
        self.real, self.count, self.forbid = real, 0, False

    def __call__(self, *args, **kwargs):
        assert not self.forbid, "a chart was drawn where the cache should have held it"
        self.count += 1
        return self.real(*args, **kwargs)


@pytest.fixture
def draws(monkeypatch) -> Draws:
    spy = Draws(charts._svg)
    monkeypatch.setattr(charts, "_svg", spy)
    return spy


def svgs(page: bytes) -> list[str]:
    return re.findall(r"<svg.*?</svg>", page.decode(), re.S)


def cached_svgs(keys: list[str]) -> list[str]:
    """The SVG texts under ``keys`` (an entry holds one, a list or a dict of them)."""
    out: list[str] = []
    for found in map(cache.get, keys):
        values = found.values() if isinstance(found, dict) else found
        out += [found] if isinstance(found, str) else list(values)
    return out


def finished_run(demo, capture) -> AnalysisRun:
    with capture(execute=True):  # the run's task, then the warming task sent on its commit
        run = analysis_run_start(comparison=demo, user=None)
    run.refresh_from_db()
    assert run.status == "succeeded", run.error
    return run


def page_keys(run: AnalysisRun) -> list[str]:
    """The keys of a coordinator's first view, written out from docs/architecture.md §3.1:
    the first point (by the points' order) and its first Youden pair (benches first)."""
    limit = run.comparison.en_limit
    first = MeasurementPoint.objects.filter(assigned_values__run=run)[0]  # Meta.ordering
    twin = MeasurementPoint.objects.filter(
        assigned_values__run=run, device=first.device, axis=first.axis,
        frequency_hz=first.frequency_hz,
    ).exclude(bench=first.bench)[0]  # fmt: skip
    devices = tuple(run.comparison.devices.order_by("pk").values_list(
        "name", "unit", "nominal_sensitivity", "tolerance", "tolerance_relative"))  # fmt: skip
    std = [chart_key(run, f"std:{name}", first.pk, limit, None, "inline")
           for name in ("z", "en-bars", "density", "doe")]  # fmt: skip
    return [
        chart_key(run, "point", first.pk, None, limit),
        chart_key(run, "frequency", *devices),
        *std,
        chart_key(run, "std:youden", f"{first.pk}-{twin.pk}", None, "inline"),
        chart_key(run, "std:mandel-h", None, "inline"),
        chart_key(run, "std:mandel-k", None, "inline"),
    ]


def test_the_first_view_of_a_new_runs_charts_draws_nothing(
    client, demo, settings, draws, django_capture_on_commit_callbacks
):
    settings.CHART_WARMING = True
    cache.clear()
    run = finished_run(demo, django_capture_on_commit_callbacks)
    warmed = draws.count
    keys = page_keys(run)
    assert all(cache.get(key) is not None for key in keys), "a chart of the page not warmed"
    draws.forbid = True
    login(client, "coordinator")
    response = client.get(C + "charts/")
    assert response.status_code == 200
    shown = svgs(response.content)
    # the page shows exactly what was drawn: the point's six charts, the Youden plot,
    # Mandel's h and k and one frequency chart per device
    n_devices = demo.devices.count()
    assert len(shown) == warmed == 6 + 1 + 2 + n_devices
    assert sorted(shown) == sorted(s.strip() for s in cached_svgs(keys))  # as drawn
    assert charts_warm_task.delay(run.pk).get() is True  # delivered again: nothing drawn
    assert draws.count == warmed


def test_without_warming_a_run_draws_no_chart(demo, settings, draws,
                                             django_capture_on_commit_callbacks):  # fmt: skip
    settings.CHART_WARMING = False  # as every other test (tests/conftest.py)
    cache.clear()
    run = finished_run(demo, django_capture_on_commit_callbacks)
    assert draws.count == 0
    assert all(cache.get(key) is None for key in page_keys(run))


def test_warming_a_run_that_is_gone_or_failed_draws_nothing(run, draws):
    AnalysisRun.objects.filter(pk=run.pk).update(status="failed")
    assert charts_warm_task.delay(run.pk).get() is False
    assert charts_warm_task.delay(run.pk + 1000).get() is False
    assert draws.count == 0


def test_the_page_asks_for_the_keys_warmed(client, run, demo):
    """The warming draws for the page's default reader and choice (no query, coordinator):
    the page's Youden spec and point specs name the keys warmed."""
    cache.clear()
    login(client, "coordinator")
    assert client.get(C + "charts/").status_code == 200
    assert all(cache.get(key) is not None for key in page_keys(run))
