"""What the schema fuzzer found, pinned as plain tests (each was a 500 or a malformed error).

Every answer is now a 400 in the shape of docs/interfaces.md §3, naming the field at fault.
"""

import pytest

from tests.security.world import C1

pytestmark = pytest.mark.django_db


def _error(response, field):
    assert response.status_code == 400, response.content
    body = response.json()
    assert set(body) == {"detail", "errors"} and body["detail"], body
    assert field in {e["field"] for e in body["errors"]}, body
    assert all(set(e) == {"row", "field", "message"} for e in body["errors"]), body


def test_numbers_under_a_check_constraint(world):
    """Were IntegrityErrors (500): the CHECK constraints were not validated first."""
    coordinator = world.client("coord1")
    for field, value in (("en_limit", "0"), ("sigma_pt_value", "-1"), ("en_limit", "inf")):
        body = {"code": "NEW-1", "title": "New", field: value}
        _error(coordinator.post("/api/v1/comparisons/", body), field)
    for field in ("nominal_sensitivity", "tolerance"):
        body = {"name": "MEMS 9", field: "0"}
        _error(coordinator.post(f"/api/v1/comparisons/{C1}/devices/", body), field)


def test_grid_list_errors_name_the_item(world):
    """Was a KeyError (500): a list field's errors come as a dict by index."""
    body = {"axes": ["X", "XY"], "benches": ["linear"], "frequencies_hz": ["10"]}
    response = world.client("coord1").post(f"/api/v1/comparisons/{C1}/measurands/generate/", body)
    _error(response, "axes[1]")


def test_query_filters(world):
    """Were ValueErrors and a CoreInputError (500), and a filter error without detail."""
    coordinator, base = world.client("coord1"), f"/api/v1/comparisons/{C1}/"
    _error(coordinator.get(base + "scores/?frequency_hz=required"), "frequency_hz")
    _error(coordinator.get(base + "compatibility/?factor=axis&frequency_hz=ten"), "frequency_hz")
    _error(coordinator.get(base + "compatibility/?factor=lab&frequency_hz=0"), None)  # no result
    # django-filter's errors were {"status": [...], "errors": []}: no detail, no rows
    _error(world.client("key_a").get(base + "submissions/?status=maybe"), "status")


def test_lab_key_reading_a_run_is_404_not_500(world):
    """Was a TypeError (500): the run lookup treated the key's principal as a user."""
    response = world.client("key_a").get(f"/api/v1/analysis-runs/{world.run.pk}/")
    assert response.status_code == 404
    assert response.json()["detail"].startswith("No analysis run")


def test_invite_by_unicode_digits_or_a_huge_id_is_unknown_not_500(world):
    """Was a ValueError (500): "¹".isdigit() is True in Python but not a usable id."""
    from labs.models import Participant

    before = Participant.objects.count()
    coordinator = world.client("coord1")
    for wanted in (["¹"], ["99999999999999999999999"], [world.lab_b.name, "¹"]):
        response = coordinator.post(
            f"/api/v1/comparisons/{C1}/participants/",
            {"laboratories": wanted},
            content_type="application/json",
        )
        assert response.status_code == 400, response.content
        assert "Unknown laboratories" in response.json()["detail"]
    assert Participant.objects.count() == before  # nothing invited half-way


@pytest.mark.parametrize("kind", ["django", "psycopg"])
def test_lost_database_connection_is_a_clear_503(kind):
    """A COPY raises psycopg's OperationalError directly (no Django wrapping): it was a 500."""
    import psycopg
    from django.db import OperationalError

    from common.errors import api_exception_handler

    exc = OperationalError("server closed the connection") if kind == "django" else (
        psycopg.OperationalError("terminating connection due to administrator command")
    )  # fmt: skip
    response = api_exception_handler(exc, {})
    assert response is not None and response.status_code == 503
    assert response.data["detail"].startswith("The database connection failed")
    assert "nothing was stored half-way" in response.data["detail"]


def test_an_unreadable_content_type_is_a_documented_415(world):
    """The negative fuzzer's: 415 was answered by every body-taking view but documented
    by none (and a ``?format=`` error of the CSV template was documented as CSV)."""
    from django.test import Client

    response = world.client("key_a").post(
        f"/api/v1/comparisons/{C1}/submissions/upload/", b"x", content_type="text/plain"
    )
    assert response.status_code == 415
    assert set(response.json()) == {"detail", "errors"}
    schema = Client().get("/api/schema/?format=json").json()["paths"]
    upload = schema["/api/v1/comparisons/{code}/submissions/upload/"]["post"]["responses"]
    assert upload["415"]["content"] == {
        "application/json": {"schema": {"$ref": "#/components/schemas/Error"}}
    }
    template = schema["/api/v1/comparisons/{code}/template.csv"]["get"]["responses"]
    assert list(template["404"]["content"]) == ["application/json"]
