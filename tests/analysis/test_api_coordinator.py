"""Coordinator API: runs, scores, compatibility, publication, review — per persona."""

import pytest
from django.contrib.auth import get_user_model
from django.core import mail
from rest_framework.test import APIClient

from analysis.models import AnalysisRun
from labs.models import Laboratory, Participant, Submission
from labs.services import api_key_create
from tests.factories import ComparisonFactory, UserFactory

pytestmark = pytest.mark.django_db(transaction=True)
CODE = "IMU-2024-DEMO"


def client_for(user=None, key=None):
    c = APIClient()
    if user is not None:
        c.force_authenticate(user)
    if key is not None:
        c.credentials(HTTP_AUTHORIZATION=f"Api-Key {key}")
    return c


def user(name):
    return get_user_model().objects.get(username=name)


@pytest.fixture
def personas(demo):
    other = UserFactory.create(username="other-coordinator")
    ComparisonFactory.create(code="OTHER-01").coordinators.add(other)
    lab_a = Laboratory.objects.get(name="Alpine Vibration Metrology")  # lab03
    _, key_a = api_key_create(laboratory=lab_a, name="software", user=None)
    return {
        "anonymous": APIClient(),
        "coordinator": client_for(user("coordinator")),
        "other_coordinator": client_for(other),
        "lab_a": client_for(user("lab03")),
        "lab_b": client_for(user("lab04")),
        "key_a": client_for(key=key_a),
        "superuser": client_for(user("admin")),
    }


START = {
    "anonymous": 401, "coordinator": 202, "other_coordinator": 404, "lab_a": 403,
    "lab_b": 403, "key_a": 403, "superuser": 202,
}  # fmt: skip


@pytest.mark.parametrize("persona", sorted(START))
def test_start_run_permissions(personas, persona):
    response = personas[persona].post(f"/api/v1/comparisons/{CODE}/analysis-runs/")
    assert response.status_code == START[persona], response.content
    if response.status_code == 202:
        body = response.json()
        assert body["status"] == "succeeded" and body["progress"] == 100  # eager in tests
        assert AnalysisRun.objects.filter(pk=body["id"]).exists()
    else:
        assert AnalysisRun.objects.count() == 0
        assert "detail" in response.json()


def test_flow_run_publish_and_participant_view(personas, demo):
    coord = personas["coordinator"]
    run = coord.post(f"/api/v1/comparisons/{CODE}/analysis-runs/").json()
    detail = coord.get(f"/api/v1/analysis-runs/{run['id']}/")
    assert detail.status_code == 200 and detail.json()["stage"] == "done"
    assert personas["lab_a"].get(f"/api/v1/analysis-runs/{run['id']}/").status_code == 404
    assert (
        personas["other_coordinator"].get(f"/api/v1/analysis-runs/{run['id']}/").status_code == 404
    )

    scores = coord.get(f"/api/v1/comparisons/{CODE}/scores/").json()
    assert scores["count"] == 891
    mems2 = coord.get(f"/api/v1/comparisons/{CODE}/scores/", {"device": "MEMS 2", "axis": "X",
                      "frequency_hz": "5", "bench": "linear"}).json()  # fmt: skip
    assert mems2["count"] == 11

    # before publication a participant sees no scores
    assert personas["lab_a"].get(f"/api/v1/comparisons/{CODE}/scores/").status_code == 409
    published = coord.post(f"/api/v1/comparisons/{CODE}/publish/")
    # 202: the publication job, done at once by eager Celery
    assert published.status_code == 202 and published.json()["status"] == "published"
    assert published.json()["publication"]["status"] == "succeeded"
    # one e-mail per laboratory, to all its members (lab03's to its manager too)
    assert len(mail.outbox) == 12 and "results published" in mail.outbox[0].subject
    assert sum(len(m.to) for m in mail.outbox) == 13

    code_a = Participant.objects.get(
        comparison=demo, laboratory__name="Alpine Vibration Metrology"
    ).code
    own = personas["lab_a"].get(f"/api/v1/comparisons/{CODE}/scores/", {"lab": "L99"}).json()
    assert own["count"] == 81
    assert {r["lab"] for r in own["results"]} == {code_a}
    by_key = personas["key_a"].get(f"/api/v1/comparisons/{CODE}/scores/").json()
    assert by_key["count"] == 81
    b_view = personas["lab_b"].get(f"/api/v1/comparisons/{CODE}/scores/")
    assert code_a.encode() not in b_view.content
    assert b"Alpine" not in b_view.content


