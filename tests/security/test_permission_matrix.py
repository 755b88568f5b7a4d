"""Permission matrix: every route × every persona × GET and POST, exact statuses, no leaks.

The routes come from the URL resolver (``tests/security/routes.py``), so a route added
without a row in ``TABLE`` fails :func:`test_every_route_has_a_row`. URL kwargs are lab
A's objects in comparison 1 (``tests/security/world.py``): lab B and the coordinator of
comparison 2 must get 404 for them, never 403, never their content.

The rows are in ``tests/security/matrix_table.py``: one status per persona, in the order

    anonymous a_staff a_manager b_staff coord1 coord2 key_a key_a_revoked superuser

for GET, for POST, and for any other method an API view implements (PUT, PATCH, DELETE:
a view that gains one fails until its row says who may use it). A 302 for a persona who is
not signed in must go to the login page. Unsafe requests carry an empty body (JSON ``{}``
for the API, an empty form for pages) and every request runs in a rolled-back savepoint,
so each sees the same world.

Set ``SECURITY_MATRIX_RECORD=1`` to print the observed table instead of asserting (to
write the row of a new route; every status must then be justified by reading the view).
"""

from __future__ import annotations

import copy
import json
import os
import weakref

import pytest
from django.conf import settings
from django.core.cache import caches
from django.db import transaction
from django.http import HttpResponse, HttpResponseBase
from django.test import Client
from django.urls import reverse
from rest_framework.views import APIView

from analysis.archive import archive_request
from analysis.reports.services import report_issue
from tests.security.matrix_table import OPTIONAL, PK, PUBLISHED, TABLE, TOKEN
from tests.security.routes import Route, discover
from tests.security.world import (
    LAB_A_CODE,
    LAB_A_NAME,
    LAB_A_VALUE_TEXTS,
    OUTSIDERS,
    PERSONAS,
    World,
)

pytestmark = pytest.mark.django_db
RECORD = bool(os.environ.get("SECURITY_MATRIX_RECORD"))
SIGNED_OUT = ("anonymous", "key_a", "key_a_revoked")
LOGOUTS = ("logout", "admin:logout")


def _admin_expected(route: Route, method: str, persona: str) -> set[int]:
    """Everything under admin/ is for the superuser only; the others go to the admin login
    (which itself answers everyone; logout sends everyone back to the admin index)."""
    if persona == "superuser":  # depends on the model and the method, never an error
        return {200, 302, 403, 404, 405}
    if route.name == "admin:login":
        return {200}
    return {302}


def _admin_values(route: Route, world: World) -> dict[str, object]:
    values: dict[str, object] = {"content_type_id": 1, "object_id": 1, "id": 1}
    model_admin = getattr(route.callback, "model_admin", None)
    if model_admin is not None:  # an existing object of the admin's model
        obj = model_admin.model._default_manager.first()
        values["object_id"] = values["id"] = obj.pk if obj is not None else 1
    return values


def _admin_url(route: Route, world: World) -> str:
    if "app_label" in route.route:  # the app index is a regex of the registered apps
        return reverse("admin:app_list", kwargs={"app_label": "labs"})
    if "(?P<url>" in route.route:  # the catch-all
        return "/admin/no-such-page/"
    return route.url(_admin_values(route, world))


def _body(response: HttpResponseBase) -> bytes:
    if response.streaming:
        return b"".join(response.streaming_content)  # type: ignore[attr-defined]
    assert isinstance(response, HttpResponse)  # not streaming
    return response.content


#: each persona's scratch client (made once: a new client's handler loads the middleware
#: chain again on its first request, a tenth of a redirect's cost)
_SCRATCH: weakref.WeakKeyDictionary[Client, Client] = weakref.WeakKeyDictionary()


def _scratch(persona: Client) -> Client:
    client = _SCRATCH.get(persona)
    if client is None:
        client = _SCRATCH[persona] = Client(raise_request_exception=False)
        client.defaults.update(persona.defaults)
    return client


def _request(persona: Client, method: str, url: str, api: bool) -> HttpResponseBase:
    for cache in caches.all():  # throttling counts requests; this test makes many
        cache.clear()
    # A copy of the persona's client, given the persona's cookies again before every
    # request: a logout or a new session cookie stays in the copy.
    client = _scratch(persona)
    client.cookies = copy.deepcopy(persona.cookies)
    with transaction.atomic():
        if method == "GET":
            response = client.get(url)
        elif api:
            send = getattr(client, method.lower())
            response = send(url, data=json.dumps({}), content_type="application/json")
        else:
            response = client.post(url, data={})
        body = _body(response)
        transaction.set_rollback(True)
    response.body = body  # type: ignore[attr-defined]
    return response


def _api_methods(route: Route) -> list[str]:
    """PUT, PATCH, DELETE that an API view implements (DRF views only)."""
    view = getattr(route.callback, "view_class", None)
    if view is None or not issubclass(view, APIView):
        return []
    return [m for m in ("PUT", "PATCH", "DELETE") if hasattr(view, m.lower())]


def _leaks(body: bytes) -> list[str]:
    text = body.decode("utf-8", errors="replace")
    return [s for s in (LAB_A_NAME, LAB_A_CODE, *LAB_A_VALUE_TEXTS) if s in text]


def test_every_route_has_a_row():
    """A new route fails here until it gets a row (admin/ is covered by one rule)."""
    found = {r.route for r in discover() if not r.route.startswith("admin/")}
    missing = sorted(found - TABLE.keys())
    assert not missing, f"routes without a row in TABLE: {missing}"
    stale = sorted(TABLE.keys() - found - OPTIONAL)
    assert not stale, f"rows for routes that no longer exist: {stale}"


