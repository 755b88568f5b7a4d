"""Phase and angular-rate cells at their extremes, through every entry path, on PostgreSQL
(docs/interfaces.md §1, docs/domain.md §2 and §12).

A cell is either refused — 400, one error naming its row and column, nothing stored — or
stored as its kind stores it: a phase wrapped into (−180°, 180°] *exactly* (a phase already
there bit for bit, 0.1 stays 0.1, −180 becomes 180, 540 becomes 180, −0 becomes 0, and
a huge phase its true remainder), an angular rate per rad/s made per °/s (× π/180) and
never infinite.  The same cells go through the JSON rows of the API, a CSV upload and an
XLSX upload (text and numeric cells, numeric cells whose text is no number included).

Found here: the wrap shifted by 180° before taking the remainder, which rounded (0.1° was
stored as 0.0999999999999943°, 1e-30° as 0, and 1e22° as 100° instead of −80°); an XLSX
numeric cell ``nan`` made the whole worksheet "unreadable" without a row or column; the
range error of a negative phase quoted it without its sign.
"""

from __future__ import annotations

import io
import json
import math
import re
import zipfile
from fractions import Fraction

import openpyxl
import pytest
from django.core.files.uploadedfile import SimpleUploadedFile
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from rest_framework.test import APIClient

from labs.models import Result, Submission
from labs.services import api_key_create, submission_from_records
from proficiency.services import measurement_points_generate
from tests.factories import ComparisonFactory, DeviceFactory, ParticipantFactory

pytestmark = pytest.mark.django_db

CODE = "HOSTILE-Q"
SUBMIT = f"/api/v1/comparisons/{CODE}/submissions/"
UPLOAD = f"{SUBMIT}upload/"
POINT = {"device": "MEMS 1", "axis": "X", "frequency_hz": "10", "bench": "curvilinear",
         "direction": "tangential"}  # fmt: skip
RANGE = "must be 0 or of a size between 1e-30 and 1e30 (the range the statistics can carry)"


def exact_wrap(text: str) -> float:
    """The phase ``text`` wrapped into (−180°, 180°] in exact arithmetic (the reference)."""
    r = Fraction(float(text)) % 360
    return float(r - 360 if r > 180 else r)


#: (cell, stored phase): every one stored exactly as :func:`exact_wrap` says
GOOD = (
    ("180", 180.0), ("-180", 180.0), ("540", 180.0), ("-540", 180.0), ("-0.0", 0.0),
    ("0", 0.0), ("0.1", 0.1), ("-179.9", -179.9), ("190.1", exact_wrap("190.1")),
    ("359.99999999999994", exact_wrap("359.99999999999994")), ("1e-30", 1e-30),
    ("-1e-30", -1e-30), ("1e-10", 1e-10), ("1e22", -80.0), ("1e30", 16.0), ("-1e30", -16.0),
    ("+12.5E0", 12.5),
)  # fmt: skip
#: (cell, message the error starts with)
BAD = (
    ("1e-300", f"{RANGE}, got 1e-300"), ("1e-320", f"{RANGE}, got 1e-320"),
    ("1e308", f"{RANGE}, got 1e308"), ("-1e308", f"{RANGE}, got -1e308"),
    ("-1e31", f"{RANGE}, got -1e31"), ("nan", "must be a finite number, got 'nan'"),
    ("inf", "must be a finite number, got 'inf'"), ("-inf", "must be a finite number"),
    ("1e400", "must be a finite number, got '1e400'"),
    ("1\x00", "contains the control character U+0000 at position 2"),
    ("\x1b[0m5", "contains the control character U+001B at position 1"),
    ("12\x85", "contains the control character U+0085 at position 3"),
    ("１８０", "must be a number, got '１８０'"), ("1_80", "must be a number, got '1_80'"),
    ("0x10", "must be a number, got '0x10'"), ("", "is required"),
)  # fmt: skip


@pytest.fixture
def lab(needs_postgres):
    comparison = ComparisonFactory.create(code=CODE, status="open", protocol="custom")
    device = DeviceFactory.create(comparison=comparison, name="MEMS 1", unit="D/(m/s^2)")
    measurement_points_generate(
        comparison=comparison, devices=[device], axes=["X"], frequencies_hz=[10],
        benches=["curvilinear"], quantities=["magnitude", "phase", "angular_rate"],
    )  # fmt: skip
    participant = ParticipantFactory.create(comparison=comparison, code="L44")
    client = APIClient()
    key = api_key_create(laboratory=participant.laboratory, name="daq", user=None)[1]
    client.credentials(HTTP_AUTHORIZATION=f"Api-Key {key}")
    return client, participant


def row(quantity: str, sensitivity: object, u: object = "0.5", unit: str = "") -> dict:
    return {**POINT, "quantity": quantity, "sensitivity": sensitivity,
            "expanded_uncertainty": u, "unit": unit}  # fmt: skip


