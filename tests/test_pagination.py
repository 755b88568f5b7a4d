"""Pagination: every list page and endpoint that grows without bound
serves a fixed page size, and its next-page link leads to the rest.

Rows are added in bulk to the security world (``tests/security/world.py``); each test
reads page 1, checks its size and the link to page 2, follows it and checks that pages 1
and 2 together hold every row exactly once.
"""

from __future__ import annotations

import re
from collections.abc import Callable
from typing import Any

import pytest
from django.core.cache import cache

from analysis.models import AnalysisRun, Report, Score
from labs.models import Participant, RawFile, RawRecord, Result, Submission
from proficiency.models import Comparison, ComparisonStatus, MeasurementPoint
from tests.factories import ComparisonFactory, LaboratoryFactory
from tests.security.world import C1, LAB_A_CODE, World

pytestmark = pytest.mark.django_db

API_PAGE = 100  # settings.REST_FRAMEWORK["PAGE_SIZE"]
#: what identifies a measurement point in the API (the points have no id there)
POINT = ("device__name", "axis", "frequency_hz", "bench", "direction")


@pytest.fixture(autouse=True)
def _fresh_throttle_buckets():
    cache.clear()


@pytest.fixture
def world(django_capture_on_commit_callbacks) -> World:
    from tests.security.world import build_world

    return build_world(django_capture_on_commit_callbacks)


def _part_a(world: World) -> Participant:
    return Participant.objects.get(comparison=world.c1, code=LAB_A_CODE)


def add_versions(world: World, n: int) -> set[int]:
    """``n`` more draft versions of lab A (the world has versions 1 and 2)."""
    part = _part_a(world)
    Submission.objects.bulk_create(
        Submission(participant=part, version=v, status=Submission.Status.DRAFT)
        for v in range(3, 3 + n)
    )
    return set(part.submissions.values_list("version", flat=True))


def add_raw_records(world: World, n: int) -> set[int]:
    part = _part_a(world)
    submission = part.submissions.get(version=1)
    files = RawFile.objects.bulk_create(
        RawFile(sha256=f"{i:064x}", file=f"raw/{i}.csv", size=10) for i in range(n)
    )
    RawRecord.objects.bulk_create(
        RawRecord(
            participant=part,
            submission=submission,
            measurement_point=world.point,
            data_file=f,
            data_name=f"rec{i}.csv",
            metadata={"fs_hz": 1000},
        )
        for i, f in enumerate(files)
    )
    return set(RawRecord.objects.filter(participant=part).values_list("pk", flat=True))


def add_participants(world: World, n: int) -> set[str]:
    """``n`` more participants in comparison 1, each with a submitted version 1."""
    parts = Participant.objects.bulk_create(
        Participant(comparison=world.c1, laboratory=LaboratoryFactory.create(), code=f"P{i:03d}")
        for i in range(n)
    )
    Submission.objects.bulk_create(
        Submission(participant=p, version=1, status=Submission.Status.SUBMITTED) for p in parts
    )
    return set(Participant.objects.filter(comparison=world.c1).values_list("code", flat=True))


def add_reports(world: World, n: int) -> set[str]:
    summary = world.report_summary
    Report.objects.bulk_create(
        Report(
            comparison=world.c1,
            run=summary.run,
            kind=summary.kind,
            version=100 + i,
            file=summary.file.name,
        )
        for i in range(n)
    )
    return set(Report.objects.filter(comparison=world.c1).values_list("token", flat=True))


def add_runs(world: World, n: int) -> set[int]:
    AnalysisRun.objects.bulk_create(
        AnalysisRun(comparison=world.c1, status=AnalysisRun.Status.FAILED, error="x")
        for _ in range(n)
    )
    return set(AnalysisRun.objects.filter(comparison=world.c1).values_list("pk", flat=True))


def add_points(world: World, n: int) -> set[int]:
    device = world.point.device
    MeasurementPoint.objects.bulk_create(
        MeasurementPoint(
            comparison=world.c1,
            device=device,
            axis="Y",
            frequency_hz=1000.0 + i,
            bench="linear",
            direction="vertical",
        )
        for i in range(n)
    )
    return set(MeasurementPoint.objects.filter(comparison=world.c1).values_list(*POINT))


def add_comparisons(world: World, n: int) -> set[str]:
    """``n`` more comparisons lab A takes part in."""
    for _ in range(n):
        c = ComparisonFactory.create(status=ComparisonStatus.OPEN)
        Participant.objects.create(comparison=c, laboratory=world.lab_a, code=LAB_A_CODE)
    return set(
        Comparison.objects.filter(participants__laboratory=world.lab_a).values_list(
            "code", flat=True
        )
    )


