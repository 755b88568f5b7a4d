"""Coordinator web pages: every page × persona, setup (create, devices, grid, overrides,
invitations, reference, open/close) and review (accept, reject, ask to check)."""

import pytest
from django.contrib.auth import get_user_model
from django.core import mail

from labs.models import Laboratory, Participant, Submission
from proficiency.models import Comparison, MeasurementPoint
from tests.factories import ComparisonFactory, UserFactory

CODE = "IMU-2024-DEMO"


def user(name):
    return get_user_model().objects.get(username=name)


@pytest.fixture
def other_coordinator(demo):
    other = UserFactory.create(username="other-coordinator")
    ComparisonFactory.create(code="IMU-OTHER").coordinators.add(other)
    return other


def coordinator_pages(demo, run):
    submission = Submission.objects.filter(participant__comparison=demo).first()
    point = demo.measurement_points.first()
    assert submission is not None and point is not None
    c = f"/coordinator/{CODE}/"
    return [
        c, c + "edit/", c + "devices/new/", c + "points/generate/", f"{c}points/{point.pk}/",
        c + "participants/invite/", c + "review/",
        f"{c}review/{submission.participant.code}/v{submission.version}/",
        c + "analysis/runs/", f"{c}analysis/runs/{run.pk}/", f"{c}analysis/runs/{run.pk}/progress/",
        c + "results/", f"{c}results/?run={run.pk}", c + "scores/", c + "scores.csv",
        c + "scores.xlsx", c + "charts/", c + "compatibility/", c + "compatibility/?factor=lab",
    ]  # fmt: skip


@pytest.mark.parametrize(
    ("persona", "expected"),
    [(None, 302), ("coordinator", 200), ("other", 404), ("lab03", 404), ("admin", 200)],
)
def test_every_coordinator_page_by_persona(client, demo, run, other_coordinator, persona, expected):
    if persona == "other":
        client.force_login(other_coordinator)
    elif persona:
        client.force_login(user(persona))
    for url in coordinator_pages(demo, run):
        response = client.get(url)
        assert response.status_code == expected, url
        if expected == 302:
            assert response["Location"].startswith("/accounts/login/")


@pytest.mark.parametrize(
    ("persona", "expected"),
    [(None, 302), ("coordinator", 200), ("other", 200), ("lab03", 404), ("admin", 200)],
)
def test_dashboard_by_persona(client, demo, other_coordinator, persona, expected):
    if persona == "other":
        client.force_login(other_coordinator)
    elif persona:
        client.force_login(user(persona))
    response = client.get("/coordinator/")
    assert response.status_code == expected
    if persona == "other":
        assert CODE.encode() not in response.content
        assert b"IMU-OTHER" in response.content
    if persona == "coordinator":
        assert CODE.encode() in response.content
        assert b"New comparison" in response.content


def test_posts_are_404_for_lab_staff(client, demo):
    client.force_login(user("lab03"))
    for url in ("status/", "analysis/run/", "publish/"):
        assert client.post(f"/coordinator/{CODE}/{url}", {"to": "open"}).status_code == 404
    assert Comparison.objects.get(code=CODE).status == "closed"


def test_create_from_template_then_devices_points_invite_open(client, demo):
    client.force_login(user("coordinator"))
    response = client.post(
        "/coordinator/new/",
        {"code": "IMU-2025-01", "title": "New round", "assigned_value_method": "weighted_mean",
         "sigma_pt_mode": "none", "en_limit": "1", "template": "linear_and_curvilinear"},
    )  # fmt: skip
    assert response.status_code == 302
    new = Comparison.objects.get(code="IMU-2025-01")
    assert new.protocol == "linear_and_curvilinear"
    assert new.coordinators.filter(username="coordinator").exists()
    base = "/coordinator/IMU-2025-01/"
    device = {"name": "MEMS A", "unit": "D/(m/s^2)", "nominal_sensitivity": "418",
              "tolerance": "1", "tolerance_relative": "on",
              "tolerance_distribution": "rectangular"}  # fmt: skip
    assert client.post(base + "devices/new/", device).status_code == 302
    # a second device with the same name is refused with a message, not a 500
    again = client.post(base + "devices/new/", device)
    assert again.status_code == 200
    assert b"already has a device named" in again.content
    # opening without points is refused with the service's message
    client.post(base + "status/", {"to": "open"})
    page = client.get(base)
    assert b"has no measurement points" in page.content
    assert client.post(base + "points/generate/", {"template": new.protocol}).status_code == 302
    # 1 device x 3 axes x (3 linear + 3 curvilinear x 2 directions) = 27 points
    assert new.measurement_points.count() == 27
    labs = Laboratory.objects.order_by("name")[:2]
    response = client.post(
        base + "participants/invite/", {"laboratories": [lab.pk for lab in labs]}
    )
    assert response.status_code == 302
    codes = list(new.participants.values_list("code", flat=True))
    assert len(codes) == 2 and all(c.startswith("L") for c in codes)
    client.post(f"{base}participants/{codes[0]}/reference/")
    assert new.participants.get(code=codes[0]).is_reference
    client.post(f"{base}participants/{codes[1]}/reference/")
    assert list(new.participants.filter(is_reference=True).values_list("code", flat=True)) == [
        codes[1]
    ]
    assert client.post(base + "status/", {"to": "open"}).status_code == 302
    new.refresh_from_db()
    assert new.status == "open"
    client.post(base + "status/", {"to": "closed"})
    new.refresh_from_db()
    assert new.status == "closed"


