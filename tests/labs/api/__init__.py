"""Shared world for the API tests: named personas, two laboratories, three comparisons.

* ``cmp`` (open, deadline in a week): only lab A takes part, coordinated by ``coord``;
  lab A has a submitted version 1 with distinctive values.
* ``other``: only lab B takes part, coordinated by ``coord_other``.
* ``shared``: labs A and B both take part (for the "nothing of A reaches B" checks).
"""

from __future__ import annotations

import datetime as dt
from dataclasses import dataclass, field

from django.contrib.auth.models import User
from django.utils import timezone
from rest_framework.test import APIClient

from labs.models import Laboratory, Membership, Participant
from labs.services import api_key_create, api_key_revoke, submission_from_records
from proficiency.models import Comparison
from proficiency.services import measurement_points_generate
from tests.factories import (
    ComparisonFactory,
    DeviceFactory,
    LaboratoryFactory,
    MembershipFactory,
    ParticipantFactory,
    UserFactory,
)

LAB_A_NAME = "Alpha Vibration Laboratory"
LAB_B_NAME = "Bravo Metrology Institute"
# Values only lab A ever reports; they must never appear in an answer to lab B.
A_VALUES = (421.987654, 8.123456)
PERSONAS = (
    "anonymous",
    "staff_a",
    "staff_b",
    "manager_a",
    "coord",
    "coord_other",
    "key_a",
    "revoked_key_a",
    "admin",
)


def rows(value: float = 420.5, u: object = 8.4, axes=("X", "Y"), **extra) -> list[dict]:
    """Complete JSON rows for a comparison built by :func:`open_comparison`."""
    return [
        {"device": "MEMS 1", "axis": a, "frequency_hz": f, "bench": "linear",
         "sensitivity": value, "expanded_uncertainty": u, **extra}
        for a in axes for f in (5, 10)
    ]  # fmt: skip


def as_csv(records: list[dict]) -> bytes:
    names = list(dict.fromkeys(k for r in records for k in r))
    lines = [",".join(names)]
    lines += [",".join(str(r.get(n, "")) for n in names) for r in records]
    return ("\n".join(lines) + "\n").encode()


def open_comparison(code: str, coordinator=None, **kwargs):
    comparison = ComparisonFactory.create(
        code=code,
        status="open",
        submission_deadline=timezone.now() + dt.timedelta(days=7),
        protocol="custom",
        **kwargs,
    )
    device = DeviceFactory.create(comparison=comparison, name="MEMS 1", unit="D/(m/s^2)")
    measurement_points_generate(
        comparison=comparison, devices=[device], axes=["X", "Y"], frequencies_hz=[5, 10],
        benches=["linear"],
    )  # fmt: skip
    if coordinator is not None:
        comparison.coordinators.add(coordinator)
    return comparison


@dataclass
class World:
    users: dict[str, User] = field(default_factory=dict)
    keys: dict[str, str] = field(default_factory=dict)
    # set by build_world
    lab_a: Laboratory = field(init=False)
    lab_b: Laboratory = field(init=False)
    cmp: Comparison = field(init=False)
    other: Comparison = field(init=False)
    shared: Comparison = field(init=False)
    part_a: Participant = field(init=False)
    shared_a: Participant = field(init=False)
    shared_b: Participant = field(init=False)

    def client(self, persona: str) -> APIClient:
        client = APIClient()
        if persona in self.keys:
            client.credentials(HTTP_AUTHORIZATION=f"Api-Key {self.keys[persona]}")
        elif persona in self.users:
            client.force_authenticate(None)
            client.force_login(self.users[persona])
        return client


def build_world() -> World:
    w = World()
    w.lab_a = LaboratoryFactory.create(name=LAB_A_NAME)
    w.lab_b = LaboratoryFactory.create(name=LAB_B_NAME)
    w.users["staff_a"] = MembershipFactory.create(laboratory=w.lab_a, user__username="alice").user
    w.users["manager_a"] = MembershipFactory.create(
        laboratory=w.lab_a, user__username="mario", role=Membership.Role.MANAGER
    ).user
    w.users["staff_b"] = MembershipFactory.create(laboratory=w.lab_b, user__username="bob").user
    w.users["coord"] = UserFactory.create(username="carla")
    w.users["coord_other"] = UserFactory.create(username="otto")
    w.users["admin"] = UserFactory.create(username="root", is_superuser=True, is_staff=True)

    w.cmp = open_comparison("IMU-A-01", coordinator=w.users["coord"])
    w.part_a = ParticipantFactory.create(comparison=w.cmp, laboratory=w.lab_a, code="L17")
    w.other = open_comparison("IMU-B-01", coordinator=w.users["coord_other"])
    ParticipantFactory.create(comparison=w.other, laboratory=w.lab_b, code="L05")
    w.shared = open_comparison("IMU-AB-01", coordinator=w.users["coord"])
    w.shared_a = ParticipantFactory.create(comparison=w.shared, laboratory=w.lab_a, code="L71")
    w.shared_b = ParticipantFactory.create(comparison=w.shared, laboratory=w.lab_b, code="L32")

    value, u = A_VALUES
    for participant in (w.part_a, w.shared_a):
        submission_from_records(
            participant=participant, records=rows(value, u), source="api",
            user=w.users["staff_a"], submit=True,
        )  # fmt: skip
    w.keys["key_a"] = api_key_create(laboratory=w.lab_a, name="LabSoft", user=None)[1]
    revoked, w.keys["revoked_key_a"] = api_key_create(laboratory=w.lab_a, name="old", user=None)
    api_key_revoke(key=revoked)
    w.keys["key_b"] = api_key_create(laboratory=w.lab_b, name="BravoSoft", user=None)[1]
    return w