def add_scores(world: World, n: int) -> set[int]:
    """``n`` more scores in the current run, on results of lab A's version 1."""
    add_points(world, n)
    submission = _part_a(world).submissions.get(version=1)
    new_points = MeasurementPoint.objects.filter(comparison=world.c1, axis="Y")
    results = Result.objects.bulk_create(
        Result(
            submission=submission,
            measurement_point=p,
            value=123.0,
            unit="mV/(m/s^2)",
            expanded_uncertainty=0.8,
            coverage_factor=2.0,
        )
        for p in new_points
    )
    Score.objects.bulk_create(
        Score(run=world.run, result=r, d=0.0, d_percent=0.0, en=0.0, zeta=0.0, flag="ok")
        for r in results
    )
    scores = Score.objects.filter(run=world.run)
    return set(
        scores.values_list(
            "result__submission__participant__code",
            *(f"result__measurement_point__{f}" for f in POINT),
        )
    )


# --- web pages ---------------------------------------------------------------------------

#: (persona, url, rows per page, add rows -> all keys, regex of a row's key in the html)
WEB: list[tuple[str, str, int, Callable[[World, int], set[Any]], str]] = [
    ("a_staff", f"/lab/comparisons/{C1}/submissions/", 25, add_versions,
     rf'href="/lab/comparisons/{C1}/submissions/(\d+)/"'),
    ("a_staff", f"/lab/comparisons/{C1}/raw-data/", 25, add_raw_records,
     rf'href="/lab/comparisons/{C1}/raw-data/(\d+)/"'),
    ("coord1", f"/coordinator/{C1}/review/", 50, add_participants,
     rf'href="/coordinator/{C1}/review/(\w+)/v\d+/"'),
    ("coord1", f"/reports/{C1}/", 50, add_reports, r'href="/api/v1/reports/([\w-]+)/pdf"'),
    ("coord1", f"/coordinator/{C1}/analysis/runs/", 25, add_runs,
     rf'href="/coordinator/{C1}/analysis/runs/(\d+)/"'),
]  # fmt: skip


def _keys(pattern: str, html: str, cast: type) -> list[Any]:
    return [cast(k) for k in re.findall(pattern, html)]


@pytest.mark.parametrize(("persona", "url", "size", "add", "pattern"), WEB)
def test_web_list_is_paginated(world, persona, url, size, add, pattern):
    everything = add(world, size + 3)
    cast = str if add in (add_reports, add_participants) else int
    client = world.client(persona)
    first = client.get(url)
    assert first.status_code == 200
    html = first.content.decode()
    page1 = _keys(pattern, html, cast)
    # a row may link its key twice (e.g. name and button): count distinct keys
    assert len(set(page1)) == size
    assert 'href="?page=2"' in html
    second = client.get(url + "?page=2")
    assert second.status_code == 200
    page2 = set(_keys(pattern, second.content.decode(), cast))
    assert 'href="?page=3"' not in second.content.decode()
    assert len(page2) == len(everything) - size
    assert set(page1) | page2 == everything and not set(page1) & page2


# --- API ---------------------------------------------------------------------------------

#: (persona, url, add rows -> all keys, key of a row in the JSON)
API: list[tuple[str, str, Callable[[World, int], set[Any]], tuple[str, ...]]] = [
    ("key_a", "/api/v1/comparisons/", add_comparisons, ("code",)),
    ("key_a", f"/api/v1/comparisons/{C1}/measurands/", add_points, ("device", *POINT[1:])),
    ("key_a", f"/api/v1/comparisons/{C1}/submissions/", add_versions, ("version",)),
    ("key_a", f"/api/v1/comparisons/{C1}/raw-data/", add_raw_records, ("id",)),
    ("coord1", f"/api/v1/comparisons/{C1}/analysis-runs/", add_runs, ("id",)),
    ("coord1", f"/api/v1/comparisons/{C1}/scores/", add_scores, ("lab", "device", *POINT[1:])),
]


@pytest.mark.parametrize(("persona", "url", "add", "key"), API)
def test_api_list_is_paginated(world, persona, url, add, key):
    everything = add(world, API_PAGE + 3)
    client = world.client(persona)
    first = client.get(url)
    assert first.status_code == 200, first.content
    body = first.json()
    assert body["count"] == len(everything)
    assert len(body["results"]) == API_PAGE
    assert body["previous"] is None and body["next"].endswith("page=2")
    second = client.get(body["next"])
    assert second.status_code == 200
    rest = second.json()
    assert rest["next"] is None and len(rest["results"]) == len(everything) - API_PAGE
    keys = [tuple(r[k] for k in key) for r in body["results"] + rest["results"]]
    if len(key) == 1:
        keys = [k for (k,) in keys]
    assert len(keys) == len(set(keys)) and set(keys) == everything
