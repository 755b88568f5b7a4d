"""Review at round scale: "accept all complete" (page, confirmation, POST, API), the review
list's filters and counts, and the next and previous links of a submission's page."""

from __future__ import annotations

import re

import pytest
from django.contrib.auth import get_user_model
from django.core import mail
from rest_framework.test import APIClient

from labs.models import Notice, Participant, Submission
from labs.review import submission_request_check
from proficiency.models import Comparison
from tests.factories import ComparisonFactory, UserFactory

CODE = "IMU-2024-DEMO"
C = f"/coordinator/{CODE}/"
CONFIRM = f"{C}confirm/accept-complete/"
ACCEPT = f"{C}review/accept-complete/"
API = f"/api/v1/comparisons/{CODE}/submissions/accept-complete/"


def user(name):
    return get_user_model().objects.get(username=name)


def code_of(demo: Comparison, lab: str) -> str:
    return Participant.objects.get(comparison=demo, laboratory__name__startswith=lab).code


@pytest.fixture
def other_coordinator(demo):
    other = UserFactory.create(username="other-coordinator")
    ComparisonFactory.create(code="IMU-OTHER").coordinators.add(other)
    return other


@pytest.fixture
def waiting(demo) -> dict[str, str]:
    """Every demo submission back to submitted, then three that must not be accepted:
    Baltic's lacks a result, Castile's was asked to check one, Danube has a newer draft.
    The two bench laboratories report their own bench only (complete for their scope)."""
    Submission.objects.filter(participant__comparison=demo).update(
        status=Submission.Status.SUBMITTED, decided_at=None
    )
    incomplete = Participant.objects.get(comparison=demo, laboratory__name__startswith="Baltic")
    incomplete.submissions.get().results.order_by("pk")[0].delete()
    checked = Participant.objects.get(comparison=demo, laboratory__name__startswith="Castile")
    submission_request_check(result=checked.submissions.get().results.order_by("pk")[0], user=None)
    drafted = Participant.objects.get(comparison=demo, laboratory__name__startswith="Danube")
    Submission.objects.create(participant=drafted, version=2, status=Submission.Status.DRAFT)
    return {"incomplete": incomplete.code, "checked": checked.code, "drafted": drafted.code}


def acceptable_codes(demo, waiting) -> list[str]:
    excluded = set(waiting.values())
    return sorted(p.code for p in demo.participants.all() if p.code not in excluded)


def cells(page: str) -> list[str]:
    return [re.sub(r"<[^>]+>", "", c).strip() for c in re.findall(r"<td[^>]*>(.*?)</td>", page)]


def test_review_page_counts_the_complete_submissions_and_confirmation_lists_them(
    client, demo, waiting
):
    client.force_login(user("coordinator"))
    codes = acceptable_codes(demo, waiting)
    assert len(codes) == 9
    page = client.get(f"{C}review/").content.decode()
    assert f'href="{CONFIRM}">Accept 9 complete submissions…</a>' in page
    assert "asked to check" in page
    confirm = client.get(CONFIRM)
    assert confirm.status_code == 200
    text = confirm.content.decode()
    assert f"Accepted: {', '.join(codes)}:" in text
    assert "9 laboratories are e-mailed that their submission is accepted" in text
    assert f'action="{ACCEPT}"' in text
    assert f'name="expected" value="{",".join(codes)}"' in text
    for code in waiting.values():
        assert code not in text.split("Accepted:")[1].split(":")[0]
    # the cancel button goes back to the review list
    assert f'href="{C}review/">Cancel</a>' in text


