"""Notices (docs/lifecycles.md §6): each event makes one notice and one e-mail to the
addressed laboratory's members, with an absolute link that only the addressee can open."""

import datetime as dt
from urllib.parse import urlsplit

import pytest
from django.core import mail
from django.core.mail import EmailMultiAlternatives
from django.utils import timezone

from labs.models import Notice, Submission
from labs.notices import notice_email_send, notify
from labs.review import submission_decide, submission_request_check
from labs.services import comparison_move, participants_invite, submission_from_records
from proficiency.services import measurement_points_generate
from tests.factories import (
    ComparisonFactory,
    DeviceFactory,
    LaboratoryFactory,
    MembershipFactory,
    ParticipantFactory,
    UserFactory,
)

pytestmark = pytest.mark.django_db

SITE = "http://pt.example.org"


@pytest.fixture(autouse=True)
def site_url(settings):
    settings.SITE_URL = SITE


@pytest.fixture
def world():
    comparison = ComparisonFactory.create(code="IMU-N1", title="Notices round")
    device = DeviceFactory.create(comparison=comparison, name="MEMS 1")
    measurement_points_generate(
        comparison=comparison, devices=[device], axes=["X", "Y"], frequencies_hz=[5, 10],
        benches=["linear"],
    )  # fmt: skip
    lab_a = LaboratoryFactory.create(name="Alpha Lab")
    lab_b = LaboratoryFactory.create(name="Beta Lab")
    a1 = MembershipFactory.create(laboratory=lab_a, user=UserFactory.create(username="a1")).user
    MembershipFactory.create(laboratory=lab_a, user=UserFactory.create(username="a2"))
    b1 = MembershipFactory.create(laboratory=lab_b, user=UserFactory.create(username="b1")).user
    lab_c = LaboratoryFactory.create(name="Gamma Lab")  # takes part in nothing
    c1 = MembershipFactory.create(laboratory=lab_c, user=UserFactory.create(username="c1")).user
    coordinator = UserFactory.create(username="coord")
    comparison.coordinators.add(coordinator)
    return {"comparison": comparison, "lab_a": lab_a, "lab_b": lab_b, "a1": a1, "b1": b1, "c1": c1,
            "coordinator": coordinator}  # fmt: skip


def rows(value=420.0):
    return [
        {"device": "MEMS 1", "axis": a, "frequency_hz": f, "bench": "linear",
         "sensitivity": value, "expanded_uncertainty": 8.4}
        for a in ("X", "Y") for f in (5, 10)
    ]  # fmt: skip


def the_link(message):
    """The absolute link of the e-mail's text part, checked to start with SITE_URL."""
    (line,) = [x for x in message.body.splitlines() if x.startswith("Open: ")]
    url = line.removeprefix("Open: ")
    assert url.startswith(SITE + "/")
    return urlsplit(url).path


def assert_link_only_for_addressee(client, world, path, addressee="a1", others=("b1", "c1")):
    client.force_login(world[addressee])
    assert client.get(path).status_code == 200
    for other in others:
        client.force_login(world[other])
        assert client.get(path).status_code == 404
    client.logout()
    anonymous = client.get(path)
    assert anonymous.status_code == 302 and anonymous["Location"].startswith("/accounts/login/")


def one_email(notice):
    """The one e-mail sent, to the members of the notice's laboratory, text and HTML."""
    (message,) = mail.outbox
    assert message.to == ["a1@example.org", "a2@example.org"]
    assert message.subject == notice.subject
    assert notice.body in message.body
    assert isinstance(message, EmailMultiAlternatives)
    ((html, mimetype),) = message.alternatives
    assert mimetype == "text/html" and f'href="{SITE}{notice.link}"' in str(html)
    notice.refresh_from_db()
    assert notice.emailed_at is not None
    assert notice.emailed_to == "a1@example.org, a2@example.org"
    return message


def test_invitation(client, world, django_capture_on_commit_callbacks):
    comparison = world["comparison"]
    with django_capture_on_commit_callbacks(execute=True):
        (participant,) = participants_invite(comparison=comparison, laboratories=[world["lab_a"]])
    notice = Notice.objects.get()
    assert (notice.kind, notice.laboratory, notice.participant) == (
        "invitation", world["lab_a"], participant
    )  # fmt: skip
    assert notice.subject == "[IMU-N1] invitation to take part"
    assert f"Your participant code is {participant.code}" in notice.body
    message = one_email(notice)
    path = the_link(message)
    assert path == "/lab/comparisons/IMU-N1/" == notice.link
    assert_link_only_for_addressee(client, world, path)
    # inviting again changes nothing: no second notice, no second e-mail
    with django_capture_on_commit_callbacks(execute=True):
        participants_invite(comparison=comparison, laboratories=[world["lab_a"]])
    assert Notice.objects.count() == 1 and len(mail.outbox) == 1


