"""The same results with quantity rows sent twice at once through the API, on PostgreSQL
(docs/interfaces.md §3, docs/lifecycles.md §2): a retried upload, a retried request with
its ``Idempotency-Key``, the same key with other results, and a draft saved twice.  Each
pair stores exactly one version (or one draft) with one result set; the other request
answers it (201, ``Idempotent-Replayed: true``) or is refused (422); never a 500 from an
``IntegrityError``.  A phase written as 190 or −170, 180 or −180, is the same result: the
importer stores the wrap, and a retry that spells it the other way is still a retry.
"""

from __future__ import annotations

import datetime as dt

import pytest
from django.core.files.uploadedfile import SimpleUploadedFile
from django.utils import timezone
from rest_framework.test import APIClient

from labs.models import Result, Submission, SubmissionKey
from labs.services import api_key_create
from proficiency.services import measurement_points_generate
from tests.factories import ComparisonFactory, DeviceFactory, ParticipantFactory
from tests.faults.test_concurrency import at_once

pytestmark = [pytest.mark.services, pytest.mark.django_db(transaction=True)]

CODE = "RACE-Q"
SUBMIT = f"/api/v1/comparisons/{CODE}/submissions/"
AXES, FREQUENCIES = ("X", "Y", "Z"), (10, 20, 40, 80)
#: the phase each point's row gives, and the same phase spelled the other way round
PHASES = {10: ("190", "-170"), 20: ("-180", "180"), 40: ("540", "-180"), 80: ("0.5", "-359.5")}


@pytest.fixture
def lab(needs_postgres):
    comparison = ComparisonFactory.create(
        code=CODE, status="open", protocol="custom",
        submission_deadline=timezone.now() + dt.timedelta(days=7),
    )  # fmt: skip
    device = DeviceFactory.create(comparison=comparison, name="IMU 1", unit="D/(m/s^2)")
    measurement_points_generate(
        comparison=comparison, devices=[device], axes=list(AXES), frequencies_hz=list(FREQUENCIES),
        benches=["curvilinear"], directions=["tangential"],
        quantities=["magnitude", "phase", "angular_rate"],
    )  # fmt: skip
    participant = ParticipantFactory.create(comparison=comparison, code="L61")
    key = api_key_create(laboratory=participant.laboratory, name="daq", user=None)[1]
    return participant, key


def client(key: str) -> APIClient:
    c = APIClient()
    c.credentials(HTTP_AUTHORIZATION=f"Api-Key {key}")
    return c


def records(spelling: int = 0, shift: float = 0.0) -> list[dict]:
    """A complete table: each point's magnitude, phase and angular rate (per rad/s)."""
    out = []
    for axis in AXES:
        for f in FREQUENCIES:
            point = {"device": "IMU 1", "axis": axis, "frequency_hz": f, "bench": "curvilinear",
                     "direction": "tangential"}  # fmt: skip
            out += [
                {**point, "quantity": "magnitude", "sensitivity": 418.5 + shift,
                 "expanded_uncertainty": "1.5%", "unit": ""},
                {**point, "quantity": "phase", "sensitivity": PHASES[f][spelling],
                 "expanded_uncertainty": 0.5, "unit": "deg"},
                {**point, "quantity": "angular_rate", "sensitivity": 3280.0,
                 "expanded_uncertainty": 16.4, "unit": "LSB/(rad/s)"},
            ]  # fmt: skip
    return out


def as_csv(rows: list[dict]) -> bytes:
    names = list(rows[0])
    lines = [",".join(names), *(",".join(str(r[n]) for n in names) for r in rows)]
    return ("\n".join(lines) + "\n").encode()


def one_version(participant, status: str = "submitted") -> Submission:
    (submission,) = Submission.objects.filter(participant=participant)
    assert submission.status == status
    values = dict(
        Result.objects.filter(submission=submission, measurement_point__quantity="phase",
                              measurement_point__axis="X")
        .values_list("measurement_point__frequency_hz", "value")
    )  # fmt: skip
    assert values == {10.0: -170.0, 20.0: 180.0, 40.0: 180.0, 80.0: 0.5}
    assert Result.objects.filter(submission=submission).count() == 36
    assert Result.objects.count() == 36  # one result set in the whole database
    return submission


def test_the_same_upload_posted_twice_at_once_stores_one_version(lab):
    participant, key = lab

    def upload(spelling: int):
        data = as_csv(records(spelling)[:: 1 if spelling == 0 else -1])  # rows in another order
        file = SimpleUploadedFile("r.csv", data, content_type="text/csv")
        return lambda: client(key).post(f"{SUBMIT}upload/", {"file": file}, format="multipart")

    answers = at_once(upload(0), upload(1))
    assert [a.status_code for a in answers] == [201, 201], answers
    assert answers[0].json() == answers[1].json()
    assert sorted(a.has_header("Idempotent-Replayed") for a in answers) == [False, True]
    one_version(participant)


def test_the_same_request_with_its_key_twice_at_once_and_again_later(lab):
    participant, key = lab
    body = {"results": records()}

    def post(rows: dict, idem: str):
        return lambda: client(key).post(SUBMIT, rows, format="json", HTTP_IDEMPOTENCY_KEY=idem)

    answers = at_once(post(body, "retry-7"), post({"results": records(1)}, "retry-7"))
    assert [a.status_code for a in answers] == [201, 201], [a.content for a in answers]
    assert sorted(a.has_header("Idempotent-Replayed") for a in answers) == [False, True]
    later = post(body, "retry-7")()  # the client's third try, after both answered
    assert later.status_code == 201 and later["Idempotent-Replayed"] == "true"
    assert later.json() == answers[0].json() == answers[1].json()
    assert SubmissionKey.objects.filter(participant=participant).count() == 1
    one_version(participant)


def test_one_key_with_other_results_at_once_is_one_version_and_one_422(lab):
    participant, key = lab

    def post(shift: float):
        body = {"results": records(shift=shift)}
        return lambda: client(key).post(SUBMIT, body, format="json", HTTP_IDEMPOTENCY_KEY="k-2")

    answers = at_once(post(0.0), post(0.25))
    assert sorted(a.status_code for a in answers) == [201, 422], [a.content for a in answers]
    refused = next(a for a in answers if a.status_code == 422).json()
    assert refused["errors"] == [
        {"row": None, "field": "Idempotency-Key", "message": "already used for another request"}
    ]
    (submission,) = Submission.objects.filter(participant=participant)
    stored = next(a for a in answers if a.status_code == 201).json()
    assert stored["version"] == submission.version == 1
    assert Result.objects.count() == 36
    assert SubmissionKey.objects.filter(participant=participant).count() == 1


def test_the_same_draft_saved_twice_at_once_is_one_draft(lab):
    participant, key = lab
    body = {"results": records()[:12], "submit": False}  # a partial draft
    answers = at_once(*(lambda: client(key).post(SUBMIT, body, format="json") for _ in range(2)))
    assert [a.status_code for a in answers] == [201, 201], [a.content for a in answers]
    assert answers[0].json()["version"] == answers[1].json()["version"] == 1
    (submission,) = Submission.objects.filter(participant=participant)
    assert submission.status == "draft"
    assert Result.objects.filter(submission=submission).count() == 12 == Result.objects.count()
