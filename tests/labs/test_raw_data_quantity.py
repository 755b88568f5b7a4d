"""A raw record's recomputation compared by the point's quantity kind (docs/lifecycles.md §5,
docs/domain.md §12.1): a phase point against the axis's phase (En on the wrapped
difference), an angular-rate point against gyroscope axis G<axis> (a gyroscope-only record
too); a phase without a common time base fails with the record's own sentence; an upload
naming no quantity for a point that exists only as another kind is refused."""

from __future__ import annotations

import math
import re
from types import SimpleNamespace

import pytest

from analysis.core.signals.records import Record
from analysis.core.signals.synthetic import imu_records, linear_phase_records
from labs.models import RawFile, RawRecomputation, RawRecord
from labs.raw_outputs import en_number, point_figures
from proficiency.models import MeasurementPoint
from tests.factories import LaboratoryFactory
from tests.labs.raw_data_helpers import (
    api_post,
    axes,
    daq_key,
    key_client,
    raw_round,
    reporting,
    staff,
    upload_fields,
)

pytestmark = pytest.mark.django_db
CODE = "RAW-KINDS"
URL = f"/api/v1/comparisons/{CODE}/raw-data/"
NOTE = "phase not determinable: no common time base"
LINEAR_80 = {"device": "IMU 1", "axis": "X", "frequency_hz": "80", "bench": "linear"}
TABLE_10 = {"device": "IMU 1", "frequency_hz": "10", "bench": "curvilinear",
            "direction": "tangential"}  # fmt: skip
#: what the participant reported at each kind (value, U with k = 2)
REPORTED = {"magnitude": (420.0, 8.0), "phase": (-12.3, 0.5), "angular_rate": (57.2, 0.3)}


@pytest.fixture
def lab():
    laboratory = LaboratoryFactory.create(name="Kinds Lab")
    user = staff(laboratory)
    comparison, points = raw_round(
        CODE, "IMU 1",
        {"axes": ["X", "Z"], "frequencies_hz": [80], "benches": ["linear"],
         "quantities": ["magnitude", "phase"]},
        {"axes": ["X", "Z"], "frequencies_hz": [10], "benches": ["curvilinear"],
         "quantities": ["magnitude", "phase", "angular_rate"]},
        # a point that exists as a phase only
        {"axes": ["X"], "frequencies_hz": [160], "benches": ["linear"], "quantities": ["phase"]},
    )  # fmt: skip
    reporting(comparison, laboratory, "P03", points, REPORTED)
    return {"user": user, "key": daq_key(laboratory)}


def _post(key, data, capture):
    return api_post(URL, key, data, capture)


def _stored(row: RawRecomputation) -> tuple[float, float]:
    """The stored value and its U, present on a succeeded row."""
    assert row.sensitivity is not None and row.expanded_uncertainty is not None, row.error
    return row.sensitivity, row.expanded_uncertainty


def _hand_wrap(d: float) -> float:
    """(−180°, 180°] by hand: the nearest copy of d."""
    while d > 180.0:
        d -= 360.0
    while d <= -180.0:
        d += 360.0
    return d


def _gyro_only(mems: Record) -> Record:
    """The IMU record with its accelerometer channels taken out."""
    keep = [i for i, c in enumerate(mems.channels) if c.startswith("g")]
    channels = tuple(mems.channels[i] for i in keep)
    return Record("gyro-only", channels, mems.data[keep], mems.meta | {"channels": channels})


# --- phase ---------------------------------------------------------------------------------


def test_a_phase_point_stores_the_axis_phase_and_en_against_the_reported_one(
    lab, django_capture_on_commit_callbacks
):
    dut, ref = linear_phase_records(phase_deg=-12.5, duration=10.0, seed=5)
    response = _post(lab["key"], {**upload_fields(dut, ref), **LINEAR_80, "quantity": "phase"},
                     django_capture_on_commit_callbacks)  # fmt: skip
    assert response.status_code == 201, response.json()
    assert response.json()["quantity"] == "phase"
    row = RawRecomputation.objects.get()
    assert row.status == "succeeded", row.error
    assert row.record.measurement_point.quantity == "phase"
    assert row.parameters["quantity"] == "phase"
    x, (phase, big_u) = axes(row)["X"], _stored(row)
    assert abs(phase - (-12.5)) < 0.1  # truth of the synthetic record
    assert phase == x["phase_deg"] and row.standard_uncertainty == x["u_phase_deg"]
    assert (row.coverage_factor, big_u) == (2.0, 2 * x["u_phase_deg"])
    assert row.budget == []
    rep, big_u_rep = REPORTED["phase"]
    hand = (rep - phase) / math.sqrt(big_u_rep**2 + (2 * x["u_phase_deg"]) ** 2)
    assert row.en == pytest.approx(hand, rel=1e-12)


