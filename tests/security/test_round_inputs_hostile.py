"""Hostile input to what the round workflow reads since scopes, relative U and reminder
days: control characters, extreme floats, a very wide list and the same request twice at
once, on PostgreSQL. Each answer is a clear 400 (or the one right result) within bounded
time, and nothing is stored half-way."""

from __future__ import annotations

import json
import time
from typing import Any

import pytest
from rest_framework.test import APIClient

from labs.importers import ImportErrors, parse_table
from labs.models import Laboratory, Participant
from proficiency.models import Comparison, ComparisonStatus
from tests.concurrency import at_once
from tests.factories import (
    ComparisonFactory,
    DeviceFactory,
    LaboratoryFactory,
    MeasurementPointFactory,
    UserFactory,
)

pytestmark = pytest.mark.django_db(transaction=True)


@pytest.fixture
def round_(needs_postgres):
    comparison = ComparisonFactory.create(code="HOSTILE-01", status=ComparisonStatus.DRAFT)
    device = DeviceFactory.create(comparison=comparison, name="MEMS 1")
    for f in (5.0, 10.0):
        MeasurementPointFactory.create(
            comparison=comparison, device=device, frequency_hz=f, bench="linear",
            direction="vertical", axis="X",
        )  # fmt: skip
    coordinator = UserFactory.create()
    comparison.coordinators.add(coordinator)
    return comparison, coordinator


def api(user) -> APIClient:
    client = APIClient()
    client.force_authenticate(user)
    return client


def invite(client: APIClient, lab: Laboratory, scope: dict[str, Any]):
    return client.post(
        "/api/v1/comparisons/HOSTILE-01/participants/",
        {"laboratories": [lab.name], "scope": scope},
        format="json",
    )


@pytest.mark.parametrize(
    ("scope", "field"),
    [
        ({"benches": ["linear\x00"]}, "benches"),
        ({"axes": ["\x1b[31mX"]}, "axes"),
        ({"devices": ["MEMS\x001"]}, "devices"),
        ({"frequencies_hz": [1e-300]}, "frequencies_hz"),
        ({"frequencies_hz": [1e308]}, "frequencies_hz"),
        ({"frequencies_hz": [-5.0]}, "frequencies_hz"),
    ],
)
def test_a_hostile_scope_is_a_400_naming_it_and_invites_nobody(round_, scope, field):
    comparison, coordinator = round_
    lab = LaboratoryFactory.create()
    response = invite(api(coordinator), lab, scope)
    assert response.status_code == 400, response.content
    body = response.json()
    assert field in json.dumps(body["errors"]), body
    assert not Participant.objects.filter(comparison=comparison).exists()


def test_a_million_frequencies_is_refused_in_bounded_time(round_):
    comparison, coordinator = round_
    lab = LaboratoryFactory.create()
    wide = [7.0 + i * 1e-3 for i in range(1_000_000)]
    started = time.monotonic()
    response = invite(api(coordinator), lab, {"frequencies_hz": wide})
    elapsed = time.monotonic() - started
    assert response.status_code in (400, 413), response.status_code
    assert elapsed < 30, f"{elapsed:.1f} s for one request"
    assert len(response.content) < 1_000_000  # the answer does not echo a million errors
    assert "a scope lists at most 1000" in response.content.decode()
    assert not Participant.objects.filter(comparison=comparison).exists()


def test_the_same_invitation_twice_at_once_makes_one_participant(round_):
    comparison, coordinator = round_
    lab = LaboratoryFactory.create()
    a, b = at_once(
        *(lambda: invite(api(coordinator), lab, {"benches": ["linear"]}) for _ in range(2))
    )
    statuses = sorted(r.status_code for r in (a, b))
    assert statuses[0] == 201 and statuses[1] in (201, 409), (a.content, b.content)
    participant = Participant.objects.get(comparison=comparison, laboratory=lab)
    assert participant.scope_benches == ["linear"]


def test_the_same_scope_change_twice_at_once_stores_it_once(round_):
    comparison, coordinator = round_
    lab = LaboratoryFactory.create()
    assert invite(api(coordinator), lab, {}).status_code == 201
    code = Participant.objects.get(comparison=comparison).code
    url = f"/api/v1/comparisons/HOSTILE-01/participants/{code}/scope/"
    body = {"devices": ["MEMS 1"], "frequencies_hz": [5.0]}
    a, b = at_once(*(lambda: api(coordinator).put(url, body, format="json") for _ in range(2)))
    assert (a.status_code, b.status_code) == (200, 200), (a.content, b.content)
    participant = Participant.objects.get(comparison=comparison)
    assert participant.scope_devices.count() == 1
    assert participant.scope_frequencies_hz == [5.0]


