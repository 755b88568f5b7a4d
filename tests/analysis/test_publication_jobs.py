"""Publication as a background job (docs/lifecycles.md §1): asked for at request time, where
every refusal is said at once; the task renders every final report first and publishes in
one transaction only once all of them exist; a failure publishes nothing.  Eager Celery:
the job's task runs when the request's transaction commits."""

from __future__ import annotations

import datetime as dt
from pathlib import Path

import pytest
from django.contrib.auth import get_user_model
from django.core import mail
from django.utils import timezone
from rest_framework.test import APIClient

from analysis.models import Publication, Report
from analysis.publication import publication_execute, publication_start
from analysis.reports.services import report_issue
from analysis.services import analysis_run_start
from analysis.tasks import jobs_sweep_task, publication_task
from labs.models import Notice
from proficiency.models import Comparison
from proficiency.services import comparison_transition
from tests.conftest import stand_in_pdf_bytes
from tests.factories import ComparisonFactory, UserFactory

CODE = "IMU-2024-DEMO"
C = f"/coordinator/{CODE}/"
API = f"/api/v1/comparisons/{CODE}/publish/"


def person(username: str):
    return get_user_model().objects.get(username=username)


def signed_in(client, username: str):
    client.force_login(person(username))
    return client


def api(username: str) -> APIClient:
    client = APIClient()
    client.force_authenticate(person(username))
    return client


@pytest.fixture
def stand_in(monkeypatch):
    """A stand-in PDF; (participant code, status, job progress, comparison status) at each
    report rendered."""
    seen: list[tuple] = []

    def render(data):
        job = Publication.objects.order_by("-pk").first()
        status = Comparison.objects.get(code=CODE).status
        seen.append((data.own_code, data.status, job.progress if job else None, status))
        return stand_in_pdf_bytes(data)

    monkeypatch.setattr("analysis.reports.services.render_report", render)
    return seen


def current(comparison) -> list[tuple]:
    """(kind, participant code, status, version) of the current reports, sorted."""
    rows = Report.objects.filter(comparison=comparison, superseded=False)
    return sorted(
        (r.kind, r.participant.code if r.participant else "", r.status, r.version)
        for r in rows.select_related("participant")
    )


def files(media: Path) -> set[str]:
    folder = Path(media) / "reports" / CODE
    return {p.name for p in folder.iterdir()} if folder.exists() else set()


def test_publish_renders_every_report_then_publishes_and_lands_on_a_finished_page(
    client, run, demo, django_capture_on_commit_callbacks
):
    """Real PDFs, eager Celery: the request ends on the progress page of a finished job."""
    signed_in(client, "coordinator")
    mail.outbox.clear()
    with django_capture_on_commit_callbacks(execute=True):
        response = client.post(C + "publish/")
    job = Publication.objects.get()
    assert response.status_code == 302
    assert response["Location"] == f"{C}publication/{job.pk}/"
    assert (job.status, job.progress, job.stage, job.error, job.attempts) == (
        "succeeded", 100, "published", "", 1,
    )  # fmt: skip
    assert job.run == run and job.requested_by == person("coordinator")
    assert job.started_at and job.finished_at and job.token and job.claimed_by
    demo.refresh_from_db()
    assert demo.status == "published"
    codes = sorted(demo.participants.values_list("code", flat=True))
    assert current(demo) == sorted(
        [("summary", "", "final", 1)] + [("participant", c, "final", 1) for c in codes]
    )
    finals = Report.objects.filter(comparison=demo, superseded=False)
    assert sorted(job.report_ids) == sorted(finals.values_list("pk", flat=True))
    assert all(r.file.read(5) == b"%PDF-" for r in finals)
    notices = Notice.objects.filter(comparison=demo, kind="published")
    assert notices.count() == 12 == notices.values("participant").distinct().count()
    assert len(mail.outbox) == 12

    page = " ".join(client.get(response["Location"]).content.decode().split())
    assert 'data-status="succeeded"' in page and "hx-get" not in page
    assert "the final reports are issued and the participants were told by e-mail" in page
    assert f'href="{C}results/"' in page


