"""The coordinator's comments, conclusions and authorisation: API, web form, audit log,
the publication rule, and what the PDF prints (escaped)."""

import pytest
from auditlog.models import LogEntry
from django.contrib.auth import get_user_model
from django.test import Client
from rest_framework.test import APIClient

from analysis.models import Report
from analysis.reports.assemble import report_data
from analysis.reports.render import render_report
from proficiency.models import Comparison
from tests.analysis.reports.conftest import CODE, pdf_text

URL = f"/api/v1/comparisons/{CODE}/report-notes/"
MARKUP = 'Lab 3 <b>must</b> check its <font size="40">set-up</font> & cabling; x < 2 > 1.'
NOTES = {
    "comments": MARKUP + "\nSecond line of the comments.",
    "conclusions": "The round shows <i>good</i> agreement overall.",
    "authorised_by_name": "Dr. Ada Lovelace",
    "authorised_by_role": "Technical manager",
}


def api(username=None):
    c = APIClient()
    if username:
        c.force_authenticate(get_user_model().objects.get(username=username))
    return c


def flat(pdf: bytes) -> str:
    return " ".join("\n".join(pdf_text(pdf)).split())


@pytest.mark.django_db
def test_coordinator_stores_notes_through_the_api_and_it_is_audit_logged(demo):
    Comparison.objects.filter(pk=demo.pk).update(authorised_by_name="", authorised_by_role="")
    assert api("coordinator").get(URL).json()["authorised_by_name"] == ""
    response = api("coordinator").put(URL, NOTES, format="json")
    assert response.status_code == 200, response.content
    assert response.json() == NOTES | {"status": "preliminary"}
    demo.refresh_from_db()
    assert demo.report_comments == NOTES["comments"]
    assert demo.report_conclusions == NOTES["conclusions"]
    assert (demo.authorised_by_name, demo.authorised_by_role) == (
        "Dr. Ada Lovelace",
        "Technical manager",
    )
    entry = LogEntry.objects.get_for_object(demo).order_by("-timestamp").first()
    assert entry.actor.username == "coordinator"
    assert entry.changes_dict["authorised_by_name"] == ["", "Dr. Ada Lovelace"]
    assert entry.changes_dict["report_comments"][1] == NOTES["comments"]


@pytest.mark.django_db
def test_notes_are_validated_and_only_coordinators_may_touch_them(demo):
    half = NOTES | {"authorised_by_role": ""}
    response = api("coordinator").put(URL, half, format="json")
    assert response.status_code == 400
    assert response.json()["errors"][0]["field"] == "authorised_by_role"
    long = NOTES | {"comments": "x" * 20_001}
    response = api("coordinator").put(URL, long, format="json")
    assert response.status_code == 400
    assert response.json()["errors"] == [
        {"row": None, "field": "comments", "message": "At most 20,000 characters (20,001 given)."}
    ]
    assert api("lab03").put(URL, NOTES, format="json").status_code == 403
    assert api("lab03").get(URL).status_code == 403
    get_user_model().objects.create_user("outsider", password="x-pass-12345")
    assert api("outsider").put(URL, NOTES, format="json").status_code == 404
    assert api().put(URL, NOTES, format="json").status_code == 401
    demo.refresh_from_db()
    assert demo.report_comments == "" and demo.authorised_by_name == "Demo Quality Manager"


@pytest.mark.django_db
def test_web_form_saves_and_shows_errors(demo):
    web = Client()
    web.force_login(get_user_model().objects.get(username="coordinator"))
    page = f"/coordinator/{CODE}/report-notes/"
    assert web.get(page).status_code == 200
    assert "Report comments and authorisation" in web.get(f"/coordinator/{CODE}/").content.decode()
    response = web.post(page, NOTES)
    assert response.status_code == 302 and response["Location"] == f"/coordinator/{CODE}/"
    demo.refresh_from_db()
    assert demo.report_conclusions == NOTES["conclusions"]
    response = web.post(page, NOTES | {"authorised_by_name": ""})
    assert response.status_code == 200
    assert "Give both the name and the role" in response.content.decode()
    demo.refresh_from_db()
    assert demo.authorised_by_name == "Dr. Ada Lovelace"
    other = Client()
    other.force_login(get_user_model().objects.get(username="lab03"))
    assert other.get(page).status_code == 404
    assert other.post(page, NOTES).status_code == 404


@pytest.mark.django_db(transaction=True)
def test_pdf_prints_notes_escaped_and_preliminary_before_publication(analysed):
    assert api("coordinator").put(URL, NOTES, format="json").status_code == 200
    analysed.comparison.refresh_from_db()
    participant = analysed.comparison.participants.order_by("code").first()
    for who in (None, participant):
        pdf = render_report(report_data(run=analysed, participant=who))
        pages = pdf_text(pdf)
        title = " ".join(pages[0].split())
        assert "Status Preliminary" in title
        assert "Authorised by Dr. Ada Lovelace, Technical manager" in title
        text = flat(pdf)
        # the markup is printed as typed, not interpreted
        assert MARKUP in text and "Second line of the comments." in text
        assert NOTES["conclusions"] in text
        body = text.split("10 Comments and conclusions", 1)[1]
        assert body.index("Comments on performance") < body.index(MARKUP)
        assert body.index("Conclusions") < body.index(NOTES["conclusions"])


@pytest.mark.django_db(transaction=True)
def test_publication_needs_an_authoriser_then_reports_are_final(analysed):
    Comparison.objects.filter(pk=analysed.comparison_id).update(
        authorised_by_name="", authorised_by_role=""
    )
    refused = api("coordinator").post(f"/api/v1/comparisons/{CODE}/publish/")
    assert refused.status_code == 409
    assert "authorising" in refused.json()["detail"]
    comparison = Comparison.objects.get(pk=analysed.comparison_id)
    assert comparison.status == "analysed" and not Report.objects.exists()
    analysed.comparison.refresh_from_db()
    preliminary = flat(render_report(report_data(run=analysed)))
    assert "not yet authorised" in preliminary and "Status Preliminary" in preliminary

    assert api("coordinator").put(URL, NOTES, format="json").status_code == 200
    published = api("coordinator").post(f"/api/v1/comparisons/{CODE}/publish/")
    assert published.status_code == 202, published.content  # the job, done by eager Celery
    summary = Report.objects.get(kind="summary", superseded=False)
    first = " ".join(pdf_text(summary.file.read())[0].split())
    assert "Status Final" in first
    assert "Authorised for issue by Dr. Ada Lovelace, Technical manager" in first
    assert Report.objects.filter(kind="participant").count() == 12

    unsigned = NOTES | {"authorised_by_name": "", "authorised_by_role": ""}
    removed = api("coordinator").put(URL, unsigned, format="json")
    assert removed.status_code == 409
    renamed = NOTES | {"authorised_by_name": "Dr. Grace Hopper"}
    assert api("coordinator").put(URL, renamed, format="json").status_code == 200
