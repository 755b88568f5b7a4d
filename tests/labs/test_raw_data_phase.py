"""Raw records with a phase and a gyroscope (docs/domain.md §12.1): uploaded by the page and
the API, recomputed (eager), stored per axis beside today's sensitivity and shown on the
record's page; hostile sidecar values refused by key with nothing stored."""

from __future__ import annotations

import json
import re

import numpy as np
import pytest
from django.core.files.uploadedfile import SimpleUploadedFile

from analysis.core.phase import difference
from analysis.core.signals.synthetic import imu_records, linear_phase_records
from labs.models import RawFile, RawRecomputation, RawRecord
from proficiency.models import MeasurementPoint
from tests.factories import LaboratoryFactory
from tests.labs.raw_data_helpers import (
    api_post,
    axes,
    daq_key,
    key_client,
    raw_round,
    reporting,
    sidecar,
    staff,
    upload_fields,
)

pytestmark = pytest.mark.django_db
CODE = "RAW-PHASE"
URL = f"/api/v1/comparisons/{CODE}/raw-data/"
NOTE = "phase not determinable: no common time base"
LINEAR_80 = {"device": "IMU 1", "axis": "X", "frequency_hz": "80", "bench": "linear"}
TABLE_10 = {"device": "IMU 1", "axis": "X", "frequency_hz": "10", "bench": "curvilinear",
            "direction": "tangential"}  # fmt: skip


@pytest.fixture
def lab():
    laboratory = LaboratoryFactory.create(name="Phase Lab")
    user = staff(laboratory)
    comparison, points = raw_round(
        CODE,
        "IMU 1",
        {"axes": ["X"], "frequencies_hz": [10, 80], "benches": ["linear", "curvilinear"]},
    )
    reporting(comparison, laboratory, "P07", points, (420.0, 8.0))
    return {"user": user, "key": daq_key(laboratory)}


def test_the_page_upload_stores_and_shows_the_phase(
    client, lab, django_capture_on_commit_callbacks
):
    dut, ref = linear_phase_records(phase_deg=-12.5, duration=10.0, seed=5)
    point = MeasurementPoint.objects.get(comparison__code=CODE, bench="linear", frequency_hz=80)
    client.force_login(lab["user"])
    with django_capture_on_commit_callbacks(execute=True):
        response = client.post(f"/lab/comparisons/{CODE}/raw-data/", {"point": point.pk,
                               **upload_fields(dut, ref)})  # fmt: skip
    assert response.status_code == 302
    row = RawRecomputation.objects.get()
    assert row.status == "succeeded", row.error
    assert row.sensitivity == pytest.approx(420.0, rel=5e-4)  # today's figure, unchanged
    x = axes(row)["X"]
    assert abs(float(difference(x["phase_deg"], -12.5))) < 0.1 and x["phase_note"] == ""
    assert row.record.metadata["trigger_offset_s"] == 0.0123
    page = client.get(response["Location"]).content.decode()
    shown = re.search(r'data-testid="phase-X">([^<]+)<', page)
    assert shown, page
    # to U's decimals (k = 2, two significant digits of U: docs/domain.md §3.1)
    big_u = 2 * x["u_phase_deg"]
    decimals = 1 - int(np.floor(np.log10(big_u)))
    assert shown.group(1) == f"{x['phase_deg']:.{decimals}f}"


def test_start_times_as_form_fields_are_a_common_time_base(
    client, lab, django_capture_on_commit_callbacks
):
    dut, ref = linear_phase_records(phase_deg=33.0, duration=10.0, time_base=None)
    point = MeasurementPoint.objects.get(comparison__code=CODE, bench="linear", frequency_hz=80)
    client.force_login(lab["user"])
    fields = {"start_time_s": "1700000000.0123", "reference_start_time_s": "1700000000"}
    with django_capture_on_commit_callbacks(execute=True):
        client.post(f"/lab/comparisons/{CODE}/raw-data/", {"point": point.pk,
                    **upload_fields(dut, ref), **fields})  # fmt: skip
    row = RawRecomputation.objects.get()
    assert row.record.reference_metadata["start_time_s"] == 1.7e9
    assert abs(float(difference(axes(row)["X"]["phase_deg"], 33.0))) < 0.1


def test_without_a_time_base_the_page_says_so_in_words(
    client, lab, django_capture_on_commit_callbacks
):
    dut, ref = linear_phase_records(duration=10.0, time_base=None)
    client.force_login(lab["user"])
    point = MeasurementPoint.objects.get(comparison__code=CODE, bench="linear", frequency_hz=80)
    with django_capture_on_commit_callbacks(execute=True):
        response = client.post(f"/lab/comparisons/{CODE}/raw-data/", {"point": point.pk,
                               **upload_fields(dut, ref)})  # fmt: skip
    row = RawRecomputation.objects.get()
    assert (axes(row)["X"]["phase_deg"], axes(row)["X"]["phase_note"]) == (None, NOTE)
    assert row.sensitivity == pytest.approx(420.0, rel=5e-4)
    page = client.get(response["Location"]).content.decode()
    assert re.search(r'data-testid="phase-X">Phase not determinable: no common time base<', page)


