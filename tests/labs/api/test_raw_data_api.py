"""``/api/v1/comparisons/{code}/raw-data/``: upload, recomputation, dedup, limits, scope."""

from __future__ import annotations

import math

import pytest
from django.contrib.auth.models import User
from django.core.files.uploadedfile import SimpleUploadedFile
from rest_framework.test import APIClient

from labs.models import Participant, RawFile, RawRecomputation, RawRecord
from tests.factories import LaboratoryFactory, MembershipFactory, UserFactory
from tests.labs.raw_data_helpers import (
    TRUTH,
    csv_bytes,
    curvilinear,
    daq_key,
    int16_bytes,
    linear,
    raw_round,
    reporting,
    sidecar,
    staff,
    upload_fields,
)

pytestmark = pytest.mark.django_db

CODE = "RAW-01"
URL = f"/api/v1/comparisons/{CODE}/raw-data/"
REPORTED, REPORTED_U = 420.5, 8.4
LINEAR_POINT = {"device": "MEMS 1", "axis": "X", "frequency_hz": "10", "bench": "linear"}
CURV_POINT = {**LINEAR_POINT, "bench": "curvilinear", "direction": "tangential"}


class World:
    users: dict[str, User]
    part_a: Participant
    part_b: Participant
    key_a: str

    def client(self, persona: str) -> APIClient:
        client = APIClient()
        if persona == "key_a":
            client.credentials(HTTP_AUTHORIZATION=f"Api-Key {self.key_a}")
        elif persona != "anonymous":
            client.force_login(self.users[persona])
        return client


@pytest.fixture
def world():
    w = World()
    lab_a, lab_b = (
        LaboratoryFactory.create(name="Alpha Raw Lab"),
        LaboratoryFactory.create(name="Bravo"),
    )
    w.users = {
        "staff_a": staff(lab_a),
        "staff_b": MembershipFactory.create(laboratory=lab_b).user,
        "coord": UserFactory.create(username="coord-raw"),
    }
    grid = {"axes": ["X", "Y"], "frequencies_hz": [10], "benches": ["linear", "curvilinear"]}
    comparison, points = raw_round(CODE, "MEMS 1", grid)
    comparison.coordinators.add(w.users["coord"])
    w.part_a, w.part_b = (
        reporting(comparison, lab, code, points, (REPORTED, REPORTED_U))
        for lab, code in ((lab_a, "R17"), (lab_b, "R42"))
    )
    w.key_a = daq_key(lab_a)
    return w


def post_linear(client, record=None, point=LINEAR_POINT, capture=None, **extra):
    record = record or linear()
    data = {**upload_fields(record, name="run1.bin"), **point, **extra}
    if capture is None:
        return client.post(URL, data, format="multipart")
    with capture(execute=True):
        return client.post(URL, data, format="multipart")


def test_upload_recomputes_the_known_truth_and_en(world, django_capture_on_commit_callbacks):
    record = linear()
    response = post_linear(
        world.client("key_a"), record, capture=django_capture_on_commit_callbacks
    )
    assert response.status_code == 201, response.json()
    row = RawRecomputation.objects.get(record_id=response.json()["id"])
    assert row.status == "succeeded", row.error
    assert row.sensitivity == pytest.approx(TRUTH[0], rel=5e-4)
    assert row.fs_hz == pytest.approx(1663.7, abs=0.01)
    assert row.reported_value == REPORTED and row.reported_expanded_uncertainty == REPORTED_U
    # En by hand from the stored values
    assert row.sensitivity is not None and row.expanded_uncertainty is not None
    expected = (REPORTED - row.sensitivity) / math.sqrt(REPORTED_U**2 + row.expanded_uncertainty**2)
    assert row.en == pytest.approx(expected, rel=1e-12)
    assert row.software_version and row.parameters["data_sha256"] == row.record.data_file.sha256
    assert [a["axis"] for a in row.axes] == ["X", "Y", "Z"]
    assert {c["name"] for c in row.budget}  # the chosen axis' budget components
    detail = world.client("key_a").get(f"{URL}{row.record_id}/").json()
    assert detail["recomputation"]["sensitivity"] == row.sensitivity
    assert detail["participant"] == "R17" and detail["data_file"]["size"] == record.data.size * 2


