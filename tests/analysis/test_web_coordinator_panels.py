"""The coordinator's comparison page lists every participant in a plain table (paginated
beyond 50), and the invitation form offers laboratories as checkboxes with a filter and
"select all" that work without JavaScript."""

from __future__ import annotations

import re

import pytest

from labs.models import Participant
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


@pytest.fixture
def labs_to_invite():
    return [LaboratoryFactory.create(name=n) for n in
            ("Alpha Metrology", "Beta Vibration", "Gamma Metrology")]  # fmt: skip


def test_invitation_offers_checkboxes_not_a_multiselect(client, coordinator, labs_to_invite):
    comparison = round_with(coordinator, 1)
    client.force_login(coordinator)
    page = client.get(f"/coordinator/{comparison.code}/participants/invite/").content.decode()
    assert not re.search(r'<select[^>]*name="laboratories"', page)
    boxes = re.findall(r'<input type="checkbox" name="laboratories" value="(\d+)"', page)
    assert sorted(map(int, boxes)) == sorted(lab.pk for lab in labs_to_invite)
    assert all(f"{lab.name}</label>" in page for lab in labs_to_invite)
    assert "checked" not in page.split('name="laboratories"')[1].split("</fieldset>")[0]


def test_invitation_filter_and_select_all_work_without_javascript(
    client, coordinator, labs_to_invite
):
    comparison = round_with(coordinator, 1)
    client.force_login(coordinator)
    url = f"/coordinator/{comparison.code}/participants/invite/"
    found = client.get(url, {"q": "metrology"}).content.decode()
    boxes = re.findall(r'<input type="checkbox" name="laboratories" value="(\d+)"', found)
    alpha, beta, gamma = labs_to_invite
    assert sorted(map(int, boxes)) == sorted([alpha.pk, gamma.pk])
    assert "2 of 3 laboratories not yet invited match “metrology”." in found
    assert 'href="?q=metrology&amp;all=1">Select all shown</a>' in found
    # the invitation form posts with the filter kept
    assert f'action="{url}?q=metrology"' in found
    everything = client.get(url, {"q": "metrology", "all": "1"}).content.decode()
    ticked = re.findall(
        r'<input type="checkbox" name="laboratories" value="(\d+)"[^>]* checked', everything
    )
    assert sorted(map(int, ticked)) == sorted([alpha.pk, gamma.pk])
    response = client.post(f"{url}?q=metrology", {"laboratories": [alpha.pk, gamma.pk]})
    assert response.status_code == 302
    invited = Participant.objects.filter(comparison=comparison).exclude(code="L001")
    assert sorted(p.laboratory.name for p in invited) == ["Alpha Metrology", "Gamma Metrology"]
    # the invited ones are no longer offered
    again = client.get(url).content.decode()
    boxes = re.findall(r'<input type="checkbox" name="laboratories" value="(\d+)"', again)
    assert [int(b) for b in boxes] == [beta.pk]