def test_points_from_lists_and_override(client, demo):
    client.force_login(user("coordinator"))
    settings = {"assigned_value_method": "reference", "sigma_pt_mode": "none", "en_limit": "1"}
    client.post("/coordinator/new/", {"code": "IMU-LISTS", "title": "Lists", **settings})
    c = Comparison.objects.get(code="IMU-LISTS")
    assert c.protocol == "custom"
    client.post("/coordinator/IMU-LISTS/devices/new/", {"name": "D1", "unit": "mV/(m/s^2)",
                "tolerance_distribution": "rectangular"})  # fmt: skip
    bad = client.post("/coordinator/IMU-LISTS/points/generate/", {"frequencies": "5, x"})
    assert b"Give numbers separated by commas" in bad.content
    response = client.post(
        "/coordinator/IMU-LISTS/points/generate/",
        {"axes": ["X", "Z"], "frequencies": "5, 10", "benches": ["linear"]},
    )
    assert response.status_code == 302
    assert c.measurement_points.count() == 4
    point = c.measurement_points.first()
    assert point is not None
    url = f"/coordinator/IMU-LISTS/points/{point.pk}/"
    client.post(url, {"assigned_value_method": "algorithm_a", "sigma_pt_value": "2.5"})
    point = MeasurementPoint.objects.get(pk=point.pk)
    assert (point.assigned_value_method, point.sigma_pt_value) == ("algorithm_a", 2.5)


def test_sigma_pt_value_required_for_prescribed_mode(client, demo):
    client.force_login(user("coordinator"))
    data = {"code": CODE, "title": "t", "assigned_value_method": "nominal",
            "sigma_pt_mode": "absolute", "en_limit": "1"}  # fmt: skip
    response = client.post(f"/coordinator/{CODE}/edit/", data)
    assert response.status_code == 200
    assert "A prescribed σ_pt needs a value" in response.content.decode()


def _submitted(demo):
    participant = demo.participants.get(laboratory__name__startswith="Alpine")
    old = participant.submissions.get()
    new = Submission.objects.create(participant=participant, version=2, status="submitted")
    for r in old.results.all():
        r.pk, r.submission = None, new
        r.save()
    return new


def test_review_table_and_accept(client, demo):
    client.force_login(user("coordinator"))
    submission = _submitted(demo)
    code = submission.participant.code
    page = client.get(f"/coordinator/{CODE}/review/")
    assert b"Alpine Vibration Metrology" in page.content
    assert b"81 / 81" in page.content
    url = f"/coordinator/{CODE}/review/{code}/v2/"
    detail = client.get(url)
    assert detail.status_code == 200
    assert b"Ask to check" in detail.content and b"Accept" in detail.content
    response = client.post(url, {"decision": "accept", "message": ""})
    assert response.status_code == 302
    submission.refresh_from_db()
    assert submission.status == "accepted"
    messages = client.get(response["Location"]).content
    assert f"Version 2 of {code} accepted".encode() in messages


def test_reject_needs_a_message(client, demo):
    client.force_login(user("coordinator"))
    submission = _submitted(demo)
    url = f"/coordinator/{CODE}/review/{submission.participant.code}/v2/"
    refused = client.post(url, {"decision": "reject", "message": "  "})
    assert refused.status_code == 200
    assert b"Say why the submission is rejected" in refused.content
    submission.refresh_from_db()
    assert submission.status == "submitted"
    client.post(url, {"decision": "reject", "message": "Units look like mV, please check."})
    submission.refresh_from_db()
    assert (submission.status, submission.message) == (
        "rejected",
        "Units look like mV, please check.",
    )


def test_ask_to_check_says_nothing_about_the_deviation(
    client, demo, django_capture_on_commit_callbacks
):
    client.force_login(user("coordinator"))
    participant = Participant.objects.get(comparison=demo, laboratory__name__startswith="Outlier")
    result = participant.submissions.get().results.first()
    assert result is not None
    mail.outbox.clear()
    with django_capture_on_commit_callbacks(execute=True):  # the e-mail goes after commit
        response = client.post(f"/coordinator/{CODE}/review/results/{result.pk}/check/")
    assert response.status_code == 302
    assert len(mail.outbox) == 1
    body = str(mail.outbox[0].body)
    assert "please check" in mail.outbox[0].subject
    assert str(result.value) not in body and "%" not in body


def test_lab_name_is_escaped(client, demo):
    lab = Laboratory.objects.get(name__startswith="Alpine")
    lab.name = "<script>alert(1)</script>"
    lab.save()
    client.force_login(user("coordinator"))
    for url in (f"/coordinator/{CODE}/", f"/coordinator/{CODE}/review/"):
        content = client.get(url).content
        assert b"<script>alert(1)</script>" not in content
        assert b"&lt;script&gt;alert(1)&lt;/script&gt;" in content
