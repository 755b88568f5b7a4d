"""The landing page lists only the comparisons the visitor may see."""

import pytest

from labs.services import participant_add
from tests.factories import ComparisonFactory, MembershipFactory, UserFactory

pytestmark = pytest.mark.django_db


def test_anonymous_sees_no_comparison(client):
    ComparisonFactory.create(code="SECRET-ROUND")
    response = client.get("/")
    assert response.status_code == 200
    assert b"SECRET-ROUND" not in response.content
    assert b"sign in" in response.content


def test_lab_member_sees_only_its_comparisons(client):
    mine = ComparisonFactory.create(code="MINE-01")
    ComparisonFactory.create(code="OTHER-01")
    member = MembershipFactory.create()
    participant_add(comparison=mine, laboratory=member.laboratory)
    client.force_login(member.user)
    body = client.get("/").content
    assert b"MINE-01" in body and b"OTHER-01" not in body


def test_coordinator_sees_coordinated(client):
    coordinated = ComparisonFactory.create(code="COORD-01")
    ComparisonFactory.create(code="NOPE-01")
    user = UserFactory.create()
    coordinated.coordinators.add(user)
    client.force_login(user)
    body = client.get("/").content
    assert b"COORD-01" in body and b"NOPE-01" not in body
