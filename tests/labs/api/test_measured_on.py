"""The optional ``measured_on`` of a result through the API and the coordinator's commands
(docs/interfaces.md §1, §3, §4): stored, answered, exported; a bad date a 400 naming row
and field (the command: its problems listed, exit 2), a date before the comparison opened
or in the future refused, and nothing stored then."""

from __future__ import annotations

import datetime as dt
import io
from types import SimpleNamespace

import pytest
from django.core.files.uploadedfile import SimpleUploadedFile
from django.core.management import CommandError, call_command

from labs import selectors
from labs.kits import SlotPlan, circulation_set, kit_create
from labs.models import Result, Submission
from proficiency.models import Comparison
from tests.labs.api import as_csv, rows

pytestmark = pytest.mark.django_db

C = "/api/v1/comparisons/IMU-A-01"
SUBMIT = f"{C}/submissions/"
OPENED = dt.date(2026, 1, 10)


def _clock(monkeypatch, at: dt.datetime) -> None:
    """The service's clock for the date bounds only (labs.selectors.measurement_dates)."""
    monkeypatch.setattr(selectors, "timezone", SimpleNamespace(now=lambda: at))


# --- the API -----------------------------------------------------------------------------------


@pytest.fixture
def key_a(world):
    Comparison.objects.filter(pk=world.cmp.pk).update(
        created_at=dt.datetime.combine(OPENED, dt.time(9), tzinfo=dt.UTC)
    )
    return world.client("key_a")


def test_json_rows_store_and_answer_their_dates(world, key_a):
    data = rows()
    data[0]["measured_on"] = "2026-03-14"
    data[1]["measured_on"] = None
    data[2]["measured_on"] = ""
    response = key_a.post(SUBMIT, {"results": data}, format="json")
    assert response.status_code == 201, response.json()
    version = response.json()["version"]
    stored = Result.objects.filter(submission__participant=world.part_a,
                                   submission__version=version)  # fmt: skip
    assert sorted(stored.values_list("measured_on", flat=True), key=str) == [
        dt.date(2026, 3, 14), None, None, None
    ]  # fmt: skip
    answered = key_a.get(f"{C}/submissions/{version}/").json()["results"]
    assert sorted((r["axis"], r["frequency_hz"], r["measured_on"]) for r in answered) == [
        ("X", 5.0, "2026-03-14"), ("X", 10.0, None), ("Y", 5.0, None), ("Y", 10.0, None)
    ]  # fmt: skip


def test_bad_dates_are_a_400_by_row_and_field_and_nothing_is_stored(world, key_a, monkeypatch):
    _clock(monkeypatch, dt.datetime(2026, 6, 1, 10, 30, tzinfo=dt.UTC))  # UTC+14: June 2
    data = rows()
    for row, text in zip(data, ("14/03/2026", "2026-01-09", "2026-06-03", "2026-06-02"),
                         strict=True):  # fmt: skip
        row["measured_on"] = text
    before = (Submission.objects.count(), Result.objects.count())
    response = key_a.post(SUBMIT, {"results": data}, format="json")
    assert response.status_code == 400
    assert response.json()["errors"] == [
        {"row": 1, "field": "measured_on",
         "message": "must be a date YYYY-MM-DD, got '14/03/2026'"},
        {"row": 2, "field": "measured_on",
         "message": "2026-01-09 is before the comparison opened on 2026-01-10"},
        {"row": 3, "field": "measured_on",
         "message": "2026-06-03 is in the future: a measurement date is at the latest "
                    "2026-06-02 (today anywhere on Earth)"},
    ]  # fmt: skip
    assert (Submission.objects.count(), Result.objects.count()) == before


def test_a_kit_plan_starting_earlier_opens_the_dates_earlier(world, key_a):
    device = world.cmp.devices.get()
    kit = kit_create(comparison_id=world.cmp.pk, name="Kit A", serials={device: "S1"})
    circulation_set(kit=kit, plan=[SlotPlan(world.part_a, dt.date(2025, 12, 1),
                                            dt.date(2025, 12, 20))])  # fmt: skip
    data = rows()
    data[0]["measured_on"] = "2025-12-05"
    assert key_a.post(SUBMIT, {"results": data}, format="json").status_code == 201
    data[0]["measured_on"] = "2025-11-30"
    response = key_a.post(SUBMIT, {"results": data}, format="json")
    assert response.status_code == 400
    assert response.json()["errors"][0]["message"] == (
        "2025-11-30 is before the comparison opened on 2025-12-01"
    )
    template = key_a.get(f"{C}/template.csv").content.decode("utf-8-sig").splitlines()[0]
    assert template.endswith(",n_repeats,measured_on,note")  # a kit round asks the date


