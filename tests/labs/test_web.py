"""Laboratory web pages: who sees what (302 to login, 200, 404), isolation, escaping.

Personas: ``a_staff`` and ``a_manager`` of Lab Alpha, ``b_staff`` of Lab Bravo.  Alpha takes
part in ``CMP-A`` alone and with Bravo in ``CMP-SHARED``; both comparisons are open.
"""

import datetime as dt
import re
from dataclasses import dataclass

import pytest
from django.urls import reverse
from django.utils import timezone

from labs.models import Membership, Participant, Submission
from labs.services import api_key_create
from proficiency.models import Comparison
from proficiency.services import measurement_points_generate
from tests.factories import (
    ComparisonFactory,
    DeviceFactory,
    LaboratoryFactory,
    MembershipFactory,
    ParticipantFactory,
    ResultFactory,
    SubmissionFactory,
)

pytestmark = pytest.mark.django_db

A_VALUE = 423.456789  # Alpha's distinctive result, never shown to Bravo
A_U = 0.00012  # small enough that the pages write A_VALUE as 423.45679 (docs/domain.md §3.1)
A_NAME = "Lab Alpha Metrology"


@dataclass
class World:
    cmp_a: Comparison
    cmp_shared: Comparison
    part_a: Participant
    part_a_shared: Participant
    part_b_shared: Participant
    a_staff: object
    a_manager: object
    b_staff: object


def open_comparison(code: str, **extra) -> Comparison:
    """An open comparison with MEMS 1, axes X and Y, 5 and 10 Hz on the linear bench."""
    deadline = timezone.now() + dt.timedelta(days=30)
    comparison = ComparisonFactory.create(
        code=code, status="open", submission_deadline=deadline, **extra
    )
    device = DeviceFactory.create(comparison=comparison, name="MEMS 1")
    measurement_points_generate(
        comparison=comparison,
        devices=[device],
        axes=["X", "Y"],
        frequencies_hz=[5, 10],
        benches=["linear"],
    )
    return comparison


def submitted(participant: Participant, value: float = A_VALUE) -> Submission:
    submission = SubmissionFactory.create(
        participant=participant, status="submitted", submitted_at=timezone.now()
    )
    for point in participant.comparison.measurement_points.all():
        ResultFactory.create(
            submission=submission, measurement_point=point, value=value, expanded_uncertainty=A_U
        )
    return submission


def make_world() -> World:
    lab_a = LaboratoryFactory.create(name=A_NAME)
    lab_b = LaboratoryFactory.create(name="Lab Bravo Calibration")
    a_staff = MembershipFactory.create(laboratory=lab_a, user__username="alpha-staff").user
    a_manager = MembershipFactory.create(
        laboratory=lab_a, user__username="alpha-manager", role=Membership.Role.MANAGER
    ).user
    b_staff = MembershipFactory.create(laboratory=lab_b, user__username="bravo-staff").user
    cmp_a, cmp_shared = open_comparison("CMP-A"), open_comparison("CMP-SHARED")
    part_a = ParticipantFactory.create(comparison=cmp_a, laboratory=lab_a, code="L91")
    part_a_shared = ParticipantFactory.create(comparison=cmp_shared, laboratory=lab_a, code="L93")
    part_b_shared = ParticipantFactory.create(comparison=cmp_shared, laboratory=lab_b, code="L94")
    submitted(part_a)
    submitted(part_a_shared)
    return World(
        cmp_a, cmp_shared, part_a, part_a_shared, part_b_shared, a_staff, a_manager, b_staff
    )


@pytest.fixture
def world() -> World:
    return make_world()


def visible(response) -> str:
    """The page text without the random CSRF tokens (they could contain any letters)."""
    text = response.content.decode()
    text = re.sub(r'name="csrfmiddlewaretoken" value="[^"]*"', "", text)
    return re.sub(r'"X-CSRFToken": "[^"]*"', "", text)


