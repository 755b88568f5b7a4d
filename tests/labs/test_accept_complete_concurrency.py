""" "Accept all complete" under concurrency (PostgreSQL): the set is decided under the
participants' row locks, so a new version arriving meanwhile is waited for and left out,
and two coordinators accepting at once accept each version once, with one notice."""

from __future__ import annotations

import threading
import time

import pytest
from django.db import connection, transaction

from labs.models import Notice, Participant, Submission
from labs.review import submissions_accept_complete
from tests.factories import (
    ComparisonFactory,
    MeasurementPointFactory,
    ParticipantFactory,
    ResultFactory,
    SubmissionFactory,
)

pytestmark = pytest.mark.django_db(transaction=True)


@pytest.fixture
def round_(needs_postgres):
    comparison = ComparisonFactory.create(code="ACCEPT-01")
    point = MeasurementPointFactory.create(device__comparison=comparison)
    for code in ("L01", "L02"):
        participant = ParticipantFactory.create(comparison=comparison, code=code)
        submission = SubmissionFactory.create(participant=participant, status="submitted")
        ResultFactory.create(submission=submission, measurement_point=point)
    return comparison


def in_thread(body):
    out: dict[str, object] = {}

    def run() -> None:
        try:
            out["value"] = body()
        except BaseException as exc:
            out["value"] = exc
        finally:
            connection.close()

    thread = threading.Thread(target=run)
    thread.start()
    return thread, out


def test_a_new_version_arriving_meanwhile_is_waited_for_and_left_out(round_):
    locked = threading.Event()

    def new_draft() -> None:
        with transaction.atomic():  # what submission_save does: the participant's row lock
            participant = Participant.objects.select_for_update().get(comparison=round_, code="L01")
            Submission.objects.create(participant=participant, version=2, status="draft")
            locked.set()
            time.sleep(1.0)

    thread, out = in_thread(new_draft)
    assert locked.wait(10)
    started = time.monotonic()
    accepted = submissions_accept_complete(comparison=round_, user=None)
    waited = time.monotonic() - started
    thread.join(30)
    assert out["value"] is None
    assert waited > 0.5  # it waited for the lock instead of reading the old latest version
    assert [s.participant.code for s in accepted] == ["L02"]
    statuses = dict(
        Submission.objects.filter(participant__comparison=round_, version=1).values_list(
            "participant__code", "status"
        )
    )
    assert statuses == {"L01": "submitted", "L02": "accepted"}


def test_two_at_once_accept_each_version_once(round_):
    barrier = threading.Barrier(2)

    def accept() -> list[str]:
        barrier.wait(10)
        return [s.participant.code for s in
                submissions_accept_complete(comparison=round_, user=None)]  # fmt: skip

    threads = [in_thread(accept) for _ in range(2)]
    for thread, _ in threads:
        thread.join(30)
    results: list = [out["value"] for _, out in threads]
    assert all(isinstance(r, list) for r in results), results
    assert sorted(code for r in results for code in r) == ["L01", "L02"]
    assert Submission.objects.filter(participant__comparison=round_, status="accepted").count() == 2
    assert Notice.objects.filter(comparison=round_, kind="accepted").count() == 2