def test_round_opened_tells_every_participant_once(
    client, world, django_capture_on_commit_callbacks
):
    comparison = world["comparison"]
    comparison.submission_deadline = timezone.now() + dt.timedelta(days=30)
    comparison.save()
    ParticipantFactory.create(comparison=comparison, laboratory=world["lab_a"], code="L11")
    ParticipantFactory.create(comparison=comparison, laboratory=world["lab_b"], code="L22")
    with django_capture_on_commit_callbacks(execute=True):
        comparison_move(comparison=comparison, to="open")
    assert sorted(Notice.objects.values_list("kind", "laboratory__name", "participant__code")) == [
        ("opened", "Alpha Lab", "L11"), ("opened", "Beta Lab", "L22")
    ]  # fmt: skip
    assert sorted(m.to[0] for m in mail.outbox) == ["a1@example.org", "b1@example.org"]
    notice = Notice.objects.get(laboratory=world["lab_a"])
    assert notice.subject == "[IMU-N1] open for submissions"
    assert "Submission deadline: " in notice.body
    message = next(m for m in mail.outbox if m.to[0] == "a1@example.org")
    assert_link_only_for_addressee(client, world, the_link(message), others=("c1",))
    # closed and reopened with the same deadline: not told again
    with django_capture_on_commit_callbacks(execute=True):
        comparison_move(comparison=comparison, to="closed")
        comparison_move(comparison=comparison, to="open")
    assert Notice.objects.count() == 2 and len(mail.outbox) == 2


def test_submission_receipt_says_what_was_stored(client, world, django_capture_on_commit_callbacks):
    comparison = world["comparison"]
    comparison.status = "open"
    comparison.save()
    participant = ParticipantFactory.create(comparison=comparison, laboratory=world["lab_a"])
    # a draft is no submission: no receipt
    with django_capture_on_commit_callbacks(execute=True):
        submission_from_records(participant=participant, records=rows()[:2], source="web",
                                user=world["a1"], submit=False)  # fmt: skip
    assert Notice.objects.count() == 0 and mail.outbox == []
    with django_capture_on_commit_callbacks(execute=True):
        sub = submission_from_records(participant=participant, records=rows(), source="api",
                                      user=world["a1"], submit=True)  # fmt: skip
    notice = Notice.objects.get()
    assert (notice.kind, notice.participant) == ("receipt", participant)
    assert notice.subject == "[IMU-N1] receipt: submission version 1"
    assert "Version: 1\n" in notice.body
    assert "Results stored: 4\n" in notice.body
    assert len(sub.content_sha256) == 64
    assert f"SHA-256 checksum of the stored results: {sub.content_sha256}" in notice.body
    assert "(REST API) by a1" in notice.body
    message = one_email(notice)
    path = the_link(message)
    assert path == "/lab/comparisons/IMU-N1/submissions/1/"
    assert_link_only_for_addressee(client, world, path)
    # the same request again is answered with the stored version: no second receipt
    with django_capture_on_commit_callbacks(execute=True):
        again = submission_from_records(participant=participant, records=rows(), source="api",
                                        user=world["a1"], submit=True)  # fmt: skip
    assert again.pk == sub.pk and Notice.objects.count() == 1 and len(mail.outbox) == 1


@pytest.fixture
def submitted(world):
    comparison = world["comparison"]
    comparison.status = "open"
    comparison.save()
    participant = ParticipantFactory.create(comparison=comparison, laboratory=world["lab_a"])
    submission_from_records(participant=participant, records=rows(), source="web",
                            user=world["a1"], submit=True)  # fmt: skip
    Notice.objects.all().delete()  # the receipt (its e-mail was never sent: no commit)
    return Submission.objects.get(participant=participant)


def test_acceptance_has_a_link(client, world, submitted, django_capture_on_commit_callbacks):
    with django_capture_on_commit_callbacks(execute=True):
        submission_decide(submission=submitted, decision="accept", message="",
                          user=world["coordinator"])  # fmt: skip
    notice = Notice.objects.get()
    assert notice.kind == "accepted"
    assert notice.subject == "[IMU-N1] submission version 1 accepted"
    assert notice.body.startswith("Your submission version 1 was accepted.")
    message = one_email(notice)
    assert_link_only_for_addressee(client, world, the_link(message))


