"""Two coordinators starting the analysis at once get one run and one result set; two
uploads of the same laboratory at once give two consecutive versions, none lost, or one
version when they are the same results (a retry)."""

from collections.abc import Callable
from io import StringIO

import pytest
from django.contrib.auth import get_user_model
from django.core.management import call_command
from rest_framework.test import APIClient

from analysis.models import AnalysisRun, Score
from labs.models import Result
from labs.selectors import current_submissions
from labs.services import submission_from_file
from proficiency.models import Comparison
from tests.concurrency import at_once
from tests.faults.conftest import wait_until
from tests.labs.test_upload_files import csv_file, grid, records  # noqa: F401

pytestmark = [pytest.mark.services, pytest.mark.django_db(transaction=True)]
CODE = "IMU-2024-DEMO"


@pytest.mark.real_worker
def test_two_coordinators_start_at_once_one_run_one_result_set(workers):
    call_command("load_demo", password="demo-password-1", stdout=StringIO())
    demo = Comparison.objects.get(code=CODE)
    users = get_user_model().objects
    second = users.create_user("coordinator2", password="x-password-2", is_staff=True)
    demo.coordinators.add(second)
    clients = []
    for user in (users.get(username="coordinator"), second):
        client = APIClient()
        client.force_authenticate(user)
        clients.append(client)
    workers.start("w0")
    url = f"/api/v1/comparisons/{CODE}/analysis-runs/"
    a, b = at_once(*(lambda c=c: c.post(url) for c in clients))
    assert (a.status_code, b.status_code) == (202, 202), (a.content, b.content)
    assert a.json()["id"] == b.json()["id"]
    run = AnalysisRun.objects.get()  # one run

    def finished() -> bool:
        run.refresh_from_db()
        return run.status in ("succeeded", "failed")

    wait_until(finished, "the run", workers, timeout=60)
    assert run.status == "succeeded", run.error
    accepted = Result.objects.filter(submission__in=current_submissions(demo)).count()
    scores = Score.objects.filter(run=run)
    assert scores.count() == accepted == scores.values("result_id").distinct().count() == 891
    assert Score.objects.count() == 891  # one result set in the whole database


def test_two_uploads_of_one_lab_at_once_give_two_versions(grid):  # noqa: F811
    participant, user = grid
    changed = records()[::-1]
    changed[0] = {**changed[0], "sensitivity": "432.5"}  # a correction: other content
    first, second = csv_file(records()), csv_file(changed)

    def upload(data: bytes) -> Callable[[], object]:
        return lambda: submission_from_file(
            participant=participant, data=data, filename="r.csv", user=user, submit=True
        )

    out = at_once(upload(first), upload(second))
    assert not [o for o in out if isinstance(o, BaseException)], out
    assert sorted(s.version for s in out) == [1, 2]
    stored = participant.submissions.order_by("version")
    assert list(stored.values_list("version", "status")) == [(1, "submitted"), (2, "submitted")]
    for submission in stored:
        assert submission.results.count() == 3600
        assert submission.results.values("measurement_point").distinct().count() == 3600


def test_two_identical_uploads_of_one_lab_at_once_give_one_version(grid):  # noqa: F811
    """A client retrying after a timeout: the same results (rows in another order) twice."""
    participant, user = grid
    first, second = csv_file(records()), csv_file(records()[::-1])

    def upload(data: bytes) -> Callable[[], object]:
        return lambda: submission_from_file(
            participant=participant, data=data, filename="r.csv", user=user, submit=True
        )

    out = at_once(upload(first), upload(second))
    assert not [o for o in out if isinstance(o, BaseException)], out
    assert [s.version for s in out] == [1, 1]
    assert sorted(s.replayed for s in out) == [False, True]
    stored = participant.submissions.order_by("version")
    assert list(stored.values_list("version", "status")) == [(1, "submitted")]
    assert stored.get().results.count() == 3600
