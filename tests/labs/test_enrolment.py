"""Enrolment (docs/lifecycles.md §7): a round with an open call, laboratories applying with
a scope through the web page and the API, the coordinator accepting (the laboratory is
invited with a random code, the scope and the invitation notice) or declining (a notice with
the reason); closed calls, duplicates and participants are 409 with nothing stored, a scope
that does not fit is 400 naming the field, and nobody sees another laboratory's
application or another round's."""

import datetime as dt
import threading

import pytest
from django.core import mail
from django.core.mail import EmailMultiAlternatives
from django.db import connection
from django.test import Client
from django.test.utils import CaptureQueriesContext
from django.urls import reverse
from django.utils import timezone
from rest_framework.test import APIClient

from common.errors import StateConflict, ValidationFailed
from labs import enrolment as enrolment_module
from labs.enrolment import enrolment_accept, enrolment_apply, enrolment_decline
from labs.models import Enrolment, Membership, Notice, Participant
from labs.selectors import participant_points, scope_text
from labs.services import Scope, api_key_create, participants_invite
from proficiency.models import Comparison
from proficiency.selectors import open_calls
from proficiency.services import enrolment_check, measurement_points_generate
from tests.factories import (
    ComparisonFactory,
    DeviceFactory,
    LaboratoryFactory,
    MembershipFactory,
    UserFactory,
)
from tests.labs.test_web import visible

pytestmark = pytest.mark.django_db

CODE = "IMU-CALL"
API = f"/api/v1/comparisons/{CODE}/applications/"
Es = Enrolment.Status


class Call:
    """A draft round taking applications: MEMS 1 and MEMS 2, axis X at 5 and 10 Hz on the
    linear and curvilinear benches (8 points). ``lab`` has a manager and a staff member;
    ``other`` is a second laboratory with its own manager; ``coordinator`` coordinates the
    round and ``stranger`` another one."""

    def __init__(self) -> None:
        now = timezone.now()
        self.comparison = ComparisonFactory.create(
            code=CODE, status="draft", enrolment_open=True,
            enrolment_closes=now + dt.timedelta(days=10),
            submission_deadline=now + dt.timedelta(days=60),
        )  # fmt: skip
        self.coordinator = UserFactory.create(username="coord-call")
        self.comparison.coordinators.add(self.coordinator)
        self.stranger = UserFactory.create(username="coord-other")
        ComparisonFactory.create(code="IMU-ELSEWHERE").coordinators.add(self.stranger)
        self.mems1 = DeviceFactory.create(comparison=self.comparison, name="MEMS 1")
        self.mems2 = DeviceFactory.create(comparison=self.comparison, name="MEMS 2")
        for bench, direction in (("linear", "vertical"), ("curvilinear", "tangential")):
            measurement_points_generate(
                comparison=self.comparison, devices=[self.mems1, self.mems2], axes=["X"],
                frequencies_hz=[5, 10], benches=[bench], directions=[direction],
            )  # fmt: skip
        self.lab = LaboratoryFactory.create(name="Applicant Vibration Lab")
        self.manager = MembershipFactory.create(
            laboratory=self.lab, role=Membership.Role.MANAGER, user__username="lab-manager"
        ).user
        self.staff = MembershipFactory.create(laboratory=self.lab, user__username="lab-staff").user
        self.other = LaboratoryFactory.create(name="Other Inertial Lab")
        self.other_manager = MembershipFactory.create(
            laboratory=self.other, role=Membership.Role.MANAGER, user__username="other-manager"
        ).user

    def apply(self, **kwargs) -> Enrolment:
        kwargs.setdefault("scope", Scope(benches=["linear"]))
        return enrolment_apply(
            comparison=self.comparison, laboratory=kwargs.pop("laboratory", self.lab),
            user=self.manager, **kwargs,
        )  # fmt: skip

    def key(self, lab=None) -> APIClient:
        _, key = api_key_create(laboratory=lab or self.lab, name="bench PC", user=None)
        client = APIClient()
        client.credentials(HTTP_AUTHORIZATION=f"Api-Key {key}")
        return client

    def person(self, user) -> APIClient:
        client = APIClient()
        client.force_authenticate(user)
        return client


@pytest.fixture
def call() -> Call:
    return Call()


