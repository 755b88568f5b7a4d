"""The coordinator's comparison page lists every participant in a plain table (paginated
beyond 50)."""

from __future__ import annotations

import re

import pytest

from tests.factories import ComparisonFactory, LaboratoryFactory, ParticipantFactory, UserFactory

pytestmark = pytest.mark.django_db


@pytest.fixture
def coordinator():
    return UserFactory.create(username="panel-coordinator")


def round_with(coordinator, n: int):
    comparison = ComparisonFactory.create()
    comparison.coordinators.add(coordinator)
    for i in range(n):
        lab = LaboratoryFactory.create(name=f"Panel lab {i:03d}")
        ParticipantFactory.create(comparison=comparison, laboratory=lab, code=f"L{i + 1:03d}")
    return comparison


def participant_codes(page: str) -> list[str]:
    table = page.split('id="participants"')[1].split("</table>")[0]
    return re.findall(r'<td data-label="Code"><code>(L\d+)</code></td>', table)


def test_every_participant_in_a_plain_table(client, coordinator):
    comparison = round_with(coordinator, 12)
    client.force_login(coordinator)
    response = client.get(f"/coordinator/{comparison.code}/")
    assert response.status_code == 200
    page = response.content.decode()
    assert participant_codes(page) == [f"L{i:03d}" for i in range(1, 13)]
    # no box of fixed height that hides rows behind an invisible scrollbar
    assert "scroll-box" not in page and "overflow" not in page
    assert 'aria-label="Pages"' not in page.split('id="participants"')[1].split('id="notices"')[0]


def test_participants_beyond_fifty_are_paginated(client, coordinator):
    comparison = round_with(coordinator, 51)
    client.force_login(coordinator)
    first = client.get(f"/coordinator/{comparison.code}/").content.decode()
    assert participant_codes(first) == [f"L{i:03d}" for i in range(1, 51)]
    assert "Page 1 of 2" in first and 'href="?page=2"' in first
    assert '<span class="badge text-bg-light border">51</span>' in first
    second = client.get(f"/coordinator/{comparison.code}/?page=2").content.decode()
    assert participant_codes(second) == ["L051"]
    assert client.get(f"/coordinator/{comparison.code}/?page=x").status_code == 200
    last = client.get(f"/coordinator/{comparison.code}/?page=9").content.decode()
    assert participant_codes(last) == ["L051"]
