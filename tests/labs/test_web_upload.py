"""Upload page and template download: CSV/XLSX in, per-row error report, size limit."""

import csv
import io

import openpyxl
import pytest
from django.core.files.uploadedfile import SimpleUploadedFile
from django.urls import reverse

from labs.models import Submission
from tests.factories import MembershipFactory, ParticipantFactory
from tests.labs.test_web import open_comparison, visible

pytestmark = pytest.mark.django_db

UPLOAD = reverse("labs:upload", args=["CMP-U"])
HEADER = "device,axis,frequency_hz,bench,sensitivity,expanded_uncertainty\r\n"


@pytest.fixture
def participant():
    return ParticipantFactory.create(comparison=open_comparison("CMP-U"), code="L66")


@pytest.fixture
def staff(client, participant):
    user = MembershipFactory.create(laboratory=participant.laboratory).user
    client.force_login(user)
    return user


def good_csv(u="8.4") -> bytes:
    lines = [f"MEMS 1,{a},{f},linear,420.5,{u}\r\n" for a in "XY" for f in (5, 10)]
    return (HEADER + "".join(lines)).encode()


def upload(client, data: bytes, name: str, action: str = "draft"):
    return client.post(UPLOAD, {"file": SimpleUploadedFile(name, data), "action": action})


def test_upload_page_has_file_input_and_template_links(client, staff):
    body = visible(client.get(UPLOAD))
    assert 'type="file"' in body and 'for="id_file"' in body
    assert reverse("labs:template", args=["CMP-U", "csv"]) in body
    assert reverse("labs:template", args=["CMP-U", "xlsx"]) in body


def test_good_csv_is_stored_as_draft(client, staff, participant):
    response = upload(client, good_csv(), "results.csv")
    assert response.status_code == 302
    submission = Submission.objects.get(participant=participant)
    assert (submission.status, submission.source) == ("draft", "file")
    assert submission.results.count() == 4


def test_good_xlsx_is_submitted(client, staff, participant):
    workbook = openpyxl.Workbook()
    sheet = workbook.active
    sheet.append(["Device", "Axis", "Frequency_Hz", "Bench", "Sensitivity", "Expanded_Uncertainty"])
    for axis in "XY":
        for f in (5, 10):
            sheet.append(["MEMS 1", axis, f, "linear", 419.0, "1.5%"])
    buffer = io.BytesIO()
    workbook.save(buffer)
    response = upload(client, buffer.getvalue(), "results.xlsx", action="submit")
    assert response.status_code == 302
    submission = Submission.objects.get(participant=participant)
    assert submission.status == "submitted"
    result = submission.results.first()
    assert result is not None and result.expanded_uncertainty == pytest.approx(419 * 0.015)


def test_bad_csv_gives_a_row_report_and_stores_nothing(client, staff):
    data = good_csv().replace(b"MEMS 1,Y,5,linear,420.5,8.4", b"MEMS 1,Y,5,linear,420.5,-3")
    response = upload(client, data, "results.csv", action="submit")
    assert response.status_code == 200
    body = visible(response)
    assert "nothing was stored" in body
    assert '<td data-label="Row" class="text-nowrap">row 4</td>' in body
    assert "<code>expanded_uncertainty</code>" in body and "must be &gt; 0, got -3" in body
    assert not Submission.objects.exists()


def test_file_over_the_limit_is_refused_before_parsing(client, staff, settings):
    settings.MAX_UPLOAD_BYTES = 100
    response = upload(client, good_csv(), "results.csv")
    assert response.status_code == 200
    body = visible(response)
    assert "the limit is 100 bytes" in body and "The file is" in body
    assert not Submission.objects.exists()


def test_csv_template_has_one_row_per_point(client, staff):
    response = client.get(reverse("labs:template", args=["CMP-U", "csv"]))
    assert response["Content-Type"].startswith("text/csv")
    assert 'filename="CMP-U-results-template.csv"' in response["Content-Disposition"]
    rows = list(csv.DictReader(io.StringIO(response.content.decode("utf-8-sig"))))
    assert len(rows) == 4
    assert list(rows[0]) == [
        "device", "axis", "frequency_hz", "bench", "direction", "amplitude_m_s2",
        "sensitivity", "unit", "expanded_uncertainty", "coverage_factor", "dof", "repeat_sd",
        "n_repeats", "note",
    ]  # fmt: skip
    assert {(r["device"], r["axis"], float(r["frequency_hz"])) for r in rows} == {
        ("MEMS 1", a, f) for a in "XY" for f in (5.0, 10.0)
    }
    assert all(r["sensitivity"] == "" and r["expanded_uncertainty"] == "" for r in rows)


def test_xlsx_template_filled_in_uploads(client, staff, participant):
    response = client.get(reverse("labs:template", args=["CMP-U", "xlsx"]))
    workbook = openpyxl.load_workbook(io.BytesIO(response.content))
    sheet = workbook.active
    rows = list(sheet.iter_rows(values_only=True))
    assert len(rows) == 1 + 4 and rows[0][0] == "device"
    filled = openpyxl.Workbook()
    out = filled.active
    header = list(rows[0])
    out.append(header)
    for row in rows[1:]:
        values = list(row)
        values[header.index("sensitivity")] = 421.0
        values[header.index("expanded_uncertainty")] = 8.0
        out.append(values)
    buffer = io.BytesIO()
    filled.save(buffer)
    assert upload(client, buffer.getvalue(), "filled.xlsx", "submit").status_code == 302
    assert Submission.objects.get(participant=participant).results.count() == 4


def test_unknown_template_format_is_404(client, staff):
    assert client.get(reverse("labs:template", args=["CMP-U", "pdf"])).status_code == 404


def test_closed_comparison_upload_shows_reason(client, staff, participant):
    type(participant.comparison).objects.filter(pk=participant.comparison_id).update(
        status="closed"
    )
    body = visible(client.get(UPLOAD))
    assert "is closed" in body and 'value="submit" class="btn btn-primary" disabled' in body
    response = upload(client, good_csv(), "results.csv")
    assert "is closed" in visible(response)
    assert not Submission.objects.exists()
