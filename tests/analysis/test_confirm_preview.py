"""Coordinators see what open, close, run and publish will do before they do it, and
preview the reports before publication; nobody else sees either (404)."""

from __future__ import annotations

import io

from django.contrib.auth import get_user_model
from django.core import mail
from pypdf import PdfReader

from analysis.models import Report
from proficiency.models import Comparison, ComparisonStatus
from tests.factories import ComparisonFactory, UserFactory

CODE = "IMU-2024-DEMO"
C = f"/coordinator/{CODE}/"


def signed_in(client, username):
    client.force_login(get_user_model().objects.get(username=username))
    return client


def text(pdf: bytes) -> str:
    return " ".join(" ".join(p.extract_text() for p in PdfReader(io.BytesIO(pdf)).pages).split())


def test_publish_says_what_will_happen_and_changes_nothing(client, run):
    signed_in(client, "coordinator")
    response = client.get(C + "confirm/publish/")
    assert response.status_code == 200
    page = " ".join(response.content.decode().split())
    assert (
        f"The results of analysis run {run.pk} become visible to the 12 participating "
        "laboratories" in page
    )
    assert "12 laboratories are e-mailed, with links to their results and reports." in page
    assert "(the summary and 12 participant reports)" in page
    assert "Publication is final: it cannot be undone." in page
    assert f'<form method="post" action="{C}publish/"' in page and "btn-danger" in page
    Comparison.objects.get(code=CODE, status=ComparisonStatus.ANALYSED)  # still analysed
    assert mail.outbox == []
    # the results page leads to the confirmation, not straight to publishing
    results = client.get(C + "results/").content.decode()
    assert f'href="{C}confirm/publish/"' in results and f'action="{C}publish/"' not in results


def test_open_close_and_run_pages_count_the_round(client, demo):
    signed_in(client, "coordinator")
    opened = " ".join(client.get(C + "confirm/open/").content.decode().split())
    assert "Reopen IMU-2024-DEMO for submissions" in opened  # the demo round is closed
    assert "only if its deadline changed" in opened
    assert '<input type="hidden" name="to" value="open">' in opened
    run = " ".join(client.get(C + "confirm/run/").content.decode().split())
    assert "from 12 accepted submissions" in run and "nobody is e-mailed" in run
    refused = client.get(C + "confirm/close/").content.decode()
    assert "it cannot be closed now" in refused and "<form" not in refused.split("<main")[-1]
    comparison_page = client.get(C).content.decode()
    assert (
        f'href="{C}confirm/open/"' in comparison_page
        and f'href="{C}confirm/run/"' in comparison_page
    )
    assert client.get(C + "confirm/delete/").status_code == 404


def test_a_fresh_round_counts_its_invited_laboratories(client, db):
    comparison = ComparisonFactory.create(code="NEW-01", status=ComparisonStatus.DRAFT)
    user = UserFactory.create()
    comparison.coordinators.add(user)
    client.force_login(user)
    page = " ".join(client.get("/coordinator/NEW-01/confirm/open/").content.decode().split())
    assert "Open NEW-01 for submissions" in page
    assert "0 participating laboratories are e-mailed that the round is open" in page
    run = client.get("/coordinator/NEW-01/confirm/run/").content.decode()
    assert "close it before running the analysis" in run


def test_confirmations_and_previews_are_the_coordinators_only(client, run):
    other = UserFactory.create()
    ComparisonFactory.create().coordinators.add(other)
    for who in (other, get_user_model().objects.get(username="lab03")):
        client.force_login(who)
        for url in ("confirm/publish/", "reports/preview/", "reports/preview/summary.pdf"):
            assert client.get(C + url).status_code == 404, (who, url)


def test_the_preview_is_rendered_not_stored(client, run):
    signed_in(client, "coordinator")
    listing = client.get(C + "reports/preview/").content.decode()
    assert f"from analysis run {run.pk}" in listing
    assert listing.count("Preview PDF") == 13  # the summary and 12 participants
    response = client.get(C + "reports/preview/summary.pdf")
    assert response.status_code == 200 and response["Content-Type"] == "application/pdf"
    assert response["Cache-Control"] == "no-store"
    summary = text(response.content)
    assert "Preview for the coordinator (not issued" in summary
    assert "Summary report" in summary
    code = run.comparison.participants.order_by("code").first().code
    own = text(client.get(f"{C}reports/preview/{code}.pdf").content)
    assert "Participant report" in own and code in own
    assert client.get(C + "reports/preview/NOBODY.pdf").status_code == 404
    assert Report.objects.count() == 0  # nothing issued, nothing stored
    assert "Preview the reports" in client.get(f"/reports/{CODE}/").content.decode()


def test_a_preview_needs_a_run(client, demo):
    signed_in(client, "coordinator")
    assert client.get(C + "reports/preview/summary.pdf").status_code == 409
    assert "no successful analysis run yet" in client.get(C + "reports/preview/").content.decode()


def test_a_reissue_says_what_it_does_then_issues_one_new_version(client, run):
    """From the reports page: Reissue… → the confirmation (which version, from which run,
    the old one kept, nobody e-mailed) → POST → one new version, the old one superseded."""
    from analysis.reports.services import report_issue

    code = run.comparison.participants.order_by("code").first().code
    participant = run.comparison.participants.get(code=code)
    first = report_issue(comparison=run.comparison, kind="participant", participant=participant)
    signed_in(client, "coordinator")
    listing = client.get(f"/reports/{CODE}/").content.decode()
    assert f'href="{C}confirm/reissue/?report={code}"' in listing
    page = " ".join(client.get(f"{C}confirm/reissue/?report={code}").content.decode().split())
    assert f"Reissue participant report {code} of {CODE}" in page
    assert (
        f"Version 2 of participant report {code} is rendered now from analysis run {run.pk}" in page
    )
    assert "as a preliminary report." in page
    assert "Version 1 stays downloadable, marked superseded." in page
    assert f'action="{C}reports/reissue/"' in page and f'value="{code}"' in page
    assert Report.objects.count() == 1  # the page changes nothing
    assert client.get(f"{C}confirm/reissue/?report=NOBODY").status_code == 404

    response = client.post(f"{C}reports/reissue/", {"report": code})
    assert response.status_code == 302 and response["Location"] == f"/reports/{CODE}/"
    versions = Report.objects.filter(participant=participant).order_by("version")
    assert [(r.version, r.superseded) for r in versions] == [(1, True), (2, False)]
    assert versions[0].pk == first.pk
    shown = client.get(f"/reports/{CODE}/").content.decode()
    assert f"Participant report {code} issued as version 2." in shown
    assert mail.outbox == []
    # the summary too, as its first version
    assert client.post(f"{C}reports/reissue/", {"report": "summary"}).status_code == 302
    assert Report.objects.filter(kind="summary").get().version == 1


def test_a_reissue_is_the_coordinators_only(client, run):
    other = UserFactory.create()
    ComparisonFactory.create().coordinators.add(other)
    for who in (other, get_user_model().objects.get(username="lab03")):
        client.force_login(who)
        assert client.get(C + "confirm/reissue/?report=summary").status_code == 404
        assert client.post(C + "reports/reissue/", {"report": "summary"}).status_code == 404
    assert Report.objects.count() == 0