def test_accept_all_complete_accepts_exactly_those_with_one_notice_each(
    client, demo, waiting, django_capture_on_commit_callbacks
):
    client.force_login(user("coordinator"))
    codes = acceptable_codes(demo, waiting)
    before = Notice.objects.filter(kind=Notice.Kind.ACCEPTED).count()
    mail.outbox.clear()
    with django_capture_on_commit_callbacks(execute=True):
        response = client.post(ACCEPT, {"expected": ",".join(codes)})
    assert response.status_code == 302 and response["Location"] == f"{C}review/"
    accepted = Submission.objects.filter(
        participant__comparison=demo, status=Submission.Status.ACCEPTED
    )
    assert sorted(s.participant.code for s in accepted) == codes
    assert all(s.decided_at is not None for s in accepted)
    for key in ("incomplete", "checked"):
        kept = Submission.objects.get(participant__code=waiting[key], participant__comparison=demo)
        assert kept.status == "submitted"
    drafted = Submission.objects.filter(participant__code=waiting["drafted"],
                                        participant__comparison=demo)  # fmt: skip
    assert sorted(drafted.values_list("version", "status")) == [(1, "submitted"), (2, "draft")]
    notices = Notice.objects.filter(kind=Notice.Kind.ACCEPTED)
    assert notices.count() == before + 9
    assert sorted(n.participant.code for n in notices if n.participant) == codes
    assert len(mail.outbox) == 9
    shown = client.get(response["Location"]).content.decode()
    assert f"Accepted 9 submissions: {', '.join(codes)}." in shown
    assert "The list changed" not in shown
    # nothing is waiting any more: no button, and a second POST accepts nothing, e-mails no one
    assert "complete submission" not in shown.split("Review submissions")[1].split("<table")[0]
    mail.outbox.clear()
    with django_capture_on_commit_callbacks(execute=True):
        again = client.post(ACCEPT, {"expected": ""}, follow=True)
    assert "nothing was accepted" in again.content.decode()
    assert Notice.objects.filter(kind=Notice.Kind.ACCEPTED).count() == before + 9
    assert mail.outbox == []


def test_accept_all_complete_takes_the_set_of_the_moment_and_says_what_changed(
    client, demo, waiting
):
    client.force_login(user("coordinator"))
    codes = acceptable_codes(demo, waiting)
    client.get(CONFIRM)
    # after the confirmation page: Elbe saves a new draft (its submitted version is no longer
    # its latest), and Baltic's missing result is back (it becomes complete)
    elbe = code_of(demo, "Elbe")
    Submission.objects.create(participant=demo.participants.get(code=elbe), version=2,
                              status=Submission.Status.DRAFT)  # fmt: skip
    baltic = demo.participants.get(code=waiting["incomplete"])
    other = demo.participants.get(code=code_of(demo, "Fjord")).submissions.get()
    missing = other.results.exclude(
        measurement_point__in=baltic.submissions.get().results.values("measurement_point")
    ).get()
    missing.pk, missing.submission = None, baltic.submissions.get()
    missing.save()
    response = client.post(ACCEPT, {"expected": ",".join(codes)}, follow=True)
    assert response.status_code == 200
    now = sorted({*codes, baltic.code} - {elbe})
    accepted = Submission.objects.filter(participant__comparison=demo, status="accepted")
    assert sorted(s.participant.code for s in accepted) == now
    text = response.content.decode()
    assert f"Accepted 9 submissions: {', '.join(now)}." in text
    assert f"{baltic.code} was accepted too (complete and waiting since then)" in text
    assert f"{elbe} was not accepted: no longer complete and waiting" in text


def test_complete_means_the_participants_own_scope(client, demo, waiting):
    """The bench laboratories report their bench's points only: complete; once a bench
    laboratory's scope is widened to every point, its version lacks the other bench."""
    client.force_login(user("coordinator"))
    linear = demo.participants.get(laboratory__name__startswith="Linear")
    assert linear.code in acceptable_codes(demo, waiting)
    page = client.get(f"{C}review/?status=submitted&complete=complete").content.decode()
    assert linear.code in page and "(scope: bench linear)" in page
    Participant.objects.filter(pk=linear.pk).update(scope_benches=[])
    page = client.get(f"{C}review/?complete=incomplete").content.decode()
    assert f"<code>{linear.code}</code>" in page
    client.post(ACCEPT, {"expected": ""})
    assert linear.submissions.get().status == "submitted"


@pytest.mark.parametrize("persona", ["other", "lab03", "lab03-manager"])
def test_accept_all_complete_is_404_for_anyone_but_the_rounds_coordinator(
    client, demo, waiting, other_coordinator, persona
):
    client.force_login(other_coordinator if persona == "other" else user(persona))
    assert client.get(CONFIRM).status_code == 404
    assert client.post(ACCEPT, {"expected": ""}).status_code == 404
    assert client.get(ACCEPT).status_code == 405
    assert not Submission.objects.filter(participant__comparison=demo, status="accepted").exists()