@pytest.mark.parametrize("entered", ["1e308%", "1e-300%", "\x001.2%", "1.2%\x1b"])
def test_a_hostile_relative_u_is_a_row_error(entered):
    table = (
        "device,axis,frequency_hz,bench,direction,sensitivity,expanded_uncertainty\n"
        f"MEMS 1,X,5,linear,vertical,418.7,{entered}\n"
    ).encode()
    with pytest.raises(ImportErrors) as err:
        parse_table(table, filename="r.csv")
    (error,) = err.value.errors
    assert error.row == 2 and error.field == "expanded_uncertainty", error


def test_hostile_reminder_days_are_refused_on_the_settings_form(round_, client):
    comparison, coordinator = round_
    client.force_login(coordinator)
    for bad in ("7,\x00", "1e308", "-1", "7," * 10_000):
        page = client.post(
            "/coordinator/HOSTILE-01/edit/",
            {"code": "HOSTILE-01", "title": "t", "reminder_days": bad,
             "assigned_value_method": "weighted_mean", "sigma_pt_mode": "none", "en_limit": 1},
        )  # fmt: skip
        assert page.status_code in (200, 400), (bad[:20], page.status_code)
        assert Comparison.objects.get(pk=comparison.pk).reminder_days in ("", "7,1"), bad[:20]


# --- enrolment: an application's scope, note and the coordinator's reason ------------------


@pytest.fixture
def call(needs_postgres):
    from tests.labs.test_enrolment import Call

    return Call()


APPLY = "/api/v1/comparisons/IMU-CALL/applications/"


@pytest.mark.parametrize(
    ("body", "field"),
    [
        ({"scope": {"benches": ["linear\x00"]}}, "benches"),
        ({"scope": {"axes": ["\x1b[31mX"]}}, "axes"),
        ({"scope": {"devices": ["MEMS\x001"]}}, "devices"),
        ({"scope": {"frequencies_hz": [1e-300]}}, "frequencies_hz"),
        ({"scope": {"frequencies_hz": [1e308]}}, "frequencies_hz"),
        ({"note": "bench\x00note"}, "note"),
    ],
)
def test_a_hostile_application_is_a_400_naming_it_and_stores_nothing(call, body, field):
    from labs.models import Enrolment, Notice

    response = call.key().post(APPLY, body, format="json")
    assert response.status_code == 400, response.content
    assert field in json.dumps(response.json()["errors"]), response.json()
    assert not Enrolment.objects.exists()
    assert not Notice.objects.exists()


def test_a_million_wide_application_is_refused_in_bounded_time(call):
    from labs.models import Enrolment

    wide = [5.0 + i * 1e-3 for i in range(1_000_000)]
    started = time.monotonic()
    response = call.key().post(APPLY, {"scope": {"frequencies_hz": wide}}, format="json")
    elapsed = time.monotonic() - started
    assert response.status_code in (400, 413), response.status_code
    assert elapsed < 30, f"{elapsed:.1f} s for one request"
    assert len(response.content) < 1_000_000
    assert not Enrolment.objects.exists()


def test_a_decline_reason_with_a_nul_is_a_400_and_decides_nothing(call):
    from labs.models import Enrolment, Notice

    application = call.apply(notify=False)
    client = api(call.coordinator)
    response = client.post(f"{APPLY}{application.pk}/decline/", {"reason": "full\x00"},
                           format="json")  # fmt: skip
    assert response.status_code == 400, response.content
    assert response.json()["errors"][0]["field"] == "reason"
    assert Enrolment.objects.get().status == Enrolment.Status.PENDING
    assert not Notice.objects.filter(kind=Notice.Kind.DECLINED).exists()


def test_the_same_acceptance_twice_at_once_makes_one_participant(call):
    from labs.models import Enrolment

    application = call.apply(notify=False)
    url = f"{APPLY}{application.pk}/accept/"
    a, b = at_once(*(lambda: api(call.coordinator).post(url, {}, format="json") for _ in range(2)))
    assert sorted(r.status_code for r in (a, b)) == [201, 409], (a.content, b.content)
    (participant,) = Participant.objects.filter(comparison=call.comparison)
    assert participant.laboratory == call.lab and participant.scope_benches == ["linear"]
    assert Enrolment.objects.get().status == Enrolment.Status.ACCEPTED
