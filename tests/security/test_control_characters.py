"""Control characters (NUL first) in paths, query strings, JSON bodies and form posts.

PostgreSQL cannot store NUL in text: each of these was a 500 on PostgreSQL (the schema
fuzzer ran on SQLite, which stores NUL). Now a path with a C0 character is a 404, and a
query parameter, form field or JSON string with a C0 character other than tab, LF and CR
is a 400 naming the parameter, field or key path, in the error shape of docs/interfaces.md §3.
"""

from urllib.parse import urlencode

import pytest
from axes.models import AccessAttempt
from django.core.files.uploadedfile import SimpleUploadedFile

from labs.models import Result, Submission
from tests.labs.api import as_csv, rows
from tests.labs.api import build_world as build_api_world
from tests.security.world import C1, LAB_A_CODE

pytestmark = pytest.mark.django_db

SUBMIT = "/api/v1/comparisons/IMU-A-01/submissions/"
UPLOAD = "/api/v1/comparisons/IMU-A-01/submissions/upload/"
MESSAGE = "contains the control character U+0000 at position 2; only tab and line breaks"


@pytest.fixture
def api_world(settings):
    settings.DEBUG = False
    return build_api_world()


def api_error(response, *fields):
    """A 400 in the API's error shape naming exactly ``fields``."""
    assert response.status_code == 400, response.content
    body = response.json()
    assert body["detail"] == "The request contains control characters; see errors."
    assert [e["field"] for e in body["errors"]] == list(fields), body
    assert all(set(e) == {"row", "field", "message"} for e in body["errors"]), body
    return body["errors"]


# --- paths: 404 -------------------------------------------------------------------------------


@pytest.mark.parametrize("char", ["%00", "%01", "%1F", "%7F", "%0A"])
def test_a_control_character_in_a_path_part_is_404(world, char):
    coordinator, key = world.client("coord1"), world.client("key_a")
    for client, method, url in (
        (key, "get", f"/api/v1/reports/{char}/pdf"),
        (key, "get", f"/api/v1/reports/{world.report_a.token}{char}/pdf"),
        (coordinator, "post", f"/api/v1/comparisons/{C1}/submissions/{char}/1/decision/"),
        (coordinator, "get", f"/coordinator/{C1}/review/{char}/v1/"),
        (coordinator, "get", f"/coordinator/{C1}/participants/{char}/reference/"),
        (world.client("a_staff"), "post", f"/lab/{world.lab_a.pk}/api-keys/{char}/revoke/"),
    ):
        response = getattr(client, method)(url)
        assert response.status_code == 404, (url, response.content)
        if url.startswith("/api/"):
            assert response.json() == {"detail": "Not found.", "errors": []}


# --- query strings: 400 naming the parameter --------------------------------------------------


def test_a_nul_in_a_query_parameter_is_400_naming_it(world):
    base = f"/api/v1/comparisons/{C1}/"
    for client in (world.client("coord1"), world.client("key_a")):
        errors = api_error(client.get(base + "scores/?device=%00"), "device")
        assert errors[0]["message"] == (
            "The value contains the control character U+0000 at position 1; "
            "only tab and line breaks are allowed."
        )
        api_error(client.get(base + "submissions/?participant=Q%00Z&status=draft"), "participant")
    # the parameter's name: named with the character escaped
    api_error(world.client("coord1").get(base + "scores/?dev%00ice=1"), "dev\\x00ice")


def test_a_nul_in_a_page_query_is_400_naming_it(world):
    response = world.client("coord1").get(f"/coordinator/{C1}/scores/?device=%00&axis=X")
    assert response.status_code == 400
    assert response["Content-Type"] == "text/plain; charset=utf-8"
    assert response.content.decode().splitlines() == [
        "The request contains control characters; see errors.",
        "device: The value contains the control character U+0000 at position 1; "
        "only tab and line breaks are allowed.",
    ]


def test_tab_and_line_breaks_in_a_query_are_not_refused(world):
    base = f"/api/v1/comparisons/{C1}/"
    response = world.client("coord1").get(base + "submissions/?participant=Q%09Z%0A%0D")
    assert response.status_code == 200
    assert response.json()["results"] == []


# --- JSON bodies: 400 naming the key path, nothing stored -------------------------------------


def test_a_nul_in_a_json_string_is_400_naming_its_key_path(api_world):
    key_a = api_world.client("key_a")
    before = (Submission.objects.count(), Result.objects.count())
    body = {"results": rows(), "submit": "a\x00b", "extra": {"deep": ["ok", "\x07"]}}
    errors = api_error(key_a.post(SUBMIT, body, format="json"), "submit", "extra.deep[1]")
    assert MESSAGE in errors[0]["message"]
    body = {"results": rows(), "n\x00te": "x"}
    errors = api_error(key_a.post(SUBMIT, body, format="json"), None)
    assert errors[0]["message"].startswith("The key 'n\\x00te' contains the control character")
    assert (Submission.objects.count(), Result.objects.count()) == before


