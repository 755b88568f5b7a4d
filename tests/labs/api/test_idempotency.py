"""Retried submissions store one version: the Idempotency-Key header, identical content
sent again shortly after, and two identical requests at the same time."""

import datetime as dt
import threading

import pytest
from django.core.files.uploadedfile import SimpleUploadedFile
from django.db import connections
from django.utils import timezone

from labs.models import Submission, SubmissionKey
from labs.services import submission_from_records
from tests.labs.api import as_csv, build_world, rows

C = "/api/v1/comparisons/IMU-A-01"
SUBMIT = f"{C}/submissions/"
UPLOAD = f"{C}/submissions/upload/"


@pytest.fixture
def key_a(world):
    return world.client("key_a")


def post(client, body, key=None):
    headers = {"HTTP_IDEMPOTENCY_KEY": key} if key is not None else {}
    return client.post(SUBMIT, body, format="json", **headers)


def versions(world):
    return list(world.part_a.submissions.order_by("version").values_list("version", "status"))


@pytest.mark.django_db
def test_same_key_answers_the_first_version_with_the_same_body(world, key_a):
    body = {"results": rows(419.25)}
    first = post(key_a, body, key="a1b2c3-retry")
    again = post(key_a, body, key="a1b2c3-retry")
    assert (first.status_code, again.status_code) == (201, 201)
    assert again.json() == first.json()
    assert (first.json()["version"], first.json()["status"]) == (2, "submitted")
    assert "Idempotent-Replayed" not in first and again["Idempotent-Replayed"] == "true"
    assert versions(world) == [(1, "submitted"), (2, "submitted")]
    assert SubmissionKey.objects.filter(participant=world.part_a).count() == 1


@pytest.mark.django_db
def test_same_key_with_other_content_or_submit_flag_is_422_and_stores_nothing(world, key_a):
    assert post(key_a, {"results": rows(419.25)}, key="k-1").status_code == 201
    for body in ({"results": rows(419.26)}, {"results": rows(419.25), "submit": False}):
        refused = post(key_a, body, key="k-1")
        assert refused.status_code == 422
        answer = refused.json()
        assert "Idempotency-Key 'k-1' was already used" in answer["detail"]
        assert answer["errors"] == [
            {"row": None, "field": "Idempotency-Key", "message": "already used for another request"}
        ]
    assert versions(world) == [(1, "submitted"), (2, "submitted")]


@pytest.mark.django_db
def test_keys_belong_to_one_participant(world, key_a):
    body = {"results": rows(419.25)}
    assert post(key_a, body, key="shared-key").json()["version"] == 2
    other = key_a.post(
        "/api/v1/comparisons/IMU-AB-01/submissions/", body, format="json",
        HTTP_IDEMPOTENCY_KEY="shared-key",
    )  # fmt: skip
    assert other.status_code == 201 and "Idempotent-Replayed" not in other
    assert (other.json()["participant"], other.json()["version"]) == ("L71", 2)
    assert world.shared_a.submissions.count() == 2


@pytest.mark.django_db
def test_a_key_older_than_the_retention_is_a_new_request(settings, world, key_a):
    settings.IDEMPOTENCY_KEY_HOURS = 24
    assert post(key_a, {"results": rows(419.25)}, key="old-key").status_code == 201
    SubmissionKey.objects.update(created_at=timezone.now() - dt.timedelta(hours=25))
    Submission.objects.filter(participant=world.part_a, version=2).update(
        submitted_at=timezone.now() - dt.timedelta(hours=25)
    )
    again = post(key_a, {"results": rows(419.25)}, key="old-key")
    assert again.status_code == 201 and "Idempotent-Replayed" not in again
    assert again.json()["version"] == 3
    assert list(SubmissionKey.objects.values_list("submission__version", flat=True)) == [3]


@pytest.mark.django_db
def test_housekeeping_forgets_expired_keys(world, key_a):
    from labs.tasks import housekeeping

    for key in ("kept", "expired"):
        assert post(key_a, {"results": rows(419.0 + len(key))}, key=key).status_code == 201
    old = timezone.now() - dt.timedelta(hours=25)
    SubmissionKey.objects.filter(key="expired").update(created_at=old)
    assert housekeeping()["submission_keys"] == 1
    assert list(SubmissionKey.objects.values_list("key", flat=True)) == ["kept"]
    assert housekeeping()["submission_keys"] == 0


