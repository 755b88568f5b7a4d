"""The results grid with a phase point (docs/domain.md §12): the row says what it measures and
in which unit, and what is typed there is stored as that point's result, wrapped."""

import pytest
from django.urls import reverse

from labs.models import Result, Submission
from tests.factories import MeasurementPointFactory, MembershipFactory, ParticipantFactory
from tests.labs.test_web import open_comparison, visible
from tests.labs.test_web_grid import grid_rows, post_data

pytestmark = pytest.mark.django_db

GRID = reverse("labs:grid", args=["CMP-Q"])


@pytest.fixture
def participant(client):
    comparison = open_comparison("CMP-Q")
    device = comparison.devices.get()
    MeasurementPointFactory.create(comparison=comparison, device=device, axis="X",
                                   frequency_hz=5.0, quantity="phase")  # fmt: skip
    p = ParticipantFactory.create(comparison=comparison, code="L56")
    client.force_login(MembershipFactory.create(laboratory=p.laboratory).user)
    return p


def test_the_phase_row_names_its_kind_and_unit_and_stores_the_phase_wrapped(client, participant):
    body = visible(client.get(GRID))
    assert body.count('<tr id="row-') == 5
    assert "sensitivity phase" in body and "· °" in body
    assert "· D/(m/s²)" in body  # the magnitudes keep the device's unit, written m/s²
    rows = grid_rows(participant)
    at = next(i for i, p in enumerate(rows) if p.quantity == "phase")
    magnitude = next(i for i, p in enumerate(rows) if p.quantity == "magnitude")
    data = post_data({at: {"sensitivity": "190", "expanded_uncertainty": "0.5"},
                      magnitude: {"sensitivity": "419", "expanded_uncertainty": "2%"}})  # fmt: skip
    assert client.post(GRID, data).status_code == 302
    submission = Submission.objects.get(participant=participant)
    stored = {r.measurement_point.quantity: (r.value, r.unit, r.expanded_uncertainty)
              for r in Result.objects.filter(submission=submission)}  # fmt: skip
    assert stored["phase"] == (-170.0, "deg", 0.5)
    assert stored["magnitude"] == (419.0, "D/(m/s^2)", pytest.approx(8.38))


def test_a_percentage_u_on_the_phase_row_is_named_on_that_row(client, participant):
    rows = grid_rows(participant)
    at = next(i for i, p in enumerate(rows) if p.quantity == "phase")
    data = post_data({at: {"sensitivity": "10", "expanded_uncertainty": "1%"}})
    body = visible(client.post(GRID, data))
    assert "a phase&#x27;s U is given in deg, not as a percentage" in body or (
        "a phase's U is given in deg, not as a percentage" in body
    )
    assert not Submission.objects.filter(participant=participant).exists()
