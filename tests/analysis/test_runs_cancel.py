"""Cancelling an analysis run (API and run page): only the round's coordinators, the run
keeps no outputs, its queued tasks store nothing, and a new run can be started at once."""

import pytest
from django.contrib.auth import get_user_model
from django.contrib.auth.models import User
from rest_framework.test import APIClient

from analysis import services
from analysis.models import AnalysisChunk, AnalysisRun, AssignedValue, Score
from analysis.services import analysis_chunk_execute, analysis_run_execute
from tests.factories import ComparisonFactory, UserFactory

pytestmark = pytest.mark.django_db(transaction=True)
CODE = "IMU-2024-DEMO"


def user(name):
    return get_user_model().objects.get(username=name)


def api(u) -> APIClient:
    c = APIClient()
    if u is not None:
        c.force_authenticate(u)
    return c


@pytest.fixture
def running(demo, settings, monkeypatch):
    """A fanned-out run, planned, one of its 3 chunks stored, the other two queued."""
    settings.ANALYSIS_CHUNK_RESULTS = 300
    monkeypatch.setattr(services, "_dispatch", lambda run_id, todo, queue: None)
    run = AnalysisRun.objects.create(comparison=demo, parameters=services._parameters(demo))
    assert analysis_run_execute(run_id=run.pk) == "running"
    assert analysis_chunk_execute(run_id=run.pk, index=0) == "running"
    assert Score.objects.filter(run=run).count() == 308
    return run


def test_cancel_by_the_coordinator_keeps_nothing_and_a_new_run_starts(running, monkeypatch):
    coord = api(user("coordinator"))
    response = coord.post(f"/api/v1/analysis-runs/{running.pk}/cancel/")
    assert response.status_code == 200, response.content
    body = response.json()
    assert body["status"] == "cancelled" and body["error"] == "Cancelled by coordinator."
    assert not Score.objects.filter(run=running).exists()
    assert not AssignedValue.objects.filter(run=running).exists()
    # the chunks still queued find the run cancelled and store nothing
    assert analysis_chunk_execute(run_id=running.pk, index=1) == "cancelled"
    assert not Score.objects.filter(run=running).exists()
    assert not AnalysisChunk.objects.filter(run=running, index=1, done=True).exists()
    monkeypatch.undo()  # chunks sent again (eager)
    again = coord.post(f"/api/v1/comparisons/{CODE}/analysis-runs/")
    assert again.status_code == 202
    assert again.json()["id"] != running.pk and again.json()["status"] == "succeeded"
    # an ended run cannot be cancelled
    ended = coord.post(f"/api/v1/analysis-runs/{running.pk}/cancel/")
    assert ended.status_code == 409 and "cancelled" in ended.json()["detail"]


def test_a_chunk_storing_while_the_run_is_cancelled_stores_nothing(running, monkeypatch):
    """The cancellation lands between the chunk's computation and its storing."""
    real = services._compute_checked

    def cancelled_meanwhile(run, loaded):
        out = real(run, loaded)
        services.analysis_run_cancel(run=run, user=None)
        return out

    monkeypatch.setattr(services, "_compute_checked", cancelled_meanwhile)
    assert analysis_chunk_execute(run_id=running.pk, index=1) == "cancelled"
    running.refresh_from_db()
    assert (running.status, running.error) == ("cancelled", "Cancelled by a coordinator.")
    assert not Score.objects.filter(run=running).exists()
    assert running.chunks_done == 1


@pytest.mark.parametrize("persona", ["other_coordinator", "lab03", "anonymous"])
def test_others_cannot_cancel(running, persona):
    who: User | None
    if persona == "other_coordinator":
        other = UserFactory.create(username="other-coordinator")
        ComparisonFactory.create(code="OTHER-01").coordinators.add(other)
        who = other
    else:
        who = None if persona == "anonymous" else user(persona)
    response = api(who).post(f"/api/v1/analysis-runs/{running.pk}/cancel/")
    assert response.status_code == (401 if who is None else 404), response.content
    running.refresh_from_db()
    assert running.status == "running"
    assert Score.objects.filter(run=running).count() == 308


def test_run_page_has_a_cancel_button_that_works(client, running):
    client.force_login(user("coordinator"))
    page = client.get(f"/coordinator/{CODE}/analysis/runs/{running.pk}/")
    url = f"/coordinator/{CODE}/analysis/runs/{running.pk}/cancel/"
    assert page.status_code == 200 and f'action="{url}"' in page.content.decode()
    assert b"Cancel this run" in page.content
    response = client.post(url, follow=True)
    assert response.status_code == 200
    assert b"is cancelled; it keeps no results" in response.content
    assert b"Cancel this run" not in response.content
    running.refresh_from_db()
    assert running.status == "cancelled"
    assert not Score.objects.filter(run=running).exists()


def test_run_page_cancel_is_404_for_others(client, running):
    client.force_login(user("lab03"))
    url = f"/coordinator/{CODE}/analysis/runs/{running.pk}/cancel/"
    assert client.post(url).status_code == 404
    running.refresh_from_db()
    assert running.status == "running"
