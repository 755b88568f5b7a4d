"""Inviting laboratories through the coordinator page and the setup API: one service,
all or none in one transaction (docs/architecture.md §2)."""

import pytest
from django.test import Client
from rest_framework.test import APIClient

from common.errors import StateConflict
from labs import services
from labs.models import Participant
from tests.factories import ComparisonFactory, LaboratoryFactory, UserFactory

pytestmark = pytest.mark.django_db
CODE = "INV-01"


@pytest.fixture
def setup():
    comparison = ComparisonFactory.create(code=CODE)
    coordinator = UserFactory.create(username="coord")
    comparison.coordinators.add(coordinator)
    labs = [LaboratoryFactory.create(name=f"Lab {i}") for i in range(3)]
    return comparison, coordinator, labs


@pytest.fixture
def second_code_fails(monkeypatch):
    """The code of the second laboratory cannot be allocated (after the first is stored)."""
    real, calls = services.participant_code_new, []

    def code_new(*, comparison):
        calls.append(comparison)
        if len(calls) == 2:
            raise StateConflict(f"Comparison {comparison.code} has no participant codes left.")
        return real(comparison=comparison)

    monkeypatch.setattr(services, "participant_code_new", code_new)


def web_client(user):
    client = Client()
    client.force_login(user)
    return client


def api_client(user):
    client = APIClient()
    client.force_authenticate(user)
    return client


def test_a_failure_half_way_stores_none_on_the_web(setup, second_code_fails):
    comparison, coordinator, labs = setup
    body = {"laboratories": [lab.pk for lab in labs]}
    response = web_client(coordinator).post(f"/coordinator/{CODE}/participants/invite/", body)
    assert response.status_code == 200
    errors = response.context["form"].non_field_errors()
    assert errors == [f"Comparison {CODE} has no participant codes left."]
    assert not Participant.objects.filter(comparison=comparison).exists()


def test_a_failure_half_way_stores_none_in_the_api(setup, second_code_fails):
    comparison, coordinator, labs = setup
    body = {"laboratories": [lab.name for lab in labs]}
    response = api_client(coordinator).post(
        f"/api/v1/comparisons/{CODE}/participants/", body, format="json"
    )
    assert response.status_code == 409, response.content
    assert response.json() == {
        "detail": f"Comparison {CODE} has no participant codes left.",
        "errors": [],
    }
    assert not Participant.objects.filter(comparison=comparison).exists()


def test_an_unknown_laboratory_stores_none(setup):
    comparison, coordinator, labs = setup
    web = web_client(coordinator).post(
        f"/coordinator/{CODE}/participants/invite/", {"laboratories": [labs[0].pk, 999999]}
    )
    assert web.status_code == 200
    assert web.context["form"].errors["laboratories"] == [
        "Select a valid choice. 999999 is not one of the available choices."
    ]
    api = api_client(coordinator).post(
        f"/api/v1/comparisons/{CODE}/participants/",
        {"laboratories": ["Lab 0", "No such lab"]},
        format="json",
    )
    assert api.status_code == 400
    assert api.json()["detail"] == "Unknown laboratories: No such lab."
    assert not Participant.objects.filter(comparison=comparison).exists()


def test_all_invited_with_random_codes(setup):
    comparison, _, labs = setup
    added = services.participants_invite(comparison=comparison, laboratories=labs)
    assert [p.laboratory for p in added] == labs
    assert len({p.code for p in added}) == 3
    again = services.participants_invite(comparison=comparison, laboratories=labs[:1])
    assert again == added[:1]  # an existing participation is returned unchanged
