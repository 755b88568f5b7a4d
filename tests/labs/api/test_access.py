"""Every endpoint × persona gives the exact status; nothing of lab A ever reaches lab B."""

import pytest

from tests.labs.api import A_VALUES, LAB_A_NAME, PERSONAS, as_csv, rows

pytestmark = pytest.mark.django_db

C = "/api/v1/comparisons/IMU-A-01"
ENDPOINTS = {
    "list": ("get", "/api/v1/comparisons/"),
    "detail": ("get", f"{C}/"),
    "measurands": ("get", f"{C}/measurands/"),
    "template": ("get", f"{C}/template.csv"),
    "template_xlsx": ("get", f"{C}/template.csv?format=xlsx"),
    "submit": ("post", f"{C}/submissions/"),
    "upload": ("post", f"{C}/submissions/upload/"),
    "submissions": ("get", f"{C}/submissions/"),
    "version": ("get", f"{C}/submissions/1/?participant=L17"),
}
LAB_A = (200, 200, 200, 200, 200, 201, 201, 200, 200)
COORDINATOR = (200, 200, 200, 200, 200, 403, 403, 200, 200)
OUTSIDER = (200, 404, 404, 404, 404, 404, 404, 404, 404)
EXPECTED = {
    "anonymous": (401,) * 9,
    "staff_a": LAB_A,
    "staff_b": OUTSIDER,
    "manager_a": LAB_A,
    "coord": COORDINATOR,
    "coord_other": OUTSIDER,
    "key_a": LAB_A,
    "revoked_key_a": (401,) * 9,
    "admin": COORDINATOR,
}
CASES = [
    pytest.param(persona, name, EXPECTED[persona][i], id=f"{persona}-{name}")
    for persona in PERSONAS
    for i, name in enumerate(ENDPOINTS)
]


def call(client, endpoint: str):
    method, url = ENDPOINTS[endpoint]
    if endpoint == "submit":
        return client.post(url, {"results": rows()}, format="json")
    if endpoint == "upload":
        return client.post(url, {"file": _file(as_csv(rows()))}, format="multipart")
    return getattr(client, method)(url)


def _file(data: bytes, name: str = "results.csv"):
    from django.core.files.uploadedfile import SimpleUploadedFile

    return SimpleUploadedFile(name, data, content_type="text/csv")


@pytest.mark.parametrize(("persona", "endpoint", "status"), CASES)
def test_status_matrix(world, persona, endpoint, status):
    response = call(world.client(persona), endpoint)
    assert response.status_code == status, response.content[:300]
    if status >= 400:
        body = response.json()
        assert set(body) == {"detail", "errors"} and body["detail"]


def test_outsider_answers_are_the_same_as_for_a_missing_comparison(world):
    client = world.client("staff_b")
    hidden = client.get(f"{C}/").json()
    missing = client.get("/api/v1/comparisons/NO-SUCH/").json()
    assert hidden["detail"].replace("IMU-A-01", "X") == missing["detail"].replace("NO-SUCH", "X")


def test_anonymous_is_told_how_to_authenticate(world):
    response = world.client("anonymous").get("/api/v1/comparisons/")
    assert response.status_code == 401
    assert response["WWW-Authenticate"] == "Api-Key"


SHARED = "/api/v1/comparisons/IMU-AB-01"
B_URLS = [
    "/api/v1/comparisons/",
    "/api/v1/comparisons/?status=open",
    f"{SHARED}/",
    f"{SHARED}/measurands/",
    f"{SHARED}/template.csv",
    f"{SHARED}/submissions/",
    f"{SHARED}/submissions/1/",
    f"{SHARED}/submissions/1/?participant=L71",
    f"{C}/",
    f"{C}/submissions/",
    f"{C}/submissions/1/?participant=L17",
]


@pytest.mark.parametrize("persona", ["staff_b", "key_b"])
def test_nothing_of_lab_a_reaches_lab_b(world, persona):
    client = world.client(persona)
    answers = [client.get(url) for url in B_URLS]
    answers.append(client.post(f"{SHARED}/submissions/", {"results": rows()}, format="json"))
    answers.append(client.get(f"{SHARED}/submissions/1/"))  # B's own version 1 now
    # (404 answers echo the comparison code the caller asked for, the same for a missing one)
    secrets = [LAB_A_NAME, "L71", "L17", *(repr(v) for v in A_VALUES)]
    for response in answers:
        assert response.status_code in (200, 201, 404), response.content[:200]
        for secret in secrets:
            assert secret.encode() not in response.content, (response.request, secret)
    assert answers[-1].json()["participant"] == "L32"


def test_lab_b_gets_404_for_lab_a_version(world):
    response = world.client("key_b").get(f"{SHARED}/submissions/1/?participant=L71")
    assert response.status_code == 404


def test_coordinator_sees_every_lab_by_code_only(world):
    client = world.client("coord")
    world.client("key_b").post(f"{SHARED}/submissions/", {"results": rows()}, format="json")
    listing = client.get(f"{SHARED}/submissions/")
    assert {s["participant"] for s in listing.json()["results"]} == {"L71", "L32"}
    detail = client.get(f"{SHARED}/submissions/1/?participant=L32")
    for response in (listing, detail, client.get(f"{SHARED}/")):
        for name in (LAB_A_NAME, "Bravo", "alice", "bob"):
            assert name.encode() not in response.content


def test_coordinator_must_say_whose_version(world):
    response = world.client("coord").get(f"{C}/submissions/1/")
    assert response.status_code == 400
    assert response.json()["errors"][0]["field"] == "participant"


def test_participant_cannot_name_another_lab(world):
    response = world.client("key_a").get(f"{SHARED}/submissions/1/?participant=L32")
    assert response.status_code == 404


def test_listing_scope_and_status_filter(world):
    codes = lambda r: sorted(c["code"] for c in r.json()["results"])  # noqa: E731
    assert codes(world.client("key_a").get("/api/v1/comparisons/")) == ["IMU-A-01", "IMU-AB-01"]
    assert codes(world.client("staff_b").get("/api/v1/comparisons/")) == ["IMU-AB-01", "IMU-B-01"]
    assert codes(world.client("coord").get("/api/v1/comparisons/")) == ["IMU-A-01", "IMU-AB-01"]
    assert codes(world.client("coord_other").get("/api/v1/comparisons/")) == ["IMU-B-01"]
    assert len(codes(world.client("admin").get("/api/v1/comparisons/"))) == 3
    world.other.status = "closed"
    world.other.save()
    admin = world.client("admin")
    assert codes(admin.get("/api/v1/comparisons/?status=closed")) == ["IMU-B-01"]
    assert admin.get("/api/v1/comparisons/?status=nonsense").status_code == 400


def test_detail_shows_own_code_and_roles(world):
    mine = world.client("key_a").get(f"{C}/").json()
    assert (mine["participant_code"], mine["roles"]) == ("L17", ["participant"])
    assert mine["devices"][0]["name"] == "MEMS 1" and mine["devices"][0]["unit"] == "D/(m/s^2)"
    assert mine["n_measurement_points"] == 4
    coord = world.client("coord").get(f"{C}/").json()
    assert (coord["participant_code"], coord["roles"]) == (None, ["coordinator"])