def test_the_api_upload_of_an_imu_stores_the_gyroscope(lab, django_capture_on_commit_callbacks):
    mems, enc = imu_records(gyro_dps=57.14, gyro_phase_deg=-3.2, accel_phase_deg=-4.0)
    response = api_post(URL, lab["key"], {**upload_fields(mems, enc), **TABLE_10},
                        django_capture_on_commit_callbacks)  # fmt: skip
    assert response.status_code == 201, response.json()
    row = RawRecomputation.objects.get()
    assert row.status == "succeeded", row.error
    assert row.sensitivity == pytest.approx(420.0, rel=5e-4)  # the point's accelerometer axis
    gz, x = axes(row)["GZ"], axes(row)["X"]
    assert gz["sensor"] == "gyroscope" and abs(gz["sensitivity"] / 57.14 - 1) < 5e-4
    assert abs(gz["phase_deg"] + 3.2) < 0.1 and abs(x["phase_deg"] + 4.0) < 0.1
    body = key_client(lab["key"]).get(f"{URL}{row.record_id}/").json()
    api_gz = {a["axis"]: a for a in body["recomputation"]["axes"]}["GZ"]
    assert api_gz["sensitivity_per_rad_s"] == pytest.approx(gz["sensitivity"] * 180 / np.pi)


def test_the_page_shows_the_gyroscope_rows(client, lab, django_capture_on_commit_callbacks):
    mems, enc = imu_records(offset_s=None)
    point = MeasurementPoint.objects.get(
        comparison__code=CODE, bench="curvilinear", frequency_hz=10, direction="tangential"
    )
    client.force_login(lab["user"])
    with django_capture_on_commit_callbacks(execute=True):
        response = client.post(f"/lab/comparisons/{CODE}/raw-data/", {"point": point.pk,
                               **upload_fields(mems, enc)})  # fmt: skip
    row = RawRecomputation.objects.get()
    gz = axes(row)["GZ"]
    page = client.get(response["Location"]).content.decode()
    shown = re.search(r'data-testid="rate-GZ">([0-9.]+) digits/\(°/s\)<', page)
    assert shown and float(shown.group(1)) == pytest.approx(gz["sensitivity"], rel=1e-4), page
    assert 'data-testid="rate-phase-GZ">Phase not determinable: no common time base<' in page
    assert "Points tangential: the table turns about the axial direction" in page


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        ('"trigger_offset_s": NaN', "trigger_offset_s must be finite"),
        ('"trigger_offset_s": 1e308', "trigger_offset_s must be within"),
        ('"u_trigger_offset_s": -1e-6', "u_trigger_offset_s must be >= 0"),
        ('"start_time_s": "12\\u0000"', "start_time_s holds the control character U+0000"),
        ('"comment": "a\\u0000b"', "comment holds the control character U+0000"),
        ('"gyro_unit": "rad/s"', "gyro_unit must be one of digits, deg/s"),
        # each of these was a 500: PostgreSQL's jsonb refuses a lone surrogate, json.loads
        # recursed past the stack or refused a long integer, float() overflowed
        ('"comment": "a\\ud800"', "comment holds the lone surrogate U+D800"),
        ('"\\udfff": 1', "\\udfff holds the lone surrogate U+DFFF"),
        ('"zones": ' + "[" * 5000 + "]" * 5000, "dut.bin.json: not valid JSON: nested too deeply"),
        ('"big": 1' + "0" * 5000, "dut.bin.json: not valid JSON: Exceeds the limit"),
        ('"trigger_offset_s": 1' + "0" * 400, "trigger_offset_s must be a number, got 1000"),
        ('"extra": ' + '{"a": ' * 20 + "1" + "}" * 20, "is nested deeper than 16 levels"),
        # float() reads these as 1 and 10; a number is written in ASCII digits
        ('"trigger_offset_s": "\\u0661"', "trigger_offset_s must be a number, got '\u0661'"),
        ('"start_time_s": "1_0"', "start_time_s must be a number, got '1_0'"),
    ],
)  # fmt: skip
def test_hostile_sidecars_are_refused_by_key_with_nothing_stored(lab, extra, message):
    dut, ref = linear_phase_records(duration=2.0)
    data = upload_fields(dut, ref)
    doc = json.loads(sidecar(dut))
    text = json.dumps(doc)[:-1] + ", " + extra + "}"
    data["sidecar"] = SimpleUploadedFile("dut.bin.json", text.encode())
    response = key_client(lab["key"]).post(URL, {**data, **LINEAR_80}, format="multipart")
    assert response.status_code == 400, response.content
    body = response.json()
    assert message in body["detail"] and body["errors"][0]["field"] == "file"
    assert (RawFile.objects.count(), RawRecord.objects.count()) == (0, 0)


@pytest.mark.parametrize(
    ("field", "value", "message"),
    [
        ("trigger_offset_s", "nan", "trigger_offset_s must be finite"),
        ("u_trigger_offset_s", "-0.1", "u_trigger_offset_s must be >= 0"),
        ("reference_start_time_s", "1e308", "start_time_s must be within"),
        ("orientation", "[" * 5000 + "]" * 5000, "orientation: not valid JSON: nested too deeply"),
        ("trigger_offset_s", "\u0661", "trigger_offset_s must be a number"),
    ],
)  # fmt: skip
def test_hostile_form_fields_are_refused_by_key(lab, field, value, message):
    dut, ref = linear_phase_records(duration=2.0)
    response = key_client(lab["key"]).post(URL, {**upload_fields(dut, ref), **LINEAR_80,
                                                 field: value}, format="multipart")  # fmt: skip
    assert response.status_code == 400 and message in response.json()["detail"]
    assert (RawFile.objects.count(), RawRecord.objects.count()) == (0, 0)