def _url(route: Route, world: World) -> str:
    if route.route.startswith("admin/"):
        return _admin_url(route, world)
    values = world.url_values()
    if route.route in PK:
        values["pk"] = values[PK[route.route]]
    if route.route in TOKEN:
        values["token"] = values[TOKEN[route.route]]
    row = TABLE.get(route.route)
    return route.url(values) + (f"?{row.query}" if row and row.query else "")


def _expected(route: Route, method: str, persona: str) -> set[int] | None:
    if route.route.startswith("admin/"):
        return _admin_expected(route, method, persona)
    row = TABLE.get(route.route)
    if row is None or (method not in ("GET", "POST") and method not in row.other):
        return None  # recording, or a method without a row (reported by the caller)
    return row.expected(method)[persona]


def _judge(route: Route, method: str, persona: str, response: HttpResponseBase) -> list[str]:
    """What is wrong with one response: status, where a redirect goes, leaks."""
    # the test client sets request on the responses it returns
    path = response.request["PATH_INFO"]  # type: ignore[attr-defined]
    status, where = response.status_code, f"{method} {path} as {persona}"
    problems = []
    expected = _expected(route, method, persona)
    if not RECORD and (expected is None or status not in expected):
        problems.append(f"{where}: {status}, expected {expected}")
    if status == 302 and persona in SIGNED_OUT and route.name not in LOGOUTS:
        login = "/admin/login/" if route.route.startswith("admin/") else reverse(settings.LOGIN_URL)
        location = response.headers.get("Location", "")
        if not location.startswith(login):
            problems.append(f"{where}: redirected to {location}, not to {login}")
    if status >= 500:
        problems.append(f"{where}: server error {status}")
    leaked = _leaks(response.body)  # type: ignore[attr-defined]
    if persona in OUTSIDERS and leaked:
        problems.append(f"{where}: lab A's {leaked} in the response")
    return problems


def test_permission_matrix(world):
    clients = {p: world.client(p) for p in PERSONAS}
    problems: list[str] = []
    observed: dict[str, dict[str, list[int]]] = {}
    seen: set[str] = set()  # lab A's secrets as shown to lab A and its coordinator
    for route in discover():
        if not (RECORD or route.route in TABLE or route.route.startswith("admin/")):
            continue  # test_every_route_has_a_row reports it
        url, api = _url(route, world), route.route.startswith("api/")
        for method in ("GET", "POST", *_api_methods(route)):
            for persona in PERSONAS:
                response = _request(clients[persona], method, url, api)
                observed.setdefault(route.route, {}).setdefault(method, []).append(
                    response.status_code
                )
                problems += _judge(route, method, persona, response)
                if persona in ("a_staff", "coord1"):
                    seen.update(_leaks(response.body))  # type: ignore[attr-defined]
    if RECORD:
        _print_table(observed)
    # The probe strings are what the pages really show: lab A and coordinator 1 see them.
    assert {LAB_A_NAME, LAB_A_CODE} <= seen and seen & set(LAB_A_VALUE_TEXTS), seen
    assert not problems, "\n".join(problems)


def _print_table(observed: dict[str, dict[str, list[int]]]) -> None:
    for key, by_method in observed.items():
        if not key.startswith("admin/"):
            line = {m: " ".join(map(str, codes)) for m, codes in by_method.items()}
            other = {m: v for m, v in line.items() if m not in ("GET", "POST")}
            extra = f", other={other}" if other else ""
            print(f'    "{key}": Row(get="{line["GET"]}", post="{line["POST"]}"{extra}),')


def test_published_results_show_codes_never_names(world):
    """Lab A's own report downloads for lab A; lab B gets 404 for it and never sees a
    laboratory name; the API gives lab B its own scores only."""
    world.c1.status = "published"
    world.c1.authorised_by_name, world.c1.authorised_by_role = "A. Signer", "Head"
    world.c1.save()
    # participants read final reports only: lab A's report of the published comparison
    preliminary = world.report_a
    world.report_a = report_issue(
        comparison=world.c1, kind="participant", participant=preliminary.participant
    )
    assert (preliminary.status, world.report_a.status) == ("preliminary", "final")
    lab_a = archive_request(comparison=world.c1, run=world.run, participant=preliminary.participant)
    assert lab_a.status == "ready", lab_a.error  # its ZIP: lab A reads it, lab B gets 404
    clients = {p: world.client(p) for p in PERSONAS}
    routes = {r.route: r for r in discover()}
    problems = []
    for key, row in PUBLISHED.items():
        url = routes[key].url(world.url_values()) + (f"?{row.query}" if row.query else "")
        for persona in PERSONAS:
            response = _request(clients[persona], "GET", url, key.startswith("api/"))
            body = response.body  # type: ignore[attr-defined]
            if response.status_code not in row.expected("GET")[persona]:
                problems.append(f"GET {url} as {persona}: {response.status_code}")
            if persona in ("b_staff", "a_staff") and LAB_A_NAME.encode() in body:
                problems.append(f"GET {url} as {persona}: a laboratory name")
            if persona in OUTSIDERS and persona != "b_staff" and _leaks(body):
                problems.append(f"GET {url} as {persona}: lab A's {_leaks(body)}")
    assert not problems, "\n".join(problems)
    old = f"/api/v1/reports/{preliminary.token}/pdf"
    assert _request(clients["a_staff"], "GET", old, True).status_code == 404
    assert _request(clients["coord1"], "GET", old, True).status_code == 200
    own = _request(clients["b_staff"], "GET", f"/api/v1/comparisons/{world.c1.code}/scores/", True)
    labs = {s["lab"] for s in json.loads(own.body)["results"]}  # type: ignore[attr-defined]
    assert labs == {"KB2"}