def test_a_nul_in_a_results_row_is_400_naming_row_and_column(api_world):
    """The rows go through the importer, which names row and column as for any bad cell."""
    key_a = api_world.client("key_a")
    before = (Submission.objects.count(), Result.objects.count())
    data = rows()
    data[1]["note"], data[2]["unit"] = "a\x00b", "\x07"
    response = key_a.post(SUBMIT, {"results": data}, format="json")
    assert response.status_code == 400, response.content
    errors = response.json()["errors"]
    assert [(e["row"], e["field"]) for e in errors] == [(2, "note"), (3, "unit")]
    assert errors[0]["message"].startswith("contains the control character U+0000 at position 2")
    data[1]["note"], data[2]["unit"], data[0]["n\x00te"] = "ok", "mV/g", "x"
    response = key_a.post(SUBMIT, {"results": data}, format="json")
    assert response.status_code == 400, response.content
    assert (Submission.objects.count(), Result.objects.count()) == before


def test_tab_and_line_breaks_in_a_json_note_are_stored(api_world):
    data = rows()
    data[0]["note"] = "bench 2\tre-mounted\r\nafter the first run"
    response = api_world.client("key_a").post(SUBMIT, {"results": data}, format="json")
    assert response.status_code == 201, response.content
    notes = Result.objects.filter(submission__version=response.json()["version"])
    assert "bench 2\tre-mounted\r\nafter the first run" in notes.values_list("note", flat=True)


def test_a_nul_in_a_coordinator_json_body_is_400(world):
    before = Submission.objects.filter(status="accepted").count()
    response = world.client("coord1").post(
        f"/api/v1/comparisons/{C1}/submissions/{LAB_A_CODE}/2/decision/",
        {"decision": "accept", "message": "fine\x00"},
        content_type="application/json",
    )
    api_error(response, "message")
    assert Submission.objects.filter(status="accepted").count() == before


# --- form posts: urlencoded and multipart -----------------------------------------------------


def test_a_nul_in_the_sign_in_form_is_400_and_records_nothing(world):
    from django.test import Client

    response = Client().post("/accounts/login/", {"username": "coord\x001", "password": "x"})
    assert response.status_code == 400
    assert "username: The value contains the control character U+0000" in response.content.decode()
    assert AccessAttempt.objects.count() == 0


def test_a_nul_in_a_page_form_field_is_400(world):
    response = world.client("coord1").post(f"/coordinator/{C1}/status/", {"to": "open\x00"})
    assert response.status_code == 400
    assert "to: The value contains the control character U+0000" in response.content.decode()


def test_a_nul_in_an_api_form_post_is_400(world):
    url = f"/api/v1/comparisons/{C1}/submissions/{LAB_A_CODE}/2/decision/"
    coordinator = world.client("coord1")
    body = {"decision": "accept", "message": "fine\x00"}
    api_error(coordinator.post(url, body), "message")  # multipart/form-data
    form = "application/x-www-form-urlencoded"
    api_error(coordinator.post(url, urlencode(body), content_type=form), "message")


def test_multipart_fields_are_checked_in_the_api(api_world):
    key_a = api_world.client("key_a")
    before = Submission.objects.count()
    file = SimpleUploadedFile("results.csv", as_csv(rows()), content_type="text/csv")
    response = key_a.post(UPLOAD, {"file": file, "submit": "tr\x00ue"}, format="multipart")
    api_error(response, "submit")
    assert Submission.objects.count() == before


def test_multipart_fields_are_checked_in_the_pages(api_world):
    client = api_world.client("staff_a")
    before = Submission.objects.count()
    file = SimpleUploadedFile("results.csv", as_csv(rows()), content_type="text/csv")
    response = client.post(
        "/lab/comparisons/IMU-A-01/upload/", {"file": file, "action": "sub\x00mit"}
    )
    assert response.status_code == 400
    assert "action: The value contains the control character U+0000" in response.content.decode()
    assert Submission.objects.count() == before


def test_multipart_fields_read_by_the_csrf_check_are_400_naming_them(api_world):
    """With CSRF enforced, Django's CSRF check reads the form before the view does."""
    from django.test import Client

    client = Client(enforce_csrf_checks=True)
    client.force_login(api_world.users["staff_a"])
    url = "/lab/comparisons/IMU-A-01/upload/"
    assert client.get(url).status_code == 200
    token = client.cookies["csrftoken"].value
    before = Submission.objects.count()
    file = SimpleUploadedFile("results.csv", as_csv(rows()), content_type="text/csv")
    body = {"file": file, "action": "sub\x00mit", "csrfmiddlewaretoken": token}
    response = client.post(url, body)
    assert response.status_code == 400
    assert "action: The value contains the control character U+0000" in response.content.decode()
    assert Submission.objects.count() == before