def test_progress_counts_the_reports_while_the_round_stays_analysed(
    run, demo, stand_in, django_capture_on_commit_callbacks
):
    with django_capture_on_commit_callbacks(execute=True):
        job = publication_start(comparison=demo, user=person("coordinator"))
    # each report rendered: the job's progress so far (1 when claimed, up to 95), and the
    # comparison still analysed; the summary first, then the participants in code order
    codes = sorted(demo.participants.values_list("code", flat=True))
    assert stand_in == [
        (code, "final", 1 + 94 * i // 13, "analysed") for i, code in enumerate([None, *codes])
    ]
    job.refresh_from_db()
    assert (job.status, job.progress) == ("succeeded", 100)


def test_a_rendering_failure_publishes_nothing_and_the_coordinator_can_try_again(
    client, run, demo, monkeypatch, settings, django_capture_on_commit_callbacks
):
    early = [
        report_issue(comparison=demo, kind="summary"),
        report_issue(comparison=demo, kind="participant", participant=demo.participants.first()),
    ]
    assert {r.status for r in early} == {"preliminary"}
    before = current(demo)
    kept = files(settings.MEDIA_ROOT)
    assert len(kept) == 2
    codes = sorted(demo.participants.values_list("code", flat=True))
    broken = codes[4]
    rendered: list[str | None] = []

    def render(data):
        if data.own_code == broken:
            raise RuntimeError("the disk is full")
        rendered.append(data.own_code)
        return stand_in_pdf_bytes(data)

    monkeypatch.setattr("analysis.reports.services.render_report", render)
    signed_in(client, "coordinator")
    mail.outbox.clear()
    with django_capture_on_commit_callbacks(execute=True):
        response = client.post(C + "publish/")
    job = Publication.objects.get()
    assert response["Location"] == f"{C}publication/{job.pk}/"
    assert (job.status, job.error) == ("failed", "RuntimeError: the disk is full")
    assert job.finished_at is not None and job.report_ids == []
    assert rendered == [None, *codes[:4]]  # stopped at the broken one
    demo.refresh_from_db()
    assert demo.status == "analysed"
    assert not Notice.objects.filter(kind="published").exists() and mail.outbox == []
    assert not Report.objects.filter(status="final").exists()
    assert current(demo) == before  # the preliminary reports are still the current ones
    assert files(settings.MEDIA_ROOT) == kept  # the five rendered files were deleted

    page = " ".join(client.get(response["Location"]).content.decode().split())
    assert "The publication failed:</strong> RuntimeError: the disk is full" in page
    assert f"Nothing was published: {CODE} is still analysed" in page
    assert f'href="{C}confirm/publish/">Try again</a>' in page
    assert "hx-get" not in page

    broken = "nobody"  # the disk has room again
    with django_capture_on_commit_callbacks(execute=True):
        again = client.post(C + "publish/")
    second = Publication.objects.get(status="succeeded")
    assert again["Location"] == f"{C}publication/{second.pk}/" and second.pk != job.pk
    demo.refresh_from_db()
    assert demo.status == "published"
    reissued = demo.participants.get(pk=early[1].participant_id).code
    assert current(demo) == sorted(
        [("summary", "", "final", 2)]
        + [("participant", c, "final", 2 if c == reissued else 1) for c in codes]
    )
    assert Notice.objects.filter(kind="published").count() == 12 and len(mail.outbox) == 12


def test_a_second_delivery_of_a_succeeded_job_changes_nothing(
    run, demo, stand_in, django_capture_on_commit_callbacks
):
    with django_capture_on_commit_callbacks(execute=True):
        job = publication_start(comparison=demo)
    job.refresh_from_db()
    assert job.status == "succeeded"
    reports = sorted(Report.objects.values_list("pk", "sha256", "superseded"))
    n_rendered, n_mail = len(stand_in), len(mail.outbox)
    ended = (job.finished_at, job.attempts, job.token, job.report_ids)

    with django_capture_on_commit_callbacks(execute=True):
        # the same message again (its own Celery id), then another task for the same job
        assert publication_execute(publication_id=job.pk, delivery=job.claimed_by) == "succeeded"
        assert publication_task.apply(args=(job.pk,), task_id="again").get() == "succeeded"
    job.refresh_from_db()
    assert (job.finished_at, job.attempts, job.token, job.report_ids) == ended
    assert sorted(Report.objects.values_list("pk", "sha256", "superseded")) == reports
    assert Notice.objects.filter(kind="published").count() == 12
    assert len(stand_in) == n_rendered and len(mail.outbox) == n_mail
    assert Publication.objects.count() == 1


def test_a_second_request_while_one_is_pending_is_refused(client, run, demo):
    """Without executing the commit callbacks the first job stays pending."""
    first = api("coordinator").post(API)
    assert first.status_code == 202
    assert (first.json()["status"], first.json()["publication"]["status"]) == (
        "analysed", "pending",
    )  # fmt: skip
    job = Publication.objects.get()
    second = api("coordinator").post(API)
    assert second.status_code == 409
    assert second.json()["detail"] == (
        f"{CODE} is being published already (publication {job.pk}, pending); wait for it to end."
    )
    signed_in(client, "coordinator")
    response = client.post(C + "publish/", follow=True)
    assert response.redirect_chain == [(f"{C}publication/{job.pk}/", 302)]
    page = " ".join(response.content.decode().split())
    assert f"publication {job.pk}, pending); wait for it to end." in page
    assert f'hx-get="{C}publication/{job.pk}/progress/"' in page  # polls while pending
    assert Publication.objects.count() == 1
    demo.refresh_from_db()
    assert demo.status == "analysed"


def test_refusals_are_said_at_once_and_make_no_job(client, run, demo):
    Comparison.objects.filter(pk=demo.pk).update(authorised_by_name="", authorised_by_role="")
    refused = api("coordinator").post(API)
    assert refused.status_code == 409 and "authorising them" in refused.json()["detail"]
    Comparison.objects.filter(pk=demo.pk).update(authorised_by_name="A. Q.", status="closed")
    refused = api("coordinator").post(API)
    assert refused.status_code == 409
    assert refused.json()["detail"] == (
        f"Comparison {CODE} cannot go from closed to published; allowed next status: "
        "analysed, open."
    )
    signed_in(client, "coordinator")
    response = client.post(C + "publish/", follow=True)
    assert response.redirect_chain == [(C, 302)]
    assert "cannot go from closed to published" in response.content.decode()
    assert not Publication.objects.exists()


def test_the_round_moved_or_analysed_again_meanwhile_fails_the_job(
    run, demo, stand_in, monkeypatch, django_capture_on_commit_callbacks
):
    # closed again before the task ran
    job = publication_start(comparison=demo)  # its task not run: callbacks not executed
    comparison_transition(comparison=demo, to="closed")
    assert publication_execute(publication_id=job.pk, delivery="t1") == "failed"
    job.refresh_from_db()
    assert job.error == f"{CODE} is closed, no longer analysed: nothing was published."
    assert stand_in == []  # checked before rendering

    # a newer run became current while the reports rendered
    with django_capture_on_commit_callbacks(execute=True):
        newer = analysis_run_start(comparison=demo, user=None)
    newer.refresh_from_db()
    assert newer.status == "succeeded"
    older = Publication.objects.create(comparison=demo, run=run)
    assert publication_execute(publication_id=older.pk, delivery="t2") == "failed"
    older.refresh_from_db()
    assert older.error == (
        f"Analysis run {newer.pk} of {CODE} became the current one after publication of run "
        f"{run.pk} was asked for: nothing was published. Publish again to publish the "
        "current results."
    )

    # closed while the reports rendered: found in the publication's transaction
    def close_on_the_third(data):
        if len(stand_in) == 3:
            Comparison.objects.filter(pk=demo.pk).update(status="closed")
        stand_in.append(data.own_code)
        return b"%PDF-1.4 stand-in"

    monkeypatch.setattr("analysis.reports.services.render_report", close_on_the_third)
    stand_in.clear()
    job = publication_start(comparison=demo)
    assert publication_execute(publication_id=job.pk, delivery="t3") == "failed"
    job.refresh_from_db()
    assert job.error == f"{CODE} is closed, no longer analysed: nothing was published."
    assert len(stand_in) == 13  # every report rendered, then refused
    demo.refresh_from_db()
    assert demo.status == "closed"
    assert not Report.objects.exists() and not Notice.objects.filter(kind="published").exists()


def test_a_lost_job_is_sent_again_by_the_sweep(run, demo, stand_in):
    job = publication_start(comparison=demo)  # its message lost: never run
    long_ago = timezone.now() - dt.timedelta(hours=2)
    Publication.objects.filter(pk=job.pk).update(created_at=long_ago)
    assert jobs_sweep_task()["publications"] == 1  # eager: run at once
    job.refresh_from_db()
    assert (job.status, job.attempts) == ("succeeded", 1)
    assert job.claimed_by  # the task the sweep sent
    demo.refresh_from_db()
    assert demo.status == "published"
    assert jobs_sweep_task()["publications"] == 0


def test_the_job_is_the_rounds_coordinators_only(client, run, demo):
    job = publication_start(comparison=demo)
    page, partial = f"{C}publication/{job.pk}/", f"{C}publication/{job.pk}/progress/"
    signed_in(client, "coordinator")
    assert client.get(page).status_code == 200 and client.get(partial).status_code == 200
    other = UserFactory.create()
    ComparisonFactory.create(code="OTHER-01").coordinators.add(other)
    theirs = Publication.objects.create(
        comparison=Comparison.objects.get(code="OTHER-01"), run=run
    )  # another round's job, not reachable under this round's code
    client.force_login(other)
    for url in (page, partial, f"{C}publication/{theirs.pk}/"):
        assert client.get(url).status_code == 404, url
    signed_in(client, "coordinator")
    assert client.get(f"{C}publication/{theirs.pk}/").status_code == 404
    for username in ("lab03",):
        signed_in(client, username)
        assert client.get(page).status_code == 404 and client.get(partial).status_code == 404
    detail = f"/api/v1/publications/{job.pk}/"
    assert api("lab03").get(detail).status_code == 404
    outsider = APIClient()
    outsider.force_authenticate(other)
    assert outsider.get(detail).status_code == 404


def test_the_api_answers_the_job(run, demo, stand_in, django_capture_on_commit_callbacks):
    with django_capture_on_commit_callbacks(execute=True):
        response = api("coordinator").post(API)
    assert response.status_code == 202
    body = response.json()
    job = Publication.objects.get()
    assert set(body) == {"code", "status", "submission_deadline", "publication"}
    # answered before the commit's callbacks ran the task (this test's transaction)
    assert (body["code"], body["status"], body["publication"]["status"]) == (
        CODE, "analysed", "pending",
    )  # fmt: skip
    assert set(body["publication"]) == {
        "id", "url", "comparison", "run", "status", "progress", "stage", "error",
        "report_ids", "created_at", "started_at", "finished_at",
    }  # fmt: skip
    url = f"http://testserver/api/v1/publications/{job.pk}/"
    assert body["publication"]["url"] == url
    detail = api("coordinator").get(url)
    assert detail.status_code == 200
    assert {k: v for k, v in detail.json().items() if k in ("id", "url", "created_at")} == {
        k: body["publication"][k] for k in ("id", "url", "created_at")
    }
    assert (detail.json()["status"], detail.json()["progress"], detail.json()["run"]) == (
        "succeeded", 100, run.pk,
    )  # fmt: skip
    assert sorted(detail.json()["report_ids"]) == sorted(
        Report.objects.values_list("pk", flat=True)
    )