def as_csv(record: dict) -> bytes:
    names = list(record)
    return (",".join(names) + "\n" + ",".join(str(record[n]) for n in names) + "\n").encode()


def as_xlsx(record: dict, numeric: str | None = None) -> bytes:
    """The record as a workbook of text cells; with ``numeric``, the sensitivity cell is a
    numeric cell holding that text as written (``<c><v>nan</v></c>``: no spreadsheet writes
    it, a generator may)."""
    book = openpyxl.Workbook()
    sheet = book.active
    assert sheet is not None
    sheet.title = "results"
    sheet.append(list(record))
    sheet.append([str(v) for v in record.values()])
    buffer = io.BytesIO()
    book.save(buffer)
    if numeric is None:
        return buffer.getvalue()
    column = "ABCDEFGHIJ"[list(record).index("sensitivity")]
    source, out = zipfile.ZipFile(buffer), io.BytesIO()
    with zipfile.ZipFile(out, "w") as target:
        for item in source.infolist():
            data = source.read(item.filename)
            if item.filename == "xl/worksheets/sheet1.xml":
                cell = f'<c r="{column}2"><v>{numeric}</v></c>'
                data = re.sub(rf'<c r="{column}2".*?</c>'.encode(), cell.encode(), data)
            target.writestr(item, data)
    return out.getvalue()


def send(client: APIClient, route: str, record: dict, numeric: str | None = None):
    """The record by ``route``, as a draft (a partial table); (answer, its row number)."""
    if route == "json":
        return client.post(SUBMIT, {"results": [record], "submit": False}, format="json"), 1
    data = as_csv(record) if route == "csv" else as_xlsx(record, numeric)
    upload = SimpleUploadedFile(f"r.{route}", data)
    return client.post(UPLOAD, {"file": upload, "submit": "false"}, format="multipart"), 2


def stored(participant, quantity: str) -> Result:
    return Result.objects.get(submission__participant=participant,
                              measurement_point__quantity=quantity)  # fmt: skip


def refused(answer, row: int, field: str, message: str, before: tuple[int, int]) -> None:
    assert answer.status_code == 400, answer.content
    errors = answer.json()["errors"]
    assert [(e["row"], e["field"]) for e in errors] == [(row, field)], errors
    assert errors[0]["message"].startswith(message), errors
    assert (Submission.objects.count(), Result.objects.count()) == before


def counts() -> tuple[int, int]:
    return Submission.objects.count(), Result.objects.count()


@pytest.mark.parametrize("route", ["json", "csv", "xlsx"])
def test_good_phases_are_stored_wrapped_exactly(lab, route):
    client, participant = lab
    for cell, expected in GOOD:
        answer, _ = send(client, route, row("phase", cell))
        assert answer.status_code == 201, (cell, answer.content)
        result = stored(participant, "phase")
        assert (result.value, result.unit) == (expected, "deg"), cell
        assert math.copysign(1.0, result.value) == math.copysign(1.0, expected), cell  # no −0
        assert result.value == exact_wrap(cell), cell


@pytest.mark.parametrize("route", ["json", "csv", "xlsx"])
def test_bad_phases_are_refused_naming_row_and_column_and_nothing_is_stored(lab, route):
    client, _ = lab
    for cell, message in BAD:
        if route == "xlsx" and any(c in cell for c in "\x00\x1b"):
            continue  # XML cannot hold them: the next test
        before = counts()
        answer, number = send(client, route, row("phase", cell))
        refused(answer, number, "sensitivity", message, before)


def test_xlsx_numeric_cells_that_are_no_number_are_named_by_row_and_column(lab):
    """``<v>nan</v>`` made openpyxl's cast fail and the whole worksheet "unreadable"."""
    client, participant = lab
    for text, message in (
        ("nan", "must be a finite number, got 'nan'"), ("inf", "must be a finite number"),
        ("0x10", "must be a number, got '0x10'"), ("1e309", "must be a finite number"),
        ("-1e308", f"{RANGE}, got -1e+308"), ("1E-320", f"{RANGE}, got 1e-320"),
    ):  # fmt: skip
        before = counts()
        answer, number = send(client, "xlsx", row("phase", "0"), numeric=text)
        refused(answer, number, "sensitivity", message, before)
    for text, expected in (("-180", 180.0), ("540", 180.0), ("-0", 0.0), ("0.1", 0.1)):
        answer, _ = send(client, "xlsx", row("phase", "0"), numeric=text)
        assert answer.status_code == 201, (text, answer.content)
        assert stored(participant, "phase").value == expected, text


def test_an_xlsx_whose_xml_holds_a_control_character_is_refused_whole(lab):
    client, _ = lab
    before = counts()
    answer, _ = send(client, "xlsx", row("phase", "0"), numeric="1&#x1;")
    assert answer.status_code == 400, answer.content
    (error,) = answer.json()["errors"]
    assert error["row"] is None and error["message"].startswith("the worksheet cannot be read")
    assert counts() == before