def test_files_carry_the_column_csv_and_an_xlsx_date_cell(world, key_a):
    from openpyxl import Workbook

    data = [{**r, "measured_on": "2026-03-14"} for r in rows()]
    file = SimpleUploadedFile("r.csv", as_csv(data), content_type="text/csv")
    response = key_a.post(f"{SUBMIT}upload/", {"file": file, "submit": "false"},
                          format="multipart")  # fmt: skip
    assert response.status_code == 201, response.json()
    book = Workbook()
    sheet = book.active
    sheet.append([*rows()[0], "measured_on"])
    for r in rows():
        sheet.append([*r.values(), dt.datetime(2026, 4, 1)])  # a date cell of the workbook
    out = io.BytesIO()
    book.save(out)
    file = SimpleUploadedFile("r.xlsx", out.getvalue())
    response = key_a.post(f"{SUBMIT}upload/", {"file": file}, format="multipart")
    assert response.status_code == 201, response.json()
    version = response.json()["version"]
    stored = Result.objects.filter(submission__participant=world.part_a,
                                   submission__version=version)  # fmt: skip
    assert set(stored.values_list("measured_on", flat=True)) == {dt.date(2026, 4, 1)}


def test_a_bad_date_in_an_uploaded_file_names_its_spreadsheet_row(world, key_a):
    data = [{**r, "measured_on": "2026-03-14"} for r in rows()]
    data[2]["measured_on"] = "2026-3-14"
    before = Result.objects.count()
    file = SimpleUploadedFile("r.csv", as_csv(data), content_type="text/csv")
    response = key_a.post(f"{SUBMIT}upload/", {"file": file}, format="multipart")
    assert response.status_code == 400
    assert response.json()["errors"] == [
        {"row": 4, "field": "measured_on", "message": "must be a date YYYY-MM-DD, got '2026-3-14'"}
    ]
    assert Result.objects.count() == before


def test_schema_documents_the_key(key_a):
    schema = key_a.get("/api/schema/?format=json").json()["components"]["schemas"]
    row_in, row_out = schema["ResultRowInRequest"]["properties"], schema["Result"]["properties"]
    assert row_in["measured_on"]["format"] == row_out["measured_on"]["format"] == "date"


# --- the coordinator's commands ----------------------------------------------------------------


def _table(world, dates: list[str]) -> bytes:
    return as_csv([{"lab": "L17", **r, "measured_on": d} for r, d in zip(rows(), dates,
                                                                         strict=True)])  # fmt: skip


def test_import_results_stores_the_dates_and_export_results_writes_them(world, key_a, tmp_path):
    path = tmp_path / "in.csv"
    path.write_bytes(_table(world, ["2026-03-14", "", "2026-03-15", ""]))
    call_command("import_results", "IMU-A-01", str(path), stdout=io.StringIO())
    latest = Submission.objects.filter(participant=world.part_a).order_by("-version").first()
    assert latest is not None
    assert sorted(map(str, latest.results.values_list("measured_on", flat=True))) == [
        "2026-03-14", "2026-03-15", "None", "None"
    ]  # fmt: skip
    latest.status = Submission.Status.ACCEPTED
    latest.save(update_fields=["status"])
    out = io.StringIO()
    call_command("export_results", "IMU-A-01", stdout=out)
    lines = out.getvalue().splitlines()
    assert lines[0].endswith(",dof,measured_on,note")
    assert sorted(line.split(",")[-2] for line in lines[1:]) == ["", "", "2026-03-14",
                                                                 "2026-03-15"]  # fmt: skip


def test_import_results_refuses_a_bad_date_and_stores_nothing(world, key_a, tmp_path):
    path = tmp_path / "in.csv"
    path.write_bytes(_table(world, ["2026-03-14", "2026-13-01", "", "2026-01-09"]))
    before = (Submission.objects.count(), Result.objects.count())
    err = io.StringIO()
    with pytest.raises(CommandError):
        call_command("import_results", "IMU-A-01", str(path), stdout=io.StringIO(), stderr=err)
    assert err.getvalue().splitlines() == [
        "row 3, column measured_on: must be a date YYYY-MM-DD, got '2026-13-01' (no such day)",
        "row 5, column measured_on: 2026-01-09 is before the comparison opened on 2026-01-10",
    ]
    assert (Submission.objects.count(), Result.objects.count()) == before
