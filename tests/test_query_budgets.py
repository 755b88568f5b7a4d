"""Query budgets: the main pages and endpoints run the same number of SQL
queries whatever the number of rows behind them (no N+1), and stay under a stated budget.

Each route is measured twice on the security world (``tests/security/world.py``): once at
size N (one growth step: extra laboratories with results, extra points, an extra draft
version of lab A, raw records, another analysis run and report) and once at size ~3N (two
more steps). The two counts must be equal, and at most the route's budget.
"""

from __future__ import annotations

import hashlib
from collections.abc import Callable
from typing import Any

import pytest
from django.core.cache import cache
from django.core.files.base import ContentFile
from django.db import connection
from django.test.utils import CaptureQueriesContext

from analysis.models import AnalysisRun, Report
from analysis.reports.services import report_issue
from analysis.services import analysis_run_start
from labs.models import Participant, RawFile, RawRecord, Submission
from proficiency.models import Comparison, ComparisonStatus, MeasurementPoint
from tests.factories import LaboratoryFactory, MeasurementPointFactory
from tests.security.world import LAB_A_CODE, World, _submission, build_world

pytestmark = pytest.mark.django_db

C1 = "SEC-C1"

#: (persona, url, budget, setup): budget is the most queries the route may run at any size
#: (measured 2026-11-23, plus 2); setup "published" measures with comparison 1 published
#: (what a laboratory needs to see scores and reports), else as built (analysed); every
#: signed-in page also counts the unread notices for the navigation's badge (one query)
ROUTES: list[tuple[str, str, int, str]] = [
    # laboratory web pages
    ("a_staff", "/lab/", 9, ""),
    ("a_staff", f"/lab/comparisons/{C1}/", 14, ""),  # + the inbox badge, the scope, a kit?
    ("a_staff", f"/lab/comparisons/{C1}/kit/", 10, ""),
    ("a_staff", f"/lab/comparisons/{C1}/results/", 13, ""),
    ("a_staff", f"/lab/comparisons/{C1}/submissions/", 10, ""),
    ("a_staff", f"/lab/comparisons/{C1}/raw-data/", 13, ""),
    # the laboratory's history: its laboratories, participations, published runs (the
    # publications, then the runs of rounds published without one) and scores
    ("a_staff", "/lab/history/", 14, "published"),
    ("a_staff", f"/reports/{C1}/", 11, "published"),
    # + its performance summary: the grouped counts, the maxima, the largest |En| and |z|
    ("a_staff", f"/results/{C1}/", 23, "published"),
    ("a_staff", f"/results/{C1}/scores/", 20, "published"),
    ("a_staff", f"/results/{C1}/archive/status/", 8, "published"),
    # every chart drawn (the cache is cleared): the point's and Mandel's (measured 2026-12-03)
    ("a_staff", f"/results/{C1}/charts/", 22, "published"),
    ("a_staff", f"/results/{C1}/charts/z.png", 9, "published"),
    # laboratory API (API key)
    ("key_a", "/api/v1/comparisons/", 5, ""),
    ("key_a", f"/api/v1/comparisons/{C1}/measurands/", 6, ""),
    ("key_a", f"/api/v1/comparisons/{C1}/submissions/", 6, ""),
    ("key_a", f"/api/v1/comparisons/{C1}/submissions/2/", 6, ""),
    ("key_a", f"/api/v1/comparisons/{C1}/scores/", 7, "published"),
    ("key_a", f"/api/v1/comparisons/{C1}/raw-data/", 6, ""),
    ("key_a", f"/api/v1/comparisons/{C1}/reports/", 4, "published"),
    # coordinator web pages
    # + the notices list, the scopes and the applications' counts
    ("coord1", f"/coordinator/{C1}/", 13, ""),
    ("coord1", f"/coordinator/{C1}/review/", 10, ""),
    ("coord1", f"/coordinator/{C1}/results/", 19, ""),
    ("coord1", f"/coordinator/{C1}/analysis/runs/", 11, ""),
    ("coord1", f"/coordinator/{C1}/scores/", 19, ""),
    ("coord1", f"/coordinator/{C1}/archive/status/", 8, ""),
    ("coord1", f"/coordinator/{C1}/performance/", 19, ""),
    # + the participant's laboratory's history over the coordinator's published rounds
    ("coord1", f"/coordinator/{C1}/performance/{LAB_A_CODE}/", 20, "published"),
    ("coord1", f"/coordinator/{C1}/charts/", 21, ""),
    ("coord1", f"/coordinator/{C1}/charts/mandel-h.svg", 8, ""),
    ("coord1", f"/coordinator/{C1}/charts/overview.svg?lab={LAB_A_CODE}", 8, ""),
    ("coord1", f"/coordinator/{C1}/raw-data/", 10, ""),
    ("coord1", f"/coordinator/{C1}/kits/", 10, ""),
    ("coord1", f"/reports/{C1}/", 11, ""),
    # coordinator API (session)
    ("coord1", f"/api/v1/comparisons/{C1}/scores/", 10, ""),
    ("coord1", f"/api/v1/comparisons/{C1}/analysis-runs/", 9, ""),
    ("coord1", f"/api/v1/comparisons/{C1}/reports/", 8, ""),
    ("coord1", f"/api/v1/comparisons/{C1}/raw-data/", 9, ""),
]