@pytest.mark.parametrize("route", ["json", "csv", "xlsx"])
def test_a_phases_u_is_in_degrees_and_within_the_range(lab, route):
    client, participant = lab
    for u, message in (
        ("1%", "a phase's U is given in deg, not as a percentage, got '1%'"),
        ("0.5 %", "a phase's U is given in deg, not as a percentage"),
        ("1e31", "must be between 1e-30 and 1e30"), ("1e-320", "must be between 1e-30"),
        ("nan", "must be a finite number"), ("-1", "must be > 0, got -1"), ("0", "must be > 0"),
    ):  # fmt: skip
        before = counts()
        answer, number = send(client, route, row("phase", "10", u=u))
        refused(answer, number, "expanded_uncertainty", message, before)
    answer, _ = send(client, route, row("phase", "10", u="1e30"))  # huge, in range: kept
    assert answer.status_code == 201, answer.content
    result = stored(participant, "phase")
    assert (result.value, result.expanded_uncertainty, result.standard_uncertainty) == (
        10.0, 1e30, 5e29)  # fmt: skip


def test_json_numbers_and_literals(lab):
    client, participant = lab
    for number, expected in ((-0.0, 0.0), (540, 180.0), (-180.0, 180.0), (0.1, 0.1)):
        answer, _ = send(client, "json", row("phase", number))
        assert answer.status_code == 201, answer.content
        assert stored(participant, "phase").value == expected
    before = counts()
    for number in (1e308, -1e308, 10**400):
        answer, _ = send(client, "json", row("phase", number))
        assert answer.status_code == 400, answer.content
        assert [e["field"] for e in answer.json()["errors"]] == ["sensitivity"]
    for literal in ("NaN", "Infinity", "-Infinity"):
        body = json.dumps({"results": [row("phase", 0)], "submit": False})
        body = body.replace('"sensitivity": 0', f'"sensitivity": {literal}')
        answer = client.post(SUBMIT, body, content_type="application/json")
        assert answer.status_code == 400, (literal, answer.content)
    assert counts() == before


@pytest.mark.parametrize("route", ["json", "csv", "xlsx"])
def test_an_angular_rate_per_rad_s_is_converted_and_never_infinite(lab, route):
    """× π/180 (docs/domain.md §2: digits per rad/s are π/180 as many per °/s): the
    conversion makes a value smaller, so only the range of the cells and of the result
    can be crossed, and a percentage of a huge value can overflow: each is refused."""
    client, participant = lab
    cases = (
        ("1e308", "1", "sensitivity", RANGE.replace("0 or of a size ", "")),
        ("1e-30", "1e-30", "sensitivity", "is 1.74533e-32 after the conversion from D/(rad/s)"),
        ("1e30", "1e300%", "expanded_uncertainty", "U is inf after the conversion"),
        ("1e30", "1e30%", "expanded_uncertainty", "U is 1.74533e+56 after the conversion"),
        ("-57.3", "1", "sensitivity", "must be > 0, got -57.3"),
        ("inf", "1", "sensitivity", "must be a finite number"),
    )
    for value, u, field, message in cases:
        before = counts()
        answer, number = send(client, route, row("angular_rate", value, u, "D/(rad/s)"))
        assert answer.status_code == 400, answer.content
        errors = answer.json()["errors"]
        assert errors[0]["row"] == number and errors[0]["field"] == field, errors
        assert errors[0]["message"].startswith(message), errors
        assert counts() == before
    for value, u in (("1e30", "1e30"), ("57.29577951308232", "1%"), ("2e-28", "2e-28")):
        answer, _ = send(client, route, row("angular_rate", value, u, "LSB/(rad/s)"))
        assert answer.status_code == 201, answer.content
        result = stored(participant, "angular_rate")
        factor = math.pi / 180
        assert result.unit == "D/(deg/s)" and result.value == float(value) * factor
        assert math.isfinite(result.expanded_uncertainty)
        if u.endswith("%"):
            assert result.expanded_uncertainty == pytest.approx(0.01 * result.value, rel=1e-15)
        else:
            assert result.expanded_uncertainty == float(u) * factor


@settings(
    max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(
    st.one_of(
        st.floats(min_value=-1e30, max_value=1e30).filter(lambda x: x == 0 or abs(x) >= 1e-30),
        st.sampled_from([180.0, -180.0, 540.0, -540.0, 0.1, -0.0, 1e22, 359.99999999999994]),
    )
)
def test_any_phase_in_range_round_trips_postgresql_exactly(lab, phase):
    """Positive generation: what the importer accepts, PostgreSQL keeps bit for bit."""
    _, participant = lab
    submission_from_records(participant=participant, records=[row("phase", repr(phase))],
                            source="api", user=None, submit=False)  # fmt: skip
    value = stored(participant, "phase").value
    assert value == exact_wrap(repr(phase)) and -180.0 < value <= 180.0
    assert math.copysign(1.0, value) == 1.0 or value != 0.0