def test_rejection_carries_the_reason(client, world, submitted, django_capture_on_commit_callbacks):
    with django_capture_on_commit_callbacks(execute=True):
        submission_decide(submission=submitted, decision="reject",
                          message="Units look like mV/g, not mV/(m/s²).",
                          user=world["coordinator"])  # fmt: skip
    notice = Notice.objects.get()
    assert notice.kind == "rejected"
    assert notice.subject == "[IMU-N1] submission version 1 rejected"
    assert "The coordinator's reason:\nUnits look like mV/g, not mV/(m/s²)." in notice.body
    message = one_email(notice)
    assert "Units look like mV/g, not mV/(m/s²)." in message.body
    path = the_link(message)
    assert path == "/lab/comparisons/IMU-N1/submissions/1/"
    assert_link_only_for_addressee(client, world, path)


def test_check_request_in_inbox_and_mail(
    client, world, submitted, django_capture_on_commit_callbacks
):
    result = submitted.results.select_related("measurement_point__device").get(
        measurement_point__axis="Y", measurement_point__frequency_hz=10
    )
    with django_capture_on_commit_callbacks(execute=True):
        submission_request_check(result=result, user=world["coordinator"])
    notice = Notice.objects.get()
    assert notice.kind == "check" and notice.subject == "[IMU-N1] please check a result"
    assert "Please check your result for MEMS 1, Y, 10 Hz, linear vertical" in notice.body
    message = one_email(notice)
    for leak in (str(result.value), "%", "deviation"):
        assert leak not in message.body
    assert_link_only_for_addressee(client, world, the_link(message))
    # asked twice about the same result: one notice
    with django_capture_on_commit_callbacks(execute=True):
        submission_request_check(result=result, user=world["coordinator"])
    assert Notice.objects.count() == 1 and len(mail.outbox) == 1


def test_notify_is_idempotent_and_the_email_goes_once(world, django_capture_on_commit_callbacks):
    participant = ParticipantFactory.create(
        comparison=world["comparison"], laboratory=world["lab_a"]
    )
    with django_capture_on_commit_callbacks(execute=True):
        first = notify(kind="invitation", participant=participant, dedupe_key="k1", link="/lab/")
        second = notify(kind="invitation", participant=participant, dedupe_key="k1", link="/lab/")
    assert first is not None and second is None
    assert Notice.objects.count() == 1 and len(mail.outbox) == 1
    # the task delivered again finds the notice sent and sends nothing
    assert notice_email_send(notice_id=first.pk) is False
    assert len(mail.outbox) == 1


def test_email_is_released_when_sending_fails(world, settings, monkeypatch):
    participant = ParticipantFactory.create(
        comparison=world["comparison"], laboratory=world["lab_a"]
    )
    notice = notify(kind="invitation", participant=participant, dedupe_key="k2", link="/lab/")
    assert notice is not None

    def broken(self, fail_silently=False):
        raise OSError("mail server down")

    monkeypatch.setattr("django.core.mail.EmailMultiAlternatives.send", broken)
    with pytest.raises(OSError):
        notice_email_send(notice_id=notice.pk)
    notice.refresh_from_db()
    assert (notice.emailed_at, notice.emailed_to) == (None, "")
    monkeypatch.undo()
    assert notice_email_send(notice_id=notice.pk) is True
    assert len(mail.outbox) == 1


def test_a_laboratory_without_addresses_gets_the_notice_only(
    world, django_capture_on_commit_callbacks
):
    lonely = LaboratoryFactory.create(name="No Mail Lab")
    participant = ParticipantFactory.create(comparison=world["comparison"], laboratory=lonely)
    with django_capture_on_commit_callbacks(execute=True):
        notice = notify(kind="invitation", participant=participant, dedupe_key="k3", link="/lab/")
    assert notice is not None and mail.outbox == []
    notice.refresh_from_db()
    assert notice.emailed_at is None


# --- the inbox and the coordinator's list --------------------------------------------------


@pytest.fixture
def inbox(world):
    participant = ParticipantFactory.create(
        comparison=world["comparison"], laboratory=world["lab_a"], code="L07"
    )
    old = notify(kind="invitation", participant=participant, dedupe_key="i1",
                 link="/lab/comparisons/IMU-N1/")  # fmt: skip
    new = notify(kind="opened", participant=participant, dedupe_key="i2",
                 link="/lab/comparisons/IMU-N1/")  # fmt: skip
    assert old is not None and new is not None
    Notice.objects.filter(pk=old.pk).update(created_at=timezone.now() - dt.timedelta(hours=1))
    return old, new