def notices(lab, kind):
    return list(Notice.objects.filter(laboratory=lab, kind=kind))


# --- the call ---------------------------------------------------------------------------------


def test_the_open_calls_are_the_rounds_taking_applications_now(call):
    now = timezone.now()
    past = now - dt.timedelta(days=1)
    ComparisonFactory.create(code="NOT-CALLING", status="draft")  # enrolment_open False
    ComparisonFactory.create(code="CLOSES-PAST", enrolment_open=True, enrolment_closes=past)
    ComparisonFactory.create(code="DEADLINE-PAST", enrolment_open=True, submission_deadline=past)
    ComparisonFactory.create(code="ROUND-CLOSED", enrolment_open=True, status="closed")
    ComparisonFactory.create(code="ROUND-OPEN", enrolment_open=True, status="open")
    assert sorted(c.code for c in open_calls()) == [CODE, "ROUND-OPEN"]
    # the per-round check says the same, with its reason
    for comparison in Comparison.objects.exclude(code__in=[CODE, "ROUND-OPEN"]):
        with pytest.raises(StateConflict):
            enrolment_check(comparison)
    enrolment_check(call.comparison)

    body = call.key().get("/api/v1/calls/").json()
    assert [c["code"] for c in body["results"]] == [CODE, "ROUND-OPEN"]
    first = body["results"][0]
    assert first["devices"] == ["MEMS 1", "MEMS 2"]
    assert first["benches"] == ["curvilinear", "linear"]
    assert first["axes"] == ["X"]
    assert first["frequencies_hz"] == [5.0, 10.0]
    assert first["n_measurement_points"] == 8
    assert first["enrolment_closes"] is not None

    page = visible(_signed_in(call.staff).get(reverse("labs:calls")))
    assert CODE in page and "ROUND-OPEN" in page
    for absent in ("NOT-CALLING", "CLOSES-PAST", "DEADLINE-PAST", "ROUND-CLOSED"):
        assert absent not in page


def test_the_comparison_api_reads_the_enrolment_settings(call):
    call.comparison.participants.create(laboratory=call.lab, code="L77")
    body = call.key().get(f"/api/v1/comparisons/{CODE}/").json()
    assert body["enrolment_open"] is True
    assert body["enrolment_closes"] is not None
    assert body["participant_code"] == "L77"  # the keys it had are unchanged


def test_the_coordinator_opens_the_call_on_the_settings_form(call):
    comparison = ComparisonFactory.create(code="IMU-LATER", title="Later round")
    comparison.coordinators.add(call.coordinator)
    client = _signed_in(call.coordinator)
    form = client.get(reverse("coordinator:edit", args=["IMU-LATER"]))
    assert 'name="enrolment_open"' in visible(form)
    response = client.post(
        reverse("coordinator:edit", args=["IMU-LATER"]),
        {"code": "IMU-LATER", "title": "Later round", "assigned_value_method": "reference",
         "sigma_pt_mode": "none", "en_limit": "1", "reminder_days": "7,1",
         "enrolment_open": "on", "enrolment_closes": "2099-01-31T12:00"},
    )  # fmt: skip
    assert response.status_code == 302
    comparison.refresh_from_db()
    assert comparison.enrolment_open is True
    assert comparison.enrolment_closes is not None
    assert comparison.enrolment_closes.year == 2099
    assert "IMU-LATER" in [c.code for c in open_calls()]


# --- applying ---------------------------------------------------------------------------------


def test_applying_stores_a_pending_application_and_sends_a_receipt(
    call, django_capture_on_commit_callbacks
):
    with django_capture_on_commit_callbacks(execute=True):
        application = call.apply(scope=Scope(devices=["MEMS 1"], benches=["linear"]),
                                 note="Linear bench up to 20 Hz")  # fmt: skip
    stored = Enrolment.objects.get()
    assert stored.pk == application.pk
    assert (stored.status, stored.laboratory, stored.applied_by) == (Es.PENDING, call.lab,
                                                                      call.manager)  # fmt: skip
    assert stored.scope_benches == ["linear"]
    assert [d.name for d in stored.scope_devices.all()] == ["MEMS 1"]
    assert stored.note == "Linear bench up to 20 Hz"
    assert not Participant.objects.exists()
    (receipt,) = notices(call.lab, Notice.Kind.APPLIED)
    assert receipt.participant is None
    assert receipt.comparison == call.comparison
    assert receipt.link == reverse("labs:calls")
    assert receipt.subject == f"[{CODE}] application received"
    assert "device MEMS 1; bench linear" in receipt.body
    assert "Linear bench up to 20 Hz" in receipt.body
    (sent,) = mail.outbox
    assert isinstance(sent, EmailMultiAlternatives)
    assert sent.to == ["lab-manager@example.org", "lab-staff@example.org"]
    assert "/lab/calls/" in sent.body
    assert "/lab/calls/" in str(sent.alternatives[0][0])