def _raw_record(participant: Participant, submission: Submission, point: MeasurementPoint) -> None:
    body = f"t,x,y,z\n0,{point.pk},{submission.pk},0\n".encode()
    sha = hashlib.sha256(body).hexdigest()
    raw = RawFile(sha256=sha, size=len(body))
    raw.file.save(f"{sha}.csv", ContentFile(body), save=False)
    raw.save()
    RawRecord.objects.create(
        participant=participant, submission=submission, measurement_point=point,
        data_file=raw, data_name=f"rec-{point.pk}.csv", metadata={"fs_hz": 1000},
    )  # fmt: skip


def grow(world: World, capture: Callable[..., Any]) -> None:
    """One growth step: 2 points, 2 laboratories with results on every point, a new draft
    version of lab A, a raw record per point for lab A, a new analysis run, new reports."""
    c1 = world.c1
    device = world.point.device
    base = MeasurementPoint.objects.filter(comparison=c1).count()
    for i in range(2):
        MeasurementPointFactory.create(device=device, frequency_hz=100.0 + 10 * (base + i))
    points = list(MeasurementPoint.objects.filter(comparison=c1).order_by("pk"))
    n_parts = Participant.objects.filter(comparison=c1).count()
    added = []
    for i in range(2):
        lab = LaboratoryFactory.create(name=f"Growth lab {n_parts + i}")
        part = Participant.objects.create(comparison=c1, laboratory=lab, code=f"G{n_parts + i}")
        _submission(part, 1, Submission.Status.ACCEPTED, 123.0 + 0.1 * i, points)
        added.append(part)
    part_a = Participant.objects.get(comparison=c1, code=LAB_A_CODE)
    version = Submission.objects.filter(participant=part_a).count() + 1
    _submission(part_a, version, Submission.Status.DRAFT, 123.4, points)
    latest = Submission.objects.get(participant=part_a, version=version)
    for p in points[-2:]:
        _raw_record(part_a, latest, p)
    with capture(execute=True):
        run = analysis_run_start(comparison=c1, user=world.users["coord1"])
    run.refresh_from_db()
    assert run.status == AnalysisRun.Status.SUCCEEDED, run.error
    c1.refresh_from_db()
    report_issue(comparison=c1, kind=Report.Kind.SUMMARY)
    report_issue(comparison=c1, kind=Report.Kind.PARTICIPANT, participant=part_a)
    report_issue(comparison=c1, kind=Report.Kind.PARTICIPANT, participant=added[0])


def count(world: World, persona: str, url: str, setup: str) -> tuple[int, int, list[str]]:
    cache.clear()  # throttle buckets and cached fragments start empty each time
    client = world.client(persona)
    status = world.c1.status
    if setup == "published":
        Comparison.objects.filter(pk=world.c1.pk).update(status=ComparisonStatus.PUBLISHED)
    try:
        with CaptureQueriesContext(connection) as ctx:
            response = client.get(url)
    finally:
        Comparison.objects.filter(pk=world.c1.pk).update(status=status)
    return response.status_code, len(ctx.captured_queries), [q["sql"] for q in ctx.captured_queries]


@pytest.fixture
def grown(django_capture_on_commit_callbacks, settings):
    settings.DEBUG = False
    world = build_world(django_capture_on_commit_callbacks)
    grow(world, django_capture_on_commit_callbacks)
    return world


def _sizes(world: World) -> dict[str, int]:
    return {
        "points": MeasurementPoint.objects.filter(comparison=world.c1).count(),
        "participants": Participant.objects.filter(comparison=world.c1).count(),
        "runs": AnalysisRun.objects.filter(comparison=world.c1).count(),
        "raw": RawRecord.objects.count(),
        "lab_a_versions": Submission.objects.filter(participant__code=LAB_A_CODE).count(),
    }


def test_query_counts_constant_as_rows_grow(grown, django_capture_on_commit_callbacks):
    """All routes in one test: the world is expensive (analysis runs, PDF reports)."""
    small = {(p, u): count(grown, p, u, setup) for p, u, _, setup in ROUTES}
    before = _sizes(grown)
    for _ in range(2):
        grow(grown, django_capture_on_commit_callbacks)
    after = _sizes(grown)
    assert (
        after["points"] >= 2 * before["points"] and after["participants"] > before["participants"]
    )
    assert after["runs"] == before["runs"] + 2
    problems = []
    for persona, url, budget, setup in ROUTES:
        s_status, s_n, _ = small[(persona, url)]
        b_status, b_n, b_sql = count(grown, persona, url, setup)
        if s_status != 200 or b_status != 200:
            problems.append(f"{persona} {url}: status {s_status}/{b_status}")
        elif s_n != b_n:
            extra = "\n    ".join(b_sql)
            problems.append(f"{persona} {url}: {s_n} queries at N, {b_n} at 3N\n    {extra}")
        elif b_n > budget:
            problems.append(f"{persona} {url}: {b_n} queries > budget {budget}")
    assert not problems, "\n".join(problems)