def comparison_urls(code: str) -> list[str]:
    return [
        reverse("labs:comparison", args=[code]),
        reverse("labs:grid", args=[code]),
        reverse("labs:upload", args=[code]),
        reverse("labs:template", args=[code, "csv"]),
        reverse("labs:template", args=[code, "xlsx"]),
        reverse("labs:history", args=[code]),
        reverse("labs:submission", args=[code, 1]),
    ]


def lab_urls(world: World) -> list[str]:
    lab_pk = world.part_a.laboratory_id
    return [
        reverse("labs:dashboard"),
        *comparison_urls("CMP-A"),
        reverse("labs:api_keys_index"),
        reverse("labs:api_keys", args=[lab_pk]),
    ]


def test_anonymous_is_sent_to_login(client, world):
    for url in lab_urls(world):
        response = client.get(url)
        assert response.status_code == 302, url
        assert response["Location"].startswith(reverse("login") + "?next="), url


def test_staff_of_lab_a_sees_its_pages(client, world):
    client.force_login(world.a_staff)
    for url in [reverse("labs:dashboard"), *comparison_urls("CMP-A")]:
        assert client.get(url).status_code == 200, url


def test_staff_is_not_shown_api_keys(client, world):
    """Key pages are for managers: staff get 404, as for anything not visible to them."""
    client.force_login(world.a_staff)
    lab_pk = world.part_a.laboratory_id
    assert client.get(reverse("labs:api_keys_index")).status_code == 404
    assert client.get(reverse("labs:api_keys", args=[lab_pk])).status_code == 404
    assert client.post(reverse("labs:api_keys", args=[lab_pk]), {"name": "x"}).status_code == 404
    assert b"API keys" not in client.get(reverse("labs:dashboard")).content


def test_manager_sees_api_keys(client, world):
    client.force_login(world.a_manager)
    lab_pk = world.part_a.laboratory_id
    index = client.get(reverse("labs:api_keys_index"))
    assert index.status_code == 302 and index["Location"] == reverse("labs:api_keys", args=[lab_pk])
    assert client.get(reverse("labs:api_keys", args=[lab_pk])).status_code == 200
    assert client.get(reverse("labs:dashboard")).status_code == 200


def test_other_lab_gets_404_on_a_things(client, world):
    client.force_login(world.b_staff)
    for url in comparison_urls("CMP-A"):
        assert client.get(url).status_code == 404, url
        assert client.post(url, {"action": "draft"}).status_code in (404, 405), url
    assert client.get(reverse("labs:comparison", args=["NO-SUCH"])).status_code == 404
    lab_pk = world.part_a.laboratory_id
    assert client.get(reverse("labs:api_keys", args=[lab_pk])).status_code == 404


def test_other_lab_never_sees_a_values_codes_or_names(client, world):
    key_obj, _ = api_key_create(laboratory=world.part_a.laboratory, name="alpha-robot", user=None)
    client.force_login(world.b_staff)
    pages = [
        reverse("home"),
        reverse("labs:dashboard"),
        *[u for u in comparison_urls("CMP-SHARED") if not u.endswith(".xlsx")],
    ]
    for url in pages:
        response = client.get(url)
        assert response.status_code in (200, 404), url  # Bravo has no version 1: 404
        body = visible(response) if response.status_code == 200 else response.content.decode()
        for secret in (A_NAME, "L91", "L93", "423.456", "CMP-A<", "alpha-", key_obj.prefix):
            assert secret not in body, (url, secret)
    assert "L94" in visible(client.get(reverse("labs:comparison", args=["CMP-SHARED"])))


def test_dashboard_lists_comparisons_with_code_status_and_submission(client, world):
    client.force_login(world.a_staff)
    body = visible(client.get(reverse("labs:dashboard")))
    for text in ("CMP-A", "CMP-SHARED", "L91", "L93", "Open for submissions", "Submitted", A_NAME):
        assert text in body
    assert "<time datetime=" in body  # deadline rendered as a machine-readable UTC time


def test_home_is_the_dashboard_for_lab_members(client, world):
    client.force_login(world.b_staff)
    body = visible(client.get("/"))
    assert "My comparisons" in body and "CMP-SHARED" in body and "CMP-A<" not in body


