"""Submitting through the API: JSON and file give the same rows; 400/409/413 answers."""

import datetime as dt
import io

import pytest
from django.core.files.uploadedfile import SimpleUploadedFile
from django.utils import timezone

from labs.importers import parse_table
from labs.models import Result, Submission
from labs.selectors import table_context
from tests.labs.api import as_csv, rows

pytestmark = pytest.mark.django_db

C = "/api/v1/comparisons/IMU-A-01"
SUBMIT = f"{C}/submissions/"
UPLOAD = f"{C}/submissions/upload/"


@pytest.fixture
def key_a(world):
    return world.client("key_a")


def upload(client, data: bytes, name="results.csv", **fields):
    file = SimpleUploadedFile(name, data, content_type="text/csv")
    return client.post(UPLOAD, {"file": file, **fields}, format="multipart")


def stored(submission: Submission) -> list[tuple]:
    return sorted(
        Result.objects.filter(submission=submission).values_list(
            "measurement_point_id", "value", "unit", "expanded_uncertainty",
            "coverage_factor", "standard_uncertainty", "dof", "note",
        )
    )  # fmt: skip


def test_json_and_csv_store_identical_rows(world, key_a):
    data = [
        {**r, "sensitivity": 419.0 + i * 0.123456789, "coverage_factor": 2.5, "dof": 50 + i,
         "note": f"run {i}"}
        for i, r in enumerate(rows(u="1.5%"))
    ]  # fmt: skip
    via_json = key_a.post(SUBMIT, {"results": data}, format="json")
    via_csv = upload(key_a, as_csv(data))
    assert (via_json.status_code, via_csv.status_code) == (201, 201)
    assert (via_json.json()["source"], via_csv.json()["source"]) == ("api", "file")
    first = Submission.objects.get(participant=world.part_a, version=via_json.json()["version"])
    second = Submission.objects.get(participant=world.part_a, version=via_csv.json()["version"])
    assert stored(first) == stored(second)
    assert len(stored(first)) == 4
    assert stored(first)[0][3] == pytest.approx(419.0 * 0.015)


def test_submit_answers_with_the_new_version(world, key_a):
    response = key_a.post(SUBMIT, {"results": rows()}, format="json")
    assert response.status_code == 201
    body = response.json()
    assert (body["participant"], body["version"], body["status"]) == ("L17", 2, "submitted")
    assert (body["source"], body["n_results"]) == ("api", 4)
    assert Submission.objects.get(participant=world.part_a, version=2).submitted_by is None


def test_session_submission_records_the_person(world):
    response = world.client("staff_a").post(SUBMIT, {"results": rows()}, format="json")
    assert response.status_code == 201
    submission = Submission.objects.get(participant=world.part_a, version=2)
    assert submission.submitted_by == world.users["staff_a"]


def test_draft_then_replace_then_submit(world, key_a):
    first = key_a.post(SUBMIT, {"results": rows(axes=("X",)), "submit": False}, format="json")
    assert (first.status_code, first.json()["status"], first.json()["n_results"]) == (
        201, "draft", 2,
    )  # fmt: skip
    again = upload(key_a, as_csv(rows(axes=("Y",))), submit="false")
    assert (again.json()["version"], again.json()["n_results"]) == (first.json()["version"], 2)
    final = key_a.post(SUBMIT, {"results": rows()}, format="json")
    assert (final.json()["version"], final.json()["status"]) == (2, "submitted")


def test_partial_submit_is_refused_with_the_missing_points(key_a):
    response = key_a.post(SUBMIT, {"results": rows(axes=("X",))}, format="json")
    assert response.status_code == 400
    assert "missing result for MEMS 1, Y, 5 Hz" in response.json()["errors"][0]["message"]


def test_bad_rows_give_row_and_field_and_store_nothing(world, key_a):
    data = rows()
    data[1]["expanded_uncertainty"] = -3
    data[3]["axis"] = "W"
    before = Result.objects.count()
    response = key_a.post(SUBMIT, {"results": data}, format="json")
    assert response.status_code == 400
    body = response.json()
    assert set(body) == {"detail", "errors"} and "2 problems" in body["detail"]
    assert [(e["row"], e["field"]) for e in body["errors"]] == [
        (2, "expanded_uncertainty"), (4, "axis"),
    ]  # fmt: skip
    assert all(e["message"] for e in body["errors"])
    assert Result.objects.count() == before


def test_bad_file_rows_are_numbered_as_in_the_spreadsheet(key_a):
    data = rows()
    data[2]["sensitivity"] = "abc"
    response = upload(key_a, as_csv(data))
    assert response.status_code == 400
    assert [(e["row"], e["field"]) for e in response.json()["errors"]] == [(4, "sensitivity")]


@pytest.mark.parametrize(
    ("body", "field"),
    [({"results": {"device": "MEMS 1"}}, "results"), ({}, "results"), ([], None),
     ({"results": rows(), "submit": "perhaps"}, "submit")],
)  # fmt: skip
def test_malformed_body_is_400_with_the_field(key_a, body, field):
    response = key_a.post(SUBMIT, body, format="json")
    assert response.status_code == 400
    assert response.json()["errors"][0]["field"] == field