@pytest.mark.django_db
def test_a_new_key_with_the_same_results_is_a_new_version(world, key_a):
    body = {"results": rows(419.25)}
    assert post(key_a, body, key="one").json()["version"] == 2
    assert post(key_a, body, key="two").json()["version"] == 3


@pytest.mark.django_db
@pytest.mark.parametrize("key", ["", " ", "x" * 256, "naïve", "two words"])
def test_a_malformed_key_is_400_naming_the_header(world, key_a, key):
    response = post(key_a, {"results": rows(419.25)}, key=key)
    assert response.status_code == 400
    assert response.json()["errors"][0]["field"] == "Idempotency-Key"
    assert versions(world) == [(1, "submitted")]


@pytest.mark.django_db
def test_identical_results_without_a_key_answer_the_version_within_the_window(
    settings, world, key_a
):
    settings.SUBMISSION_DEDUP_SECONDS = 600
    body = {"results": rows(419.25)}
    first = post(key_a, body)
    again = post(key_a, body)
    assert again.status_code == 201 and again.json() == first.json()
    assert again["Idempotent-Replayed"] == "true"
    assert versions(world) == [(1, "submitted"), (2, "submitted")]
    other = post(key_a, {"results": rows(419.5)})  # other results: a correction
    assert other.json()["version"] == 3 and "Idempotent-Replayed" not in other
    back = post(key_a, body)  # the results of version 2 again: the latest is 3
    assert back.json()["version"] == 4
    Submission.objects.filter(participant=world.part_a, version=4).update(
        submitted_at=timezone.now() - dt.timedelta(seconds=601)
    )
    assert post(key_a, body).json()["version"] == 5  # outside the window: a new version


@pytest.mark.django_db
def test_identical_upload_answers_the_version_and_a_rejected_one_is_resubmitted(world, key_a):
    data = as_csv(rows(419.25))

    def upload(key=None):
        file = SimpleUploadedFile("results.csv", data, content_type="text/csv")
        headers = {"HTTP_IDEMPOTENCY_KEY": key} if key else {}
        return key_a.post(UPLOAD, {"file": file}, format="multipart", **headers)

    first, again = upload("file-1"), upload("file-1")
    assert (first.status_code, again.status_code) == (201, 201)
    assert again.json() == first.json() and again["Idempotent-Replayed"] == "true"
    assert upload().json()["version"] == 2  # without a key: the same content, same source
    Submission.objects.filter(participant=world.part_a, version=2).update(status="rejected")
    assert upload().json()["version"] == 3  # a rejected version is not answered again


@pytest.mark.django_db
def test_the_web_path_stores_identical_results_once(world):
    """The grid and the web upload share the service: a double-clicked Submit."""
    staff = world.users["staff_a"]
    one, two = (
        submission_from_records(
            participant=world.part_a, records=rows(419.25), source="web", user=staff, submit=True
        )
        for _ in range(2)
    )
    assert one.pk == two.pk and two.replayed and not one.replayed  # type: ignore[attr-defined]  # set on the answer by submission_from_records
    drafts = [
        submission_from_records(
            participant=world.part_a, records=rows(419.5, axes=("X",)), source="web",
            user=staff, submit=False,
        ).pk
        for _ in range(2)
    ]  # fmt: skip
    assert drafts[0] == drafts[1]
    assert versions(world) == [(1, "submitted"), (2, "submitted"), (3, "draft")]


@pytest.mark.django_db(transaction=True)
@pytest.mark.parametrize("key", ["race-key-1", None])
def test_two_identical_requests_at_once_store_one_version(needs_postgres, key):
    world = build_world()
    body = {"results": rows(419.25)}
    start = threading.Barrier(2)
    answers = []

    def send():
        try:
            client = world.client("key_a")
            start.wait(10)
            answers.append(post(client, body, key=key))
        finally:
            connections.close_all()

    threads = [threading.Thread(target=send) for _ in range(2)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(60)
    assert [a.status_code for a in answers] == [201, 201]
    assert answers[0].json() == answers[1].json()
    assert sorted(a.has_header("Idempotent-Replayed") for a in answers) == [False, True]
    assert versions(world) == [(1, "submitted"), (2, "submitted")]
    assert world.part_a.submissions.get(version=2).results.count() == 4