def test_en_of_a_phase_takes_the_wrapped_difference(lab, django_capture_on_commit_callbacks):
    dut, ref = linear_phase_records(phase_deg=-179.9, duration=10.0, seed=5)
    point = MeasurementPoint.objects.get(quantity="phase", bench="linear", axis="X",
                                         frequency_hz=80)  # fmt: skip
    point.results.update(value=179.9)
    response = _post(lab["key"], {**upload_fields(dut, ref), **LINEAR_80, "quantity": "phase"},
                     django_capture_on_commit_callbacks)  # fmt: skip
    assert response.status_code == 201, response.json()
    row = RawRecomputation.objects.get()
    assert row.status == "succeeded", row.error
    phase, big_u = _stored(row)
    assert abs(_hand_wrap(phase - (-179.9))) < 0.1
    d = _hand_wrap(179.9 - phase)  # ≈ −0.2°, not 359.8°
    assert abs(d - (-0.2)) < 0.1
    assert row.en == pytest.approx(d / math.hypot(0.5, big_u), rel=1e-9)
    assert row.phase_difference == pytest.approx(d, abs=1e-9)


def test_en_number_wraps_a_phase_difference_only():
    assert en_number(179.9, 0.3, -179.9, 0.4, "phase") == pytest.approx(-0.2 / 0.5)
    assert en_number(-179.9, 0.3, 179.9, 0.4, "phase") == pytest.approx(0.2 / 0.5)
    assert en_number(420.0, 8.0, 421.0, 6.0, "magnitude") == pytest.approx(-0.1)
    assert en_number(420.0, 8.0, 421.0, 6.0) == pytest.approx(-0.1)  # no kind: magnitude


def test_a_phase_without_a_time_base_fails_with_the_records_sentence(
    client, lab, django_capture_on_commit_callbacks
):
    dut, ref = linear_phase_records(duration=10.0, time_base=None)
    point = MeasurementPoint.objects.get(quantity="phase", bench="linear", axis="X",
                                         frequency_hz=80)  # fmt: skip
    client.force_login(lab["user"])
    with django_capture_on_commit_callbacks(execute=True):
        response = client.post(f"/lab/comparisons/{CODE}/raw-data/", {"point": point.pk,
                               **upload_fields(dut, ref)})  # fmt: skip
    assert response.status_code == 302
    row = RawRecomputation.objects.get()
    assert (row.status, row.error) == ("failed", f"axis X: {NOTE}")
    assert (row.sensitivity, row.expanded_uncertainty, row.en) == (None, None, None)
    page = client.get(response["Location"]).content.decode()
    assert f"The recomputation failed: axis X: {NOTE}" in page
    assert re.search(r'data-testid="quantity">Sensitivity phase<', page), page


def test_the_page_upload_of_a_phase_point_shows_the_kind_and_the_wrapped_difference(
    client, lab, django_capture_on_commit_callbacks
):
    dut, ref = linear_phase_records(phase_deg=-12.5, duration=10.0, seed=5)
    point = MeasurementPoint.objects.get(quantity="phase", bench="linear", axis="X",
                                         frequency_hz=80)  # fmt: skip
    client.force_login(lab["user"])
    form = client.get(f"/lab/comparisons/{CODE}/raw-data/").content.decode()
    assert f'value="{point.pk}"' in form and "80 Hz, linear vertical, sensitivity phase" in form
    with django_capture_on_commit_callbacks(execute=True):
        response = client.post(f"/lab/comparisons/{CODE}/raw-data/", {"point": point.pk,
                               **upload_fields(dut, ref)})  # fmt: skip
    row = RawRecomputation.objects.get()
    assert row.status == "succeeded", row.error
    page = client.get(response["Location"]).content.decode()
    assert "Sensitivity phase (°)" in page
    shown = re.search(r'data-testid="difference">([^<]+)°<', page)
    assert shown and float(shown.group(1)) == pytest.approx(-12.3 - _stored(row)[0], abs=0.01)


# --- angular rate ---------------------------------------------------------------------------


def test_an_angular_rate_point_stores_the_gyroscope_axis(lab, django_capture_on_commit_callbacks):
    mems, enc = imu_records(gyro_dps=57.14)
    response = _post(lab["key"], {**upload_fields(mems, enc), **TABLE_10, "axis": "Z",
                                  "quantity": "angular_rate"},
                     django_capture_on_commit_callbacks)  # fmt: skip
    assert response.status_code == 201, response.json()
    row = RawRecomputation.objects.get()
    assert row.status == "succeeded", row.error
    gz, (s, big_u) = axes(row)["GZ"], _stored(row)
    assert abs(s / 57.14 - 1) < 5e-4  # truth of the synthetic record
    assert (s, big_u) == (gz["sensitivity"], gz["expanded_uncertainty"])
    assert row.coverage_factor == gz["coverage_factor"] and row.budget == gz["budget"]
    assert [c["name"] for c in row.budget] == [c["name"] for c in gz["budget"]] and row.budget
    rep, big_u_rep = REPORTED["angular_rate"]
    hand = (rep - s) / math.sqrt(big_u_rep**2 + big_u**2)
    assert row.en == pytest.approx(hand, rel=1e-12)


