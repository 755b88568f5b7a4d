"""``reminder_days`` in the comparison API (docs/interfaces.md §3): read on a comparison's
detail, written when a coordinator creates one, a list of distinct whole days."""

from __future__ import annotations

import pytest
from django.contrib.auth.models import Permission
from rest_framework.test import APIClient

from proficiency.models import Comparison
from tests.factories import ComparisonFactory, UserFactory

pytestmark = pytest.mark.django_db


@pytest.fixture
def api():
    user = UserFactory.create(username="days-coordinator")
    user.user_permissions.add(Permission.objects.get(codename="add_comparison"))
    client = APIClient()
    client.force_authenticate(user)
    return client


def create(api, **extra):
    return api.post(
        "/api/v1/comparisons/", {"code": "IMU-DAYS", "title": "Days", **extra}, format="json"
    )


def test_detail_reads_the_days_as_a_list(api):
    comparison = ComparisonFactory.create(reminder_days="14, 7,1")
    comparison.coordinators.add(api.handler._force_user)
    response = api.get(f"/api/v1/comparisons/{comparison.code}/")
    assert response.status_code == 200
    assert response.json()["reminder_days"] == [1, 7, 14]
    Comparison.objects.filter(pk=comparison.pk).update(reminder_days="")
    assert api.get(f"/api/v1/comparisons/{comparison.code}/").json()["reminder_days"] == []


def test_created_with_days_stored_and_answered(api):
    response = create(api, reminder_days=[3, 30, 1])
    assert response.status_code == 201, response.json()
    assert response.json()["reminder_days"] == [1, 3, 30]
    assert Comparison.objects.get(code="IMU-DAYS").reminder_days == "30,3,1"
    detail = api.get("/api/v1/comparisons/IMU-DAYS/").json()
    assert detail["reminder_days"] == [1, 3, 30]


def test_created_without_days_gets_the_default_and_empty_means_none(api):
    response = create(api)
    assert response.status_code == 201
    assert response.json()["reminder_days"] == [1, 7]
    assert Comparison.objects.get(code="IMU-DAYS").reminder_days == "7,1"
    none = api.post("/api/v1/comparisons/", {"code": "IMU-NONE", "title": "None",
                                             "reminder_days": []}, format="json")  # fmt: skip
    assert none.status_code == 201 and none.json()["reminder_days"] == []
    assert Comparison.objects.get(code="IMU-NONE").reminder_days == ""


@pytest.mark.parametrize(
    "days",
    [
        [7, 7],
        [0],
        [-1],
        [366],
        [1.5],
        ["x"],
        list(range(1, 12)),
        "7,1",
        7,
        {"days": 7},
        [None],
        [True],
    ],
)
def test_bad_days_are_refused_with_400_and_nothing_stored(api, days):
    response = create(api, reminder_days=days)
    assert response.status_code == 400, response.json()
    assert "reminder_days" in str(response.json())
    assert not Comparison.objects.filter(code="IMU-DAYS").exists()


def test_ten_distinct_days_up_to_a_year_are_accepted(api):
    days = [365, 200, 100, 60, 30, 14, 7, 3, 2, 1]
    response = create(api, reminder_days=days)
    assert response.status_code == 201, response.json()
    assert response.json()["reminder_days"] == sorted(days)
