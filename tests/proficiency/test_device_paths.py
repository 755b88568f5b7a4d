"""Adding a device through the coordinator page and the setup API: one service, one rule
for the name (docs/architecture.md §2), so the same bad name gets the same refusal."""

import pytest
from django.test import Client
from rest_framework.test import APIClient

from common.errors import ValidationFailed
from proficiency.models import Device
from proficiency.services import device_create, device_update
from tests.factories import ComparisonFactory, DeviceFactory, UserFactory

pytestmark = pytest.mark.django_db
CODE = "DEV-01"
LONG = "M" * 81


@pytest.fixture
def comparison():
    c = ComparisonFactory.create(code=CODE)
    c.coordinators.add(UserFactory.create(username="coord"))
    DeviceFactory.create(comparison=c, name="MEMS 1")
    return c


def web(comparison, name):
    client = Client()
    client.force_login(comparison.coordinators.get())
    body = {"name": name, "unit": "mV/(m/s^2)", "tolerance_distribution": "rectangular"}
    response = client.post(f"/coordinator/{CODE}/devices/new/", body)
    assert response.status_code == 200, response.status_code
    return response.context["form"].errors["name"]


def api(comparison, name):
    client = APIClient()
    client.force_authenticate(comparison.coordinators.get())
    response = client.post(f"/api/v1/comparisons/{CODE}/devices/", {"name": name}, format="json")
    assert response.status_code == 400, response.content
    body = response.json()
    assert [e["field"] for e in body["errors"]] == ["name"]
    assert body["errors"][0]["message"] == body["detail"]
    return [body["detail"]]


@pytest.mark.parametrize(
    ("name", "message"),
    [
        ("", f"A device of {CODE} needs a name."),
        ("   ", f"A device of {CODE} needs a name."),
        (LONG, "The device name is 81 characters long; at most 80."),
        ("MEMS 1", f"{CODE} already has a device named 'MEMS 1'."),
        ("  MEMS 1 ", f"{CODE} already has a device named 'MEMS 1'."),
    ],
)
def test_same_bad_name_same_refusal_on_web_and_api(comparison, name, message):
    assert web(comparison, name) == [message]
    assert api(comparison, name) == [message]
    assert list(comparison.devices.values_list("name", flat=True)) == ["MEMS 1"]


def test_name_stripped_on_both_paths(comparison):
    client = Client()
    client.force_login(comparison.coordinators.get())
    body = {"name": "  MEMS 2 ", "unit": "u", "tolerance_distribution": "rectangular"}
    assert client.post(f"/coordinator/{CODE}/devices/new/", body).status_code == 302
    api_client = APIClient()
    api_client.force_authenticate(comparison.coordinators.get())
    r = api_client.post(f"/api/v1/comparisons/{CODE}/devices/", {"name": " MEMS 3  "})
    assert r.status_code == 201 and r.json()["name"] == "MEMS 3"
    assert sorted(comparison.devices.values_list("name", flat=True)) == [
        "MEMS 1", "MEMS 2", "MEMS 3",
    ]  # fmt: skip


def test_non_positive_sensitivity_refused_on_the_web_with_a_field_error(comparison):
    client = Client()
    client.force_login(comparison.coordinators.get())
    body = {"name": "MEMS 2", "unit": "u", "nominal_sensitivity": "-1",
            "tolerance_distribution": "rectangular"}  # fmt: skip
    response = client.post(f"/coordinator/{CODE}/devices/new/", body)
    assert response.status_code == 200
    errors = response.context["form"].errors["nominal_sensitivity"]
    assert errors == ["must be a finite number > 0, got -1.0"]
    assert not comparison.devices.filter(name="MEMS 2").exists()


def test_device_update_keeps_the_name_rule(comparison):
    other = device_create(comparison=comparison, name=" MEMS 2 ", model="LSM6DSR")
    assert (other.name, other.model, other.unit) == ("MEMS 2", "LSM6DSR", "D/(m/s^2)")
    with pytest.raises(ValidationFailed, match="already has a device named 'MEMS 1'"):
        device_update(device=other, name="MEMS 1 ")
    with pytest.raises(ValidationFailed, match="tolerance: must be a finite number > 0"):
        device_update(device=other, tolerance=float("inf"))
    updated = device_update(device=other, name="MEMS 2", serial="42")  # its own name is fine
    assert (updated.name, updated.serial) == ("MEMS 2", "42")
    assert Device.objects.get(pk=other.pk).serial == "42"