def test_applying_through_the_web_page_with_checkboxes(call):
    client = _signed_in(call.manager)
    page = visible(client.get(reverse("labs:call_apply", args=[CODE])))
    assert 'type="checkbox"' in page and "<select" not in page
    response = client.post(
        reverse("labs:call_apply", args=[CODE]),
        {"laboratory": call.lab.pk, "devices": [call.mems2.pk], "benches": ["curvilinear"],
         "frequencies_hz": ["10"], "note": "Rotating table"},
    )  # fmt: skip
    assert response.status_code == 302
    stored = Enrolment.objects.get()
    assert stored.scope_benches == ["curvilinear"]
    assert stored.scope_frequencies_hz == [10.0]
    assert scope_text(stored) == "device MEMS 2; bench curvilinear; frequency 10 Hz"
    listing = visible(client.get(reverse("labs:calls")))
    assert "Device MEMS 2; bench curvilinear; frequency 10 Hz" in listing
    assert "Pending" in listing


def test_applying_through_the_api_with_a_key(call):
    response = call.key().post(
        API, {"scope": {"devices": ["MEMS 2"], "benches": ["linear"]}, "note": "API"},
        format="json",
    )  # fmt: skip
    assert response.status_code == 201, response.json()
    body = response.json()
    assert body["status"] == "pending"
    assert body["scope"]["description"] == "device MEMS 2; bench linear"
    assert body["participant"] is None
    stored = Enrolment.objects.get(pk=body["id"])
    assert stored.applied_by is None  # a key acts for the laboratory, never a person
    assert len(notices(call.lab, Notice.Kind.APPLIED)) == 1


@pytest.mark.parametrize("case", ["closed call", "duplicate", "participant"])
def test_state_conflicts_are_409_and_store_nothing(call, case):
    if case == "closed call":
        Comparison.objects.filter(pk=call.comparison.pk).update(
            enrolment_closes=timezone.now() - dt.timedelta(minutes=1)
        )
        before = 0
    elif case == "duplicate":
        call.apply()
        before = 1
    else:
        participants_invite(comparison=call.comparison, laboratories=[call.lab], notify=False)
        before = 0
    n_notices = Notice.objects.count()
    response = call.key().post(API, {"scope": {"benches": ["linear"]}}, format="json")
    assert response.status_code == 409, response.json()
    assert Enrolment.objects.count() == before
    assert Notice.objects.count() == n_notices
    web = _signed_in(call.manager).post(
        reverse("labs:call_apply", args=[CODE]), {"laboratory": call.lab.pk}
    )
    assert web.status_code == 200  # the form again, with the refusal
    assert Enrolment.objects.count() == before


def test_a_call_not_open_at_all_is_not_visible(call):
    Comparison.objects.filter(pk=call.comparison.pk).update(enrolment_open=False)
    assert call.key().post(API, {}, format="json").status_code == 404
    assert call.key().get(API).status_code == 404
    assert _signed_in(call.manager).get(reverse("labs:call_apply", args=[CODE])).status_code == 404
    assert not Enrolment.objects.exists()


@pytest.mark.parametrize(
    ("scope", "field"),
    [({"devices": ["MEMS 9"]}, "devices"), ({"benches": ["pendulum"]}, "benches"),
     ({"frequencies_hz": [7]}, "frequencies_hz")],
)  # fmt: skip
def test_a_scope_that_does_not_fit_is_400_naming_the_field(call, scope, field):
    response = call.key().post(API, {"scope": scope}, format="json")
    assert response.status_code == 400
    assert [e["field"] for e in response.json()["errors"]] == [field]
    assert not Enrolment.objects.exists()
    assert not Notice.objects.exists()