def test_compatibility_endpoint(personas):
    coord = personas["coordinator"]
    coord.post(f"/api/v1/comparisons/{CODE}/analysis-runs/")
    bench = coord.get(f"/api/v1/comparisons/{CODE}/compatibility/", {"factor": "bench"})
    assert bench.status_code == 200
    assert len(bench.json()) == 9  # 3 devices x 3 axes
    one = coord.get(f"/api/v1/comparisons/{CODE}/compatibility/",
                    {"factor": "bench", "device": "MEMS 1", "axis": "Y"}).json()  # fmt: skip
    assert len(one) == 1 and one[0]["levels"] == ["curvilinear", "linear"]
    assert one[0]["en"][0][1] == one[0]["en"][1][0] > 0
    lab = coord.get(
        f"/api/v1/comparisons/{CODE}/compatibility/",
        {"factor": "lab", "device": "MEMS 2", "axis": "X", "frequency_hz": "5", "bench": "linear"},
    )
    assert lab.status_code == 200
    (m,) = lab.json()
    assert len(m["levels"]) == 11 and len(m["en"]) == 11
    assert m["incompatible_pairs"] >= 10  # the outlier against the rest
    too_many = coord.get(f"/api/v1/comparisons/{CODE}/compatibility/", {"factor": "lab"})
    assert too_many.status_code == 400 and "narrow it down" in too_many.json()["detail"]
    bad = coord.get(f"/api/v1/comparisons/{CODE}/compatibility/", {"factor": "colour"})
    assert bad.status_code == 400 and bad.json()["errors"][0]["field"] == "factor"
    assert personas["lab_a"].get(f"/api/v1/comparisons/{CODE}/compatibility/",
                                 {"factor": "bench"}).status_code == 409  # fmt: skip


def test_publish_needs_a_run_and_coordinator(personas):
    assert personas["coordinator"].post(f"/api/v1/comparisons/{CODE}/publish/").status_code == 409
    assert personas["lab_a"].post(f"/api/v1/comparisons/{CODE}/publish/").status_code == 403
    assert (
        personas["other_coordinator"].post(f"/api/v1/comparisons/{CODE}/publish/").status_code
        == 404
    )


def test_transition_and_review(personas, demo):
    coord = personas["coordinator"]
    reopened = coord.post(f"/api/v1/comparisons/{CODE}/transition/", {"to": "open"}, format="json")
    assert reopened.status_code == 200 and reopened.json()["status"] == "open"
    illegal = coord.post(f"/api/v1/comparisons/{CODE}/transition/", {"to": "published"},
                         format="json")  # fmt: skip
    assert illegal.status_code == 400
    p = Participant.objects.get(comparison=demo, laboratory__name="Garonne Test House")
    sub = Submission.objects.create(participant=p, version=2, status="submitted")
    url = f"/api/v1/comparisons/{CODE}/submissions/{p.code}/2/decision/"
    assert personas["lab_a"].post(url, {"decision": "accept"}, format="json").status_code == 403
    no_reason = coord.post(url, {"decision": "reject"}, format="json")
    assert no_reason.status_code == 400 and "Say why" in no_reason.json()["detail"]
    rejected = coord.post(url, {"decision": "reject", "message": "unit mix-up on MEMS 3"},
                          format="json")  # fmt: skip
    assert rejected.status_code == 200 and rejected.json()["status"] == "rejected"
    sub.refresh_from_db()
    assert sub.status == "rejected" and sub.message == "unit mix-up on MEMS 3"
    again = coord.post(url, {"decision": "accept"}, format="json")
    assert again.status_code == 409
    from auditlog.models import LogEntry

    assert LogEntry.objects.get_for_object(sub).filter(changes__icontains="rejected").exists()


def test_check_request_does_not_reveal_the_deviation(personas, demo):
    p = Participant.objects.get(comparison=demo, laboratory__name=
                                "Outlier Metrology Services")  # fmt: skip
    result = p.submissions.get().results.select_related("measurement_point__device").filter(
        measurement_point__device__name="MEMS 2").first()  # fmt: skip
    assert result is not None
    response = personas["coordinator"].post(
        f"/api/v1/comparisons/{CODE}/check-requests/", {"result": result.pk}, format="json"
    )
    assert response.status_code == 202
    (msg,) = mail.outbox
    assert "MEMS 2" in msg.body
    from auditlog.models import LogEntry

    entry = LogEntry.objects.get_for_object(result.submission).get(action=LogEntry.Action.ACCESS)
    assert entry.actor.username == "coordinator" and "check_requested" in entry.changes
    for leak in (f"{result.value}", "En", "high", "low", "%", "deviation of"):
        assert leak not in msg.body
    assert (
        personas["lab_b"]
        .post(f"/api/v1/comparisons/{CODE}/check-requests/", {"result": result.pk}, format="json")
        .status_code
        == 403
    )