def test_unparseable_json_is_400(key_a):
    response = key_a.post(SUBMIT, b"{not json", content_type="application/json")
    assert response.status_code == 400
    assert set(response.json()) == {"detail", "errors"}


def test_upload_without_file_is_400(key_a):
    response = key_a.post(UPLOAD, {"submit": "true"}, format="multipart")
    assert (response.status_code, response.json()["errors"][0]["field"]) == (400, "file")


def test_after_the_deadline_is_409_with_the_deadline(world, key_a):
    world.cmp.submission_deadline = timezone.now() - dt.timedelta(hours=1)
    world.cmp.save()
    for response in (
        key_a.post(SUBMIT, {"results": rows()}, format="json"),
        upload(key_a, as_csv(rows())),
    ):
        assert response.status_code == 409
        assert f"{world.cmp.submission_deadline:%Y-%m-%d %H:%M}" in response.json()["detail"]
    assert world.part_a.submissions.count() == 1


@pytest.mark.parametrize("status", ["draft", "closed", "analysed", "published"])
def test_not_open_is_409(world, key_a, status):
    world.cmp.status = status
    world.cmp.save()
    response = key_a.post(SUBMIT, {"results": rows()}, format="json")
    assert response.status_code == 409
    assert status in response.json()["detail"]


def test_too_large_file_is_413(settings, key_a, monkeypatch):
    settings.MAX_UPLOAD_BYTES = 100
    data = as_csv(rows())
    assert len(data) > 100
    response = upload(key_a, data)
    assert response.status_code == 413
    assert "limit is 100 bytes" in response.json()["detail"]


def test_too_large_body_is_refused_before_it_is_read(settings, key_a, monkeypatch):
    settings.MAX_UPLOAD_BYTES = 200

    def never(*args, **kwargs):
        raise AssertionError("the body was parsed")

    monkeypatch.setattr("rest_framework.parsers.MultiPartParser.parse", never)
    response = upload(key_a, b"x" * (70 * 1024))
    assert response.status_code == 413


def test_too_large_json_is_413(settings, key_a, monkeypatch):
    settings.DATA_UPLOAD_MAX_MEMORY_SIZE = 1000
    monkeypatch.setattr("rest_framework.parsers.JSONParser.parse", lambda *a, **k: 1 / 0)
    response = key_a.post(SUBMIT, {"results": rows(note="n" * 400)}, format="json")
    assert response.status_code == 413


def test_template_is_the_results_table_and_reads_back(world, key_a):
    response = key_a.get(f"{C}/template.csv")
    assert response["Content-Type"] == "text/csv; charset=utf-8"
    assert "IMU-A-01-results-template.csv" in response["Content-Disposition"]
    text = response.content.decode("utf-8-sig")
    assert text.splitlines()[0].startswith("device,axis,frequency_hz,bench,direction")
    assert "lab" not in text.splitlines()[0].split(",")
    filled = text.replace(",,,D/(m/s^2),,", ",,420.1,D/(m/s^2),8.4,")
    parsed = parse_table(filled.encode(), context=table_context(world.cmp), lab_column="forbidden")
    assert len(parsed) == 4
    assert upload(key_a, filled.encode()).status_code == 201


def test_template_xlsx(key_a):
    response = key_a.get(f"{C}/template.csv?format=xlsx")
    assert response.status_code == 200
    assert response["Content-Type"].startswith("application/vnd.openxmlformats")
    from openpyxl import load_workbook

    sheet = load_workbook(io.BytesIO(response.content), read_only=True)["results"]
    table = list(sheet.iter_rows(values_only=True))
    assert table[0][:3] == ("device", "axis", "frequency_hz") and len(table) == 5
    assert table[1][:5] == ("MEMS 1", "X", 5.0, "linear", "vertical")


def test_template_errors_stay_json(world):
    response = world.client("staff_b").get(f"{C}/template.csv?format=xlsx")
    assert response.status_code == 404
    assert response["Content-Type"] == "application/json"


def test_version_detail_has_the_results(key_a):
    body = key_a.get(f"{C}/submissions/1/").json()
    assert body["version"] == 1 and len(body["results"]) == 4
    first = body["results"][0]
    assert set(first) >= {"device", "axis", "frequency_hz", "sensitivity", "expanded_uncertainty"}
    assert first["standard_uncertainty"] == pytest.approx(first["expanded_uncertainty"] / 2)


def test_submission_list_filters(world, key_a):
    key_a.post(SUBMIT, {"results": rows(axes=("X",)), "submit": False}, format="json")
    listed = key_a.get(f"{C}/submissions/?status=draft").json()["results"]
    assert [(s["version"], s["status"]) for s in listed] == [(2, "draft")]
    assert key_a.get(f"{C}/submissions/").json()["count"] == 2