def test_a_scope_is_capped_like_an_invitations(call):
    response = call.key().post(API, {"scope": {"frequencies_hz": [5.0] * 1001}}, format="json")
    assert response.status_code == 400
    assert response.json()["errors"][0]["field"] == "frequencies_hz"
    assert not Enrolment.objects.exists()


def test_lab_staff_cannot_apply(call):
    api = call.person(call.staff).post(API, {"scope": {}}, format="json")
    assert api.status_code == 403
    web = _signed_in(call.staff)
    assert web.get(reverse("labs:call_apply", args=[CODE])).status_code == 404
    assert web.post(reverse("labs:call_apply", args=[CODE]), {}).status_code == 404
    assert not Enrolment.objects.exists()
    page = visible(web.get(reverse("labs:calls")))
    assert "Only a manager of a laboratory can apply" in page
    assert "lab-manager (Applicant Vibration Lab)" in page
    assert reverse("labs:call_apply", args=[CODE]) not in page


def test_the_manager_applies_as_a_person_through_the_api(call):
    response = call.person(call.manager).post(API, {"scope": {"axes": ["x"]}}, format="json")
    assert response.status_code == 201, response.json()
    stored = Enrolment.objects.get()
    assert (stored.applied_by, stored.scope_axes) == (call.manager, ["X"])


# --- deciding ---------------------------------------------------------------------------------


def test_accepting_invites_with_the_requested_scope_a_random_code_and_the_invitation(
    call, django_capture_on_commit_callbacks
):
    application = call.apply(scope=Scope(devices=["MEMS 1"], benches=["linear"]))
    response = call.person(call.coordinator).post(f"{API}{application.pk}/accept/", {},
                                                  format="json")  # fmt: skip
    assert response.status_code == 201, response.json()
    participant = Participant.objects.get(comparison=call.comparison, laboratory=call.lab)
    assert response.json()["participant"] == participant.code
    assert participant.code.startswith("L") and participant.code[1:].isdigit()
    assert participant.scope_benches == ["linear"]
    assert [d.name for d in participant.scope_devices.all()] == ["MEMS 1"]
    assert participant_points(participant).count() == 2
    stored = Enrolment.objects.get(pk=application.pk)
    assert (stored.status, stored.participant, stored.decided_by) == (
        Es.ACCEPTED, participant, call.coordinator,
    )  # fmt: skip
    assert stored.decided_at is not None
    (invitation,) = notices(call.lab, Notice.Kind.INVITATION)
    assert invitation.participant == participant
    assert participant.code in invitation.body


def test_participant_codes_do_not_follow_the_laboratory(call):
    """The same laboratory accepted into rounds gets codes drawn at random: with 20 rounds
    a code derived from the laboratory would repeat every time."""
    codes = set()
    for i in range(20):
        comparison = ComparisonFactory.create(code=f"IMU-R{i}", enrolment_open=True)
        application = enrolment_apply(comparison=comparison, laboratory=call.lab, scope=Scope(),
                                      notify=False)  # fmt: skip
        participant = enrolment_accept(enrolment=application, user=None).participant
        assert participant is not None
        codes.add(participant.code)
    assert len(codes) > 1


def test_the_coordinator_amends_the_scope_on_the_accept_page(call):
    application = call.apply(scope=Scope(benches=["linear"]))
    client = _signed_in(call.coordinator)
    url = reverse("coordinator:application_accept", args=[CODE, application.pk])
    page = visible(client.get(url))
    assert "Accepting invites Applicant Vibration Lab" in page
    assert "random participant code" in page
    response = client.post(url, {"devices": [call.mems2.pk], "benches": ["linear"]})
    assert response.status_code == 302
    participant = Participant.objects.get(laboratory=call.lab)
    assert [d.name for d in participant.scope_devices.all()] == ["MEMS 2"]
    assert participant.scope_benches == ["linear"]
    stored = Enrolment.objects.get(pk=application.pk)
    assert stored.status == Es.ACCEPTED
    assert stored.scope_devices.count() == 0  # the application keeps what was asked for