def test_inbox_lists_newest_first_with_unread_marked(client, world, inbox):
    _, new = inbox
    client.force_login(world["a1"])
    page = client.get("/lab/").content.decode()
    assert page.index("[IMU-N1] open for submissions") < page.index(
        "[IMU-N1] invitation to take part"
    )
    assert page.count('<span class="badge text-bg-warning me-1">Unread</span>') == 2
    assert 'title="Unread notices">2<' in page  # the navigation badge
    assert f'href="/lab/comparisons/IMU-N1/">{new.subject}</a>' in page
    assert "Your participant code is L07" in page  # the body, under "Message"
    # another laboratory sees none of them, nor a badge
    client.force_login(world["b1"])
    other = client.get("/lab/").content.decode()
    assert "IMU-N1" not in other and "Unread notices" not in other


def test_mark_read(client, world, inbox):
    old, new = inbox
    client.force_login(world["b1"])
    assert client.post(f"/lab/notices/{new.pk}/read/").status_code == 404
    new.refresh_from_db()
    assert new.read_at is None
    client.force_login(world["a1"])
    assert client.get(f"/lab/notices/{new.pk}/read/").status_code == 405
    response = client.post(f"/lab/notices/{new.pk}/read/")
    assert response.status_code == 302 and response["Location"] == "/lab/"
    new.refresh_from_db()
    first_read = new.read_at
    assert first_read is not None
    page = client.get("/lab/").content.decode()
    assert page.count('<span class="badge text-bg-warning me-1">Unread</span>') == 1
    assert 'title="Unread notices">1<' in page
    client.post(f"/lab/notices/{new.pk}/read/")  # again: the first time is kept
    new.refresh_from_db()
    assert new.read_at == first_read
    assert client.post("/lab/notices/read/").status_code == 302
    assert Notice.objects.filter(read_at__isnull=True).count() == 0
    assert "Unread notices" not in client.get("/lab/").content.decode()
    client.logout()
    anonymous = client.post(f"/lab/notices/{old.pk}/read/")
    assert anonymous.status_code == 302 and anonymous["Location"].startswith("/accounts/login/")


def test_a_rejection_reason_is_on_the_dashboard(client, world, submitted):
    submission_decide(submission=submitted, decision="reject", message="Units look like mV/g.",
                      user=world["coordinator"])  # fmt: skip
    client.force_login(world["a1"])
    page = client.get("/lab/").content.decode()
    assert "[IMU-N1] submission version 1 rejected" in page
    assert "Units look like mV/g." in page


def test_coordinator_sees_what_was_sent_to_whom(client, world, inbox):
    old, _ = inbox
    notice_email_send(notice_id=old.pk)
    client.force_login(world["coordinator"])
    page = client.get("/coordinator/IMU-N1/").content.decode()
    assert 'Notices <span class="badge text-bg-light border">2</span>' in page
    assert page.index("Round opened") < page.index("Invitation")
    assert page.count("<code>L07</code>") >= 2 and "Alpha Lab" in page
    assert page.count(">yes</span>") == 1 and page.count("not e-mailed") == 1
    # a laboratory's member is no coordinator: 404
    client.force_login(world["a1"])
    assert client.get("/coordinator/IMU-N1/").status_code == 404


def test_a_provider_edits_the_notices_in_its_own_templates_folder(tmp_path):
    """PROVIDER_TEMPLATES_DIR holds the provider's copies of templates/notices/: they are
    found before the shipped ones, the others stay as shipped (settings read at start-up,
    hence a process of its own)."""
    import os
    import subprocess
    import sys
    from pathlib import Path

    edited = tmp_path / "notices"
    edited.mkdir()
    (edited / "invitation_subject.txt").write_text("Einladung: {{ comparison.code }}\n")
    show = (
        "from django.template.loader import render_to_string as r; "
        "print(r('notices/invitation_subject.txt', {'comparison': {'code': 'IMU-N1'}}).strip()); "
        "print(r('notices/receipt_subject.txt', {'comparison': {'code': 'IMU-N1'}}).strip())"
    )
    root = Path(__file__).resolve().parents[2]
    for folder, first in ((str(tmp_path), "Einladung: IMU-N1"), ("", None)):
        env = os.environ | {"PROVIDER_TEMPLATES_DIR": folder}
        result = subprocess.run(
            [sys.executable, "manage.py", "shell", "-c", show],
            cwd=root, env=env, capture_output=True, text=True, check=True,
        )  # fmt: skip
        invitation, receipt = result.stdout.strip().splitlines()[-2:]
        assert (invitation == first) if first else ("Einladung" not in invitation)
        assert "IMU-N1" in receipt and "Einladung" not in receipt