def test_accept_all_complete_by_the_api(demo, waiting, other_coordinator):
    api = APIClient()
    api.force_authenticate(other_coordinator)
    assert api.post(API).status_code == 404
    api.force_authenticate(user("lab03"))
    assert api.post(API).status_code == 403
    assert not Submission.objects.filter(participant__comparison=demo, status="accepted").exists()
    api.force_authenticate(user("coordinator"))
    response = api.post(API)
    assert response.status_code == 200
    codes = acceptable_codes(demo, waiting)
    assert response.json() == {"accepted": codes, "count": 9}
    accepted = Submission.objects.filter(participant__comparison=demo, status="accepted")
    assert sorted(s.participant.code for s in accepted) == codes
    assert api.post(API).json() == {"accepted": [], "count": 0}


def test_review_filters_with_their_counts(client, demo, waiting):
    client.force_login(user("coordinator"))
    page = client.get(f"{C}review/").content.decode()
    # 11 latest versions submitted (one of them incomplete), one draft (Danube's v2, empty)
    assert '<option value="submitted">Submitted (11)</option>' in page
    assert '<option value="draft">Draft (1)</option>' in page
    assert '<option value="accepted">Accepted (0)</option>' in page
    assert '<option value="none">No submission (0)</option>' in page
    assert '<option value="complete">Complete (10)</option>' in page
    assert '<option value="incomplete">Incomplete (2)</option>' in page
    chosen = client.get(f"{C}review/?status=submitted&complete=incomplete").content.decode()
    rows = re.findall(r'<td data-label="Code"><code>(L\d+)</code>', chosen)
    assert rows == [waiting["incomplete"]]
    assert "1 of 12 participants shown." in chosen
    # each choice counted with the other filter applied
    assert '<option value="submitted" selected>Submitted (1)</option>' in chosen
    assert '<option value="draft">Draft (1)</option>' in chosen
    assert '<option value="incomplete" selected>Incomplete (1)</option>' in chosen
    drafts = client.get(f"{C}review/?status=draft").content.decode()
    assert re.findall(r'<td data-label="Code"><code>(L\d+)</code>', drafts) == [waiting["drafted"]]
    # a value that is not offered is ignored
    bad = client.get(f"{C}review/?status=withdrawn&complete=complete")
    assert bad.status_code == 200
    assert len(re.findall(r'<td data-label="Code">', bad.content.decode())) == 10
    none = client.get(f"{C}review/?status=none").content.decode()
    assert "No participant matches these filters." in none


def test_next_and_previous_follow_the_filtered_list(client, demo, waiting):
    client.force_login(user("coordinator"))
    query = "status=submitted&complete=complete"
    page = client.get(f"{C}review/?{query}").content.decode()
    links = re.findall(rf'href="{C}review/(L\d+)/v(\d+)/\?status=submitted&amp;complete=complete"',
                       page)  # fmt: skip
    assert len(links) == 10
    (first, v1), (second, v2), (third, v3) = links[:3]
    middle = client.get(f"{C}review/{second}/v{v2}/?{query}").content.decode()
    q = "?status=submitted&amp;complete=complete"
    assert f'<a rel="prev" href="{C}review/{first}/v{v1}/{q}">' in middle
    assert f'<a rel="next" href="{C}review/{third}/v{v3}/{q}">' in middle
    assert f'href="{C}review/{q}">Review list (2 of 10)</a>' in middle
    top = client.get(f"{C}review/{first}/v{v1}/?{query}").content.decode()
    assert 'rel="prev"' not in top and 'rel="next"' in top
    last_code, last_v = links[-1]
    bottom = client.get(f"{C}review/{last_code}/v{last_v}/?{query}").content.decode()
    assert 'rel="next"' not in bottom
    # accepting from the page goes back to the list with its filters; the accepted version
    # leaves the filtered list but its page still leads to its neighbours
    done = client.post(f"{C}review/{second}/v{v2}/?{query}", {"decision": "accept"})
    assert done.status_code == 302
    assert done["Location"] == f"{C}review/?{query}"
    after = client.get(f"{C}review/{second}/v{v2}/?{query}").content.decode()
    assert f'<a rel="prev" href="{C}review/{first}/v{v1}/{q}">' in after
    assert f'<a rel="next" href="{C}review/{third}/v{v3}/{q}">' in after
    # without filters the links walk every participant with a version
    plain = client.get(f"{C}review/{first}/v{v1}/").content.decode()
    assert re.search(rf'<a rel="next" href="{C}review/L\d+/v\d+/">', plain)