def test_declining_sends_the_reason_and_makes_no_participant(call):
    application = call.apply()
    client = call.person(call.coordinator)
    missing = client.post(f"{API}{application.pk}/decline/", {"reason": "  "}, format="json")
    assert missing.status_code == 400
    assert missing.json()["errors"][0]["field"] == "reason"
    assert Enrolment.objects.get().status == Es.PENDING
    reason = {"reason": "The linear bench slots are full."}
    response = client.post(f"{API}{application.pk}/decline/", reason, format="json")
    assert response.status_code == 200
    assert response.json()["status"] == "declined"
    stored = Enrolment.objects.get()
    assert (stored.status, stored.reason) == (Es.DECLINED, "The linear bench slots are full.")
    assert not Participant.objects.exists()
    (notice,) = notices(call.lab, Notice.Kind.DECLINED)
    assert "The linear bench slots are full." in notice.body
    assert notice.participant is None
    # decided: neither decision again
    again = client.post(f"{API}{application.pk}/accept/", {}, format="json")
    assert again.status_code == 409
    assert not Participant.objects.exists()
    # and the laboratory may apply again
    assert call.key().post(API, {}, format="json").status_code == 201


def test_declining_on_the_web_page(call):
    application = call.apply()
    client = _signed_in(call.coordinator)
    url = reverse("coordinator:application_decline", args=[CODE, application.pk])
    assert "Declining sends Applicant Vibration Lab a notice" in visible(client.get(url))
    assert client.post(url, {"reason": ""}).status_code == 200  # the form, reason required
    assert Enrolment.objects.get().status == Es.PENDING
    assert client.post(url, {"reason": "Full"}).status_code == 302
    assert Enrolment.objects.get().status == Es.DECLINED


def test_accept_refuses_a_laboratory_invited_meanwhile(call):
    application = call.apply()
    participants_invite(comparison=call.comparison, laboratories=[call.lab], notify=False)
    response = call.person(call.coordinator).post(f"{API}{application.pk}/accept/", {},
                                                  format="json")  # fmt: skip
    assert response.status_code == 409
    assert Enrolment.objects.get().status == Es.PENDING
    assert Participant.objects.count() == 1


def test_an_amended_scope_that_does_not_fit_is_400_and_nothing_changes(call):
    application = call.apply()
    response = call.person(call.coordinator).post(
        f"{API}{application.pk}/accept/", {"scope": {"devices": ["MEMS 7"]}}, format="json"
    )
    assert response.status_code == 400
    assert response.json()["errors"][0]["field"] == "devices"
    assert not Participant.objects.exists()
    assert Enrolment.objects.get().status == Es.PENDING
    assert not notices(call.lab, Notice.Kind.INVITATION)


def test_withdrawing_a_pending_application(call):
    application = call.apply()
    client = _signed_in(call.manager)
    url = reverse("labs:application_withdraw", args=[application.pk])
    assert _signed_in(call.staff).post(url).status_code == 404  # managers only
    assert client.post(url).status_code == 302
    assert Enrolment.objects.get().status == Es.WITHDRAWN
    with pytest.raises(StateConflict):
        enrolment_decline(enrolment=application, user=call.coordinator, reason="late")


# --- who sees what ----------------------------------------------------------------------------


def test_a_lab_sees_its_own_applications_only(call):
    own = call.apply()
    theirs = call.apply(laboratory=call.other)
    listed = call.key().get(API).json()["results"]
    assert [a["id"] for a in listed] == [own.pk]
    coordinator = call.person(call.coordinator).get(API).json()["results"]
    assert sorted(a["id"] for a in coordinator) == sorted([own.pk, theirs.pk])
    # another laboratory's application: 404 on the web and in the API
    withdraw = reverse("labs:application_withdraw", args=[theirs.pk])
    assert _signed_in(call.manager).post(withdraw).status_code == 404
    assert call.key().post(f"{API}{theirs.pk}/accept/", {}, format="json").status_code == 404
    assert call.key().post(f"{API}{own.pk}/accept/", {}, format="json").status_code == 403
    page = visible(_signed_in(call.manager).get(reverse("labs:calls")))
    assert "Other Inertial Lab" not in page
    assert Enrolment.objects.get(pk=theirs.pk).status == Es.PENDING