def test_a_gyroscope_only_record_recomputes_for_an_angular_rate_point(
    client, lab, django_capture_on_commit_callbacks
):
    mems, enc = imu_records(gyro_dps=57.14, seed=3)
    point = MeasurementPoint.objects.get(quantity="angular_rate", axis="Z",
                                         direction="tangential")  # fmt: skip
    client.force_login(lab["user"])
    with django_capture_on_commit_callbacks(execute=True):
        response = client.post(f"/lab/comparisons/{CODE}/raw-data/", {"point": point.pk,
                               **upload_fields(_gyro_only(mems), enc)})  # fmt: skip
    assert response.status_code == 302
    row = RawRecomputation.objects.get()
    assert row.status == "succeeded", row.error
    assert [a["axis"] for a in row.axes] == ["GX", "GY", "GZ"]
    assert abs(_stored(row)[0] / 57.14 - 1) < 5e-4
    page = client.get(response["Location"]).content.decode()
    assert re.search(r'data-testid="quantity">Angular-rate sensitivity<', page)
    assert "gyroscope axis GZ" in page and "<svg" in page  # the figure of channel gz


def test_a_gyroscope_axis_the_table_does_not_turn_fails_with_its_note(
    lab, django_capture_on_commit_callbacks
):
    mems, enc = imu_records()
    data = {**upload_fields(mems, enc), **TABLE_10, "axis": "X", "quantity": "angular_rate"}
    _post(lab["key"], data, django_capture_on_commit_callbacks)
    row = RawRecomputation.objects.get()
    assert row.status == "failed" and row.sensitivity is None
    assert (
        row.error == "axis GX: not excited. points tangential: the table turns about the "
        "axial direction"
    )


def test_a_gyroscope_only_record_for_a_magnitude_point_still_says_what_is_missing(
    lab, django_capture_on_commit_callbacks
):
    mems, enc = imu_records()
    _post(lab["key"], {**upload_fields(_gyro_only(mems), enc), **TABLE_10, "axis": "X"},
          django_capture_on_commit_callbacks)  # fmt: skip
    row = RawRecomputation.objects.get()
    assert row.status == "failed"
    assert row.error.startswith("the record gives no sensitivity for axis X tangential")


def test_a_point_in_digits_per_rad_s_takes_the_gyroscope_figures_times_180_over_pi():
    gz = {"axis": "GZ", "sensor": "gyroscope", "sensitivity": 57.14,
          "sensitivity_unit": "digits/(°/s)", "standard_uncertainty": 0.01,
          "expanded_uncertainty": 0.02, "coverage_factor": 2.0,
          "budget": [{"name": "A", "sensitivity_coefficient": 0.5,
                      "contribution": 0.004}]}  # fmt: skip
    point = SimpleNamespace(quantity="angular_rate", axis="Z", value_unit="D/(rad/s)")
    got = point_figures([gz], point)  # type: ignore[arg-type]
    per_rad = 180.0 / math.pi
    assert got["sensitivity"] == pytest.approx(57.14 * per_rad, rel=1e-12)
    assert got["expanded_uncertainty"] == pytest.approx(0.02 * per_rad, rel=1e-12)
    assert got["budget"][0]["contribution"] == pytest.approx(0.004 * per_rad, rel=1e-12)
    same = SimpleNamespace(quantity="angular_rate", axis="Z", value_unit="D/(deg/s)")
    assert point_figures([gz], same)["sensitivity"] == 57.14  # type: ignore[arg-type]


# --- which point -----------------------------------------------------------------------------


def test_no_quantity_for_a_point_that_exists_only_as_a_phase_is_refused(lab):
    dut, ref = linear_phase_records(duration=2.0, f=160.0)
    data = {**upload_fields(dut, ref), **LINEAR_80, "frequency_hz": "160"}
    response = key_client(lab["key"]).post(URL, data, format="multipart")
    assert response.status_code == 400, response.content
    body = response.json()
    assert body["detail"] == (
        f"{CODE} has no measurement point IMU 1, X, 160 Hz, linear vertical (sensitivity "
        "magnitude); it has that point as phase only: name the quantity (quantity=phase)."
    )
    assert body["errors"][0]["field"] == "quantity"
    assert (RawFile.objects.count(), RawRecord.objects.count()) == (0, 0)


def test_an_unknown_quantity_is_refused_by_its_field(lab):
    dut, ref = linear_phase_records(duration=2.0)
    data = {**upload_fields(dut, ref), **LINEAR_80, "quantity": "gain"}
    response = key_client(lab["key"]).post(URL, data, format="multipart")
    assert response.status_code == 400
    body = response.json()
    assert body["detail"] == "quantity must be one of magnitude, phase, angular_rate, got 'gain'"
    assert body["errors"][0]["field"] == "quantity"
    assert RawRecord.objects.count() == 0
