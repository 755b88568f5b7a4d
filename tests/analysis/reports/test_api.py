"""Report API and page: publication issues the reports; who may list and download what."""

import pytest
from django.contrib.auth import get_user_model
from rest_framework.test import APIClient

from analysis.models import Report, ReportDownload
from labs.models import Laboratory, Participant
from labs.services import api_key_create
from tests.analysis.reports.conftest import CODE, pdf_text

pytestmark = pytest.mark.django_db(transaction=True)


def client(username=None):
    c = APIClient()
    if username:
        c.force_authenticate(get_user_model().objects.get(username=username))
    return c


@pytest.fixture
def published(analysed):
    response = client("coordinator").post(f"/api/v1/comparisons/{CODE}/publish/")
    assert response.status_code == 202, response.content  # the job, done by eager Celery
    return analysed.comparison


def code_of(username):
    return Participant.objects.get(
        comparison__code=CODE, laboratory__members__user__username=username
    ).code


def test_publishing_issues_summary_and_every_participant_report(published):
    reports = Report.objects.filter(comparison=published, superseded=False)
    assert reports.filter(kind="summary").count() == 1
    assert reports.filter(kind="participant").count() == 12
    summary = reports.get(kind="summary")
    assert "Final" in pdf_text(summary.file.read())[0]


def test_participant_sees_summary_and_own_report_only(stand_in_pdf, published):
    listed = client("lab03").get(f"/api/v1/comparisons/{CODE}/reports/")
    assert listed.status_code == 200
    body = listed.json()
    assert {(r["kind"], r["participant"]) for r in body} == {
        ("summary", None),
        ("participant", code_of("lab03")),
    }
    own = next(r for r in body if r["kind"] == "participant")
    pdf = client("lab03").get(own["download_url"])
    assert pdf.status_code == 200 and pdf["Content-Type"] == "application/pdf"
    assert b"".join(pdf.streaming_content).startswith(b"%PDF")
    assert ReportDownload.objects.filter(user__username="lab03").count() == 1


def test_other_participants_report_is_not_found(stand_in_pdf, published):
    theirs = Report.objects.get(kind="participant", participant__code=code_of("lab04"))
    url = f"/api/v1/reports/{theirs.token}/pdf"
    assert client("lab03").get(url).status_code == 404
    assert client("lab04").get(url).status_code == 200
    assert client().get(url).status_code == 401
    assert client("lab03").get(f"/api/v1/reports/{theirs.pk}/pdf").status_code == 404
    lab = Laboratory.objects.get(name="Alpine Vibration Metrology")
    _, key = api_key_create(laboratory=lab, name="software", user=None)
    by_key = APIClient()
    by_key.credentials(HTTP_AUTHORIZATION=f"Api-Key {key}")
    assert by_key.get(url).status_code == 404
    own = Report.objects.get(kind="participant", participant__laboratory=lab)
    assert by_key.get(f"/api/v1/reports/{own.token}/pdf").status_code == 200
    assert ReportDownload.objects.filter(laboratory=lab).count() == 1


def test_coordinator_sees_all_and_can_issue(stand_in_pdf, published):
    coord = client("coordinator")
    assert len(coord.get(f"/api/v1/comparisons/{CODE}/reports/").json()) == 13
    issued = coord.post(f"/api/v1/comparisons/{CODE}/reports/", {"kind": "summary"})
    assert issued.status_code == 201 and issued.json()["version"] == 2
    assert (
        client("lab03")
        .post(f"/api/v1/comparisons/{CODE}/reports/", {"kind": "summary"})
        .status_code
        == 403
    )
    assert client().get(f"/api/v1/comparisons/{CODE}/reports/").status_code == 401


def test_no_reports_for_participants_before_publication(stand_in_pdf, analysed):
    client("coordinator").post(f"/api/v1/comparisons/{CODE}/reports/", {"kind": "summary"})
    assert client("lab03").get(f"/api/v1/comparisons/{CODE}/reports/").json() == []
    token = Report.objects.get().token
    assert client("lab03").get(f"/api/v1/reports/{token}/pdf").status_code == 404
    assert client("coordinator").get(f"/api/v1/reports/{token}/pdf").status_code == 200


def test_reports_page(stand_in_pdf, published):
    from django.test import Client

    web = Client()
    assert web.get(f"/reports/{CODE}/").status_code == 302
    web.force_login(get_user_model().objects.get(username="lab03"))
    page = web.get(f"/reports/{CODE}/")
    assert page.status_code == 200
    html = page.content.decode()
    assert code_of("lab03") in html and code_of("lab04") not in html
    assert html.count("/api/v1/reports/") == 2