def test_another_rounds_coordinator_gets_404(call):
    application = call.apply()
    client = _signed_in(call.stranger)
    assert client.get(reverse("coordinator:applications", args=[CODE])).status_code == 404
    for name in ("coordinator:application_accept", "coordinator:application_decline"):
        url = reverse(name, args=[CODE, application.pk])
        assert client.get(url).status_code == 404
        assert client.post(url, {"reason": "x"}).status_code == 404
    api = call.person(call.stranger)
    assert api.get(API).json()["results"] == []  # the call is public, its applications not
    assert api.post(f"{API}{application.pk}/accept/", {}, format="json").status_code == 404
    assert api.post(f"{API}{application.pk}/decline/", {"reason": "x"},
                    format="json").status_code == 404  # fmt: skip
    # an application to another round is not found under this one's code either
    mine = ComparisonFactory.create(code="IMU-MINE")
    mine.coordinators.add(call.stranger)
    url = reverse("coordinator:application_accept", args=["IMU-MINE", application.pk])
    assert client.get(url).status_code == 404
    assert Enrolment.objects.get().status == Es.PENDING
    assert not Participant.objects.exists()


def test_the_coordinators_comparison_page_counts_pending_applications(call):
    call.apply()
    call.apply(laboratory=call.other)
    client = _signed_in(call.coordinator)
    page = visible(client.get(reverse("coordinator:comparison", args=[CODE])))
    assert "2 pending" in page
    assert reverse("coordinator:applications", args=[CODE]) in page
    listing = visible(client.get(reverse("coordinator:applications", args=[CODE])))
    assert "Applicant Vibration Lab" in listing and "Other Inertial Lab" in listing
    assert listing.count("Accept…") == 2


def test_services_refuse_bad_notes_and_reasons(call):
    with pytest.raises(ValidationFailed) as exc:
        call.apply(note="x" * 2001)
    assert exc.value.errors[0]["field"] == "note"
    application = call.apply()
    with pytest.raises(ValidationFailed):
        enrolment_decline(enrolment=application, user=None, reason="")


def _signed_in(user):
    client = Client()
    client.force_login(user)
    return client


# --- at once, and at scale --------------------------------------------------------------------


def _count_queries(client, url) -> int:
    with CaptureQueriesContext(connection) as queries:
        assert client.get(url).status_code == 200, url
    return len(queries)


def test_the_lists_make_as_many_queries_for_one_call_as_for_four(call):
    """No query per call or per application on the pages and API lists."""
    pages = [
        (_signed_in(call.manager), reverse("labs:calls")),
        (_signed_in(call.coordinator), reverse("coordinator:applications", args=[CODE])),
        (call.person(call.manager), "/api/v1/calls/"),
        (call.person(call.coordinator), API),
        (call.person(call.manager), API),
    ]
    call.apply()
    before = [_count_queries(client, url) for client, url in pages]
    for i in range(3):
        other = ComparisonFactory.create(code=f"IMU-MORE-{i}", enrolment_open=True)
        DeviceFactory.create(comparison=other)
        lab = LaboratoryFactory.create()
        enrolment_apply(comparison=call.comparison, laboratory=lab,
                        scope=Scope(devices=["MEMS 2"]), notify=False)  # fmt: skip
        enrolment_apply(comparison=other, laboratory=call.lab, scope=Scope(), notify=False)
    assert [_count_queries(client, url) for client, url in pages] == before


@pytest.mark.django_db(transaction=True)
def test_two_applications_at_once_store_one(needs_postgres, monkeypatch):
    """Both pass the checks before either is stored: the partial unique index lets one in,
    the other is the same 409 as a later duplicate."""
    call = Call()
    barrier = threading.Barrier(2)
    checked = enrolment_module._scope_clean

    def slow_clean(*args, **kwargs):
        result = checked(*args, **kwargs)
        barrier.wait(10)  # both applications are past the duplicate check here
        return result

    monkeypatch.setattr(enrolment_module, "_scope_clean", slow_clean)
    out: list[object] = [None, None]

    def apply(i: int) -> None:
        try:
            out[i] = call.apply(notify=False)
        except BaseException as exc:
            out[i] = exc
        finally:
            connection.close()

    threads = [threading.Thread(target=apply, args=(i,)) for i in range(2)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(60)
    assert sorted(type(o).__name__ for o in out) == ["Enrolment", "StateConflict"]
    assert Enrolment.objects.filter(laboratory=call.lab).count() == 1