def test_curvilinear_with_encoder_reference(world, django_capture_on_commit_callbacks):
    mems, encoder = curvilinear()
    data = {
        **upload_fields(mems, name="curv.bin"),
        "reference_file": SimpleUploadedFile("encoder.csv", csv_bytes(encoder)),
        "reference_fs_hz": "1000",
        **CURV_POINT,
    }
    with django_capture_on_commit_callbacks(execute=True):
        response = world.client("staff_a").post(URL, data, format="multipart")
    assert response.status_code == 201, response.json()
    row = RawRecomputation.objects.get(record_id=response.json()["id"])
    assert row.status == "succeeded", row.error
    assert row.sensitivity == pytest.approx(TRUTH[0], rel=5e-4)
    assert row.record.reference_metadata["fs_hz"] == 1000.0


def test_same_file_twice_is_stored_once(world):
    record = linear(duration=5.0)
    client = world.client("key_a")
    assert post_linear(client, record).status_code == 201
    assert post_linear(client, record).status_code == 201
    assert RawRecord.objects.count() == 2
    assert RawFile.objects.count() == 1
    stored = RawFile.objects.get()
    assert stored.file.read() == int16_bytes(record)


def test_oversize_is_413_and_nothing_is_stored(world, settings):
    settings.RAW_UPLOAD_MAX_BYTES = 10_000
    response = post_linear(world.client("key_a"), linear(duration=5.0))
    assert response.status_code == 413
    assert "limit" in response.json()["detail"]
    assert (RawFile.objects.count(), RawRecord.objects.count()) == (0, 0)


def test_oversize_by_content_length_is_refused_before_reading(world, settings):
    settings.RAW_UPLOAD_MAX_BYTES = 1_000
    response = world.client("key_a").post(
        URL, b"x" * 10, content_type="multipart/form-data; boundary=b", CONTENT_LENGTH="9999999"
    )
    assert response.status_code == 413
    assert RawRecord.objects.count() == 0


def test_bad_file_is_400_with_the_readers_message(world):
    record = linear(duration=5.0)
    data = {
        "file": SimpleUploadedFile("run1.bin", int16_bytes(record)[:-2]),  # one value short
        "sidecar": SimpleUploadedFile("run1.bin.json", sidecar(record)),
        **LINEAR_POINT,
    }
    response = world.client("key_a").post(URL, data, format="multipart")
    assert response.status_code == 400
    body = response.json()
    assert "run1.bin" in body["detail"] and "truncated file" in body["detail"]
    assert body["errors"][0]["field"] == "file"
    assert (RawFile.objects.count(), RawRecord.objects.count()) == (0, 0)


def test_unknown_point_and_contradicting_metadata_are_400(world):
    client = world.client("key_a")
    response = post_linear(client, linear(duration=5.0), point={**LINEAR_POINT, "device": "X9"})
    assert response.status_code == 400 and "no measurement point" in response.json()["detail"]
    response = post_linear(client, linear(duration=5.0, f=20.0))
    assert response.status_code == 400
    assert "frequency_hz" in response.json()["detail"]


def test_another_labs_record_is_404_and_coordinator_sees_it(world):
    record_id = post_linear(world.client("key_a"), linear(duration=5.0)).json()["id"]
    assert world.client("staff_b").get(f"{URL}{record_id}/").status_code == 404
    assert world.client("staff_b").get(URL).json()["results"] == []
    assert world.client("anonymous").get(URL).status_code in (401, 403)
    assert world.client("anonymous").post(URL, {}).status_code in (401, 403)
    coord = world.client("coord")
    assert coord.get(f"{URL}{record_id}/").json()["participant"] == "R17"
    assert [r["id"] for r in coord.get(URL).json()["results"]] == [record_id]
    assert "Alpha" not in coord.get(URL).content.decode()
    assert post_linear(coord, linear(duration=5.0)).status_code == 403


def test_task_delivered_twice_gives_one_result(world, django_capture_on_commit_callbacks):
    from labs.tasks import raw_recompute_task

    record_id = post_linear(
        world.client("key_a"), linear(duration=5.0), capture=django_capture_on_commit_callbacks
    ).json()["id"]
    first = RawRecomputation.objects.get(record_id=record_id)
    assert first.status == "succeeded"
    assert raw_recompute_task.delay(record_id).get() == "succeeded"
    again = RawRecomputation.objects.get(record_id=record_id)
    assert RawRecomputation.objects.count() == 1
    assert (again.finished_at, again.sensitivity) == (first.finished_at, first.sensitivity)
