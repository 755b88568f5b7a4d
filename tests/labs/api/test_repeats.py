"""Repeatability data (``repeat_sd``, ``n_repeats``) through the API: stored, answered, refused."""

import pytest
from django.core.files.uploadedfile import SimpleUploadedFile

from labs.models import Result, Submission
from tests.labs.api import as_csv, rows

pytestmark = pytest.mark.django_db

C = "/api/v1/comparisons/IMU-A-01"
SUBMIT = f"{C}/submissions/"


@pytest.fixture
def key_a(world):
    return world.client("key_a")


def test_json_round_trip_stores_and_answers_the_repeats(world, key_a):
    data = [
        {**r, "sensitivity": 420.0 + i, "repeat_sd": 0.25 + i / 100, "n_repeats": 3 + i}
        for i, r in enumerate(rows())
    ]
    response = key_a.post(SUBMIT, {"results": data}, format="json")
    assert response.status_code == 201, response.json()
    version = response.json()["version"]
    submission = Submission.objects.get(participant=world.part_a, version=version)
    stored = sorted(
        Result.objects.filter(submission=submission).values_list("value", "repeat_sd", "n_repeats")
    )
    assert stored == [(420.0, 0.25, 3), (421.0, 0.26, 4), (422.0, 0.27, 5), (423.0, 0.28, 6)]
    body = key_a.get(f"{C}/submissions/{version}/").json()
    got = sorted((r["sensitivity"], r["repeat_sd"], r["n_repeats"]) for r in body["results"])
    assert got == stored


def test_results_without_repeats_answer_null(key_a):
    body = key_a.get(f"{C}/submissions/1/").json()
    assert {(r["repeat_sd"], r["n_repeats"]) for r in body["results"]} == {(None, None)}


def test_file_upload_takes_the_columns(world, key_a):
    data = [{**r, "repeat_sd": "0.5", "n_repeats": "4"} for r in rows()]
    file = SimpleUploadedFile("r.csv", as_csv(data), content_type="text/csv")
    response = key_a.post(f"{SUBMIT}upload/", {"file": file}, format="multipart")
    assert response.status_code == 201, response.json()
    submission = Submission.objects.get(
        participant=world.part_a, version=response.json()["version"]
    )
    assert set(submission.results.values_list("repeat_sd", "n_repeats")) == {(0.5, 4)}


def test_a_repeat_sd_without_its_count_is_a_400_naming_row_and_field(key_a):
    data = rows()
    data[2] = {**data[2], "repeat_sd": 0.3}
    data[3] = {**data[3], "repeat_sd": 0.3, "n_repeats": 1}
    response = key_a.post(SUBMIT, {"results": data}, format="json")
    assert response.status_code == 400
    assert response.json()["errors"] == [
        {"row": 3, "field": "n_repeats", "message": "is required when repeat_sd is given: the "
         "within-laboratory standard deviation and its number of repeats go together"},
        {"row": 4, "field": "n_repeats", "message": "must be a whole number from 2 to "
         "1,000,000,000 (the repeats behind repeat_sd), got 1"},
    ]  # fmt: skip


def test_template_offers_the_columns(key_a):
    header = key_a.get(f"{C}/template.csv").content.decode("utf-8-sig").splitlines()[0]
    assert header.endswith(",coverage_factor,dof,repeat_sd,n_repeats,note")


def test_schema_documents_the_columns(key_a):
    schema = key_a.get("/api/schema/?format=json").json()["components"]["schemas"]
    row_in, row_out = schema["ResultRowInRequest"]["properties"], schema["Result"]["properties"]
    assert {"repeat_sd", "n_repeats"} <= row_in.keys() & row_out.keys()
    assert row_in["n_repeats"]["minimum"] == 2