def test_comparison_page_shows_protocol_devices_points_and_links(client, world):
    client.force_login(world.a_staff)
    body = visible(client.get(reverse("labs:comparison", args=["CMP-A"])))
    assert "MEMS 1" in body and "418" in body and "± 1 %" in body
    assert body.count("<tr><td>MEMS 1</td>") == 4  # the measurement points table
    for name in ("grid", "upload", "history"):
        assert reverse(f"labs:{name}", args=["CMP-A"]) in body
    assert reverse("labs:template", args=["CMP-A", "xlsx"]) in body
    assert "version 1, 4 results" in body


def test_history_and_version_detail(client, world):
    client.force_login(world.a_staff)
    SubmissionFactory.create(participant=world.part_a, version=2, status="draft", source="file")
    body = visible(client.get(reverse("labs:history", args=["CMP-A"])))
    assert "Version 2" in body and "Version 1" in body and "File upload" in body
    detail = visible(client.get(reverse("labs:submission", args=["CMP-A", 1])))
    assert "423.45679" in detail and "cannot be changed" in detail
    assert "<input" not in detail.split("<main")[1]  # read-only
    assert client.get(reverse("labs:submission", args=["CMP-A", 9])).status_code == 404


def test_names_and_titles_are_escaped(client):
    lab = LaboratoryFactory.create(name="<script>alert(1)</script>")
    user = MembershipFactory.create(laboratory=lab).user
    comparison = open_comparison("CMP-XSS", title='<img src=x onerror="alert(2)">')
    comparison.devices.update(name="<b>MEMS</b>")
    ParticipantFactory.create(comparison=comparison, laboratory=lab)
    client.force_login(user)
    for url in (reverse("labs:dashboard"), *comparison_urls("CMP-XSS")[:3]):
        body = client.get(url).content
        assert b"<script>alert(1)" not in body and b"<img src=x" not in body, url
        assert b"<b>MEMS</b>" not in body, url
    dashboard = client.get(reverse("labs:dashboard")).content
    assert b"&lt;script&gt;alert(1)&lt;/script&gt;" in dashboard
    grid = client.get(reverse("labs:grid", args=["CMP-XSS"])).content
    assert b"&lt;b&gt;MEMS&lt;/b&gt;" in grid


def test_login_logout_and_password_change(client, world):
    page = client.get(reverse("login"))
    assert page.status_code == 200 and b"csrfmiddlewaretoken" in page.content
    assert b'for="id_username"' in page.content and b'for="id_password"' in page.content
    response = client.post(
        reverse("login"), {"username": "alpha-staff", "password": "correct horse battery staple"}
    )
    assert response.status_code == 302
    assert client.get(reverse("password_change")).status_code == 200
    response = client.post(
        reverse("password_change"),
        {
            "old_password": "correct horse battery staple",
            "new_password1": "a much longer secret 42",
            "new_password2": "a much longer secret 42",
        },
    )
    assert response["Location"] == reverse("password_change_done")
    assert client.post(reverse("logout")).status_code == 302
    assert client.get(reverse("labs:dashboard")).status_code == 302


def test_csrf_is_enforced(world):
    from django.test import Client

    strict = Client(enforce_csrf_checks=True)
    strict.force_login(world.a_staff)
    response = strict.post(reverse("labs:grid", args=["CMP-A"]), {"action": "draft"})
    assert response.status_code == 403


def test_pages_have_viewport_and_labelled_inputs(client, world):
    client.force_login(world.a_staff)
    body = visible(client.get(reverse("labs:grid", args=["CMP-A"])))
    assert 'name="viewport"' in body
    ids = re.findall(r'<input type="text" name="[^"]+" id="([^"]+)"', body)
    assert len(ids) == 4 * 7  # 4 points x (sensitivity, U, k, dof, repeat_sd, n_repeats, note)
    for input_id in ids:
        assert f'<label class="visually-hidden" for="{input_id}">' in body
