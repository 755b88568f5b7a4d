"""The whole round through the API: create, invite, open, two labs submit, close, review,
run (Celery, eager here; a real worker in test_runs_worker), publish, participants' view."""

import pytest
from django.contrib.auth.models import Group, Permission
from rest_framework.test import APIClient

from analysis.models import AnalysisRun, Score
from labs.services import api_key_create
from tests.factories import LaboratoryFactory, UserFactory

pytestmark = pytest.mark.django_db(transaction=True)


def client(user=None, key=None):
    c = APIClient()
    if user:
        c.force_authenticate(user)
    if key:
        c.credentials(HTTP_AUTHORIZATION=f"Api-Key {key}")
    return c


@pytest.fixture
def coordinator():
    group = Group.objects.create(name="coordinators")
    group.permissions.add(Permission.objects.get(codename="add_comparison"))
    user = UserFactory.create(username="carla")
    user.groups.add(group)
    return user


def rows(offset):
    return [
        {"device": "MEMS 1", "axis": a, "frequency_hz": f, "bench": "linear",
         "sensitivity": 420.0 + offset + 0.1 * i, "expanded_uncertainty": 8.0}
        for i, (a, f) in enumerate((a, f) for a in "XYZ" for f in (5, 10, 20))
    ]  # fmt: skip


def test_round_end_to_end(coordinator):
    coord = client(coordinator)
    created = coord.post("/api/v1/comparisons/", {
        "code": "IMU-2026-01", "title": "Round 1", "template": "linear",
        "assigned_value_method": "weighted_mean", "sigma_pt_mode": "relative",
        "sigma_pt_value": 1.0}, format="json")  # fmt: skip
    assert created.status_code == 201, created.content
    assert created.json()["code"] == "IMU-2026-01"
    base = "/api/v1/comparisons/IMU-2026-01/"
    assert (
        coord.post(
            base + "devices/",
            {"name": "MEMS 1", "model": "LSM6DSR", "nominal_sensitivity": 418, "tolerance": 1},
            format="json",
        ).status_code
        == 201
    )
    grid = coord.post(base + "measurands/generate/", {"template": "linear"}, format="json")
    assert grid.json() == {"created": 9, "measurement_points": 9}
    lab_a, lab_b = (
        LaboratoryFactory.create(name="Lab Alpha"),
        LaboratoryFactory.create(name="Lab Beta"),
    )
    invited = coord.post(base + "participants/", {"laboratories": ["Lab Alpha", str(lab_b.pk)]},
                         format="json").json()["participants"]  # fmt: skip
    codes = {p["laboratory"]: p["code"] for p in invited}
    assert len(set(codes.values())) == 2
    assert (
        coord.post(base + "transition/", {"to": "open"}, format="json").json()["status"] == "open"
    )

    _, key_a = api_key_create(laboratory=lab_a, name="soft", user=None)
    _, key_b = api_key_create(laboratory=lab_b, name="soft", user=None)
    for key, offset in ((key_a, 0.0), (key_b, 2.0)):
        r = client(key=key).post(base + "submissions/", {"results": rows(offset)}, format="json")
        assert r.status_code == 201 and r.json()["status"] == "submitted", r.content

    assert coord.post(base + "transition/", {"to": "closed"}, format="json").status_code == 200
    for lab in ("Lab Alpha", "Lab Beta"):
        decided = coord.post(f"{base}submissions/{codes[lab]}/1/decision/",
                             {"decision": "accept"}, format="json")  # fmt: skip
        assert decided.json()["status"] == "accepted"

    run = coord.post(base + "analysis-runs/").json()
    assert run["status"] == "succeeded", run
    assert Score.objects.filter(run_id=run["id"]).count() == 18
    scores = coord.get(base + "scores/", {"axis": "X", "frequency_hz": "5"}).json()["results"]
    # two labs, u = 4 each: weighted mean 421, each contributes -> u(d)^2 = 16 - 8
    by_lab = {s["lab"]: s for s in scores}
    assert by_lab[codes["Lab Alpha"]]["d"] == pytest.approx(-1.0)
    assert by_lab[codes["Lab Alpha"]]["en"] == pytest.approx(-1.0 / (2 * 8**0.5))
    assert by_lab[codes["Lab Alpha"]]["correlation_applied"] is True

    assert client(key=key_a).get(base + "scores/").status_code == 409
    assert coord.post(base + "publish/").status_code == 409  # final reports need an authoriser
    signed = {"authorised_by_name": "Carla C.", "authorised_by_role": "PT coordinator"}
    assert coord.put(base + "report-notes/", signed, format="json").status_code == 200
    assert coord.post(base + "publish/").json()["status"] == "published"
    own = client(key=key_a).get(base + "scores/").json()
    assert own["count"] == 9 and {s["lab"] for s in own["results"]} == {codes["Lab Alpha"]}
    assert codes["Lab Beta"].encode() not in client(key=key_a).get(base + "scores/").content
    assert AnalysisRun.objects.get(pk=run["id"]).comparison.status == "published"


def test_setup_endpoints_are_for_coordinators(coordinator):
    outsider = UserFactory.create(username="olga")
    assert client(outsider).post("/api/v1/comparisons/", {"code": "X-1", "title": "x"},
                                 format="json").status_code == 403  # fmt: skip
    coord = client(coordinator)
    coord.post("/api/v1/comparisons/", {"code": "X-1", "title": "x"}, format="json")
    setup = (
        ("devices/", {"name": "D"}),
        ("measurands/generate/", {"template": "linear"}),
        ("participants/", {"laboratories": ["nobody"]}),
    )
    for path, body in setup:
        assert client(outsider).post(f"/api/v1/comparisons/X-1/{path}", body,
                                     format="json").status_code == 404  # fmt: skip
    bad = coord.post("/api/v1/comparisons/X-1/participants/", {"laboratories": ["nobody"]},
                     format="json")  # fmt: skip
    assert bad.status_code == 400 and "Unknown laboratories: nobody" in bad.json()["detail"]
    dup = coord.post("/api/v1/comparisons/", {"code": "X-1", "title": "again"}, format="json")
    assert dup.status_code == 400 and dup.json()["errors"][0]["field"] == "code"
