"""The grid's optional repeatability inputs (repeat_sd with n_repeats) and the version page."""

import pytest
from django.urls import reverse

from labs.models import Submission
from tests.labs.test_web import visible
from tests.labs.test_web_grid import GRID, grid_rows, participant, post_data, staff

pytestmark = pytest.mark.django_db
__all__ = ["participant", "staff"]  # fixtures


def test_draft_with_repeats_is_stored_prefilled_and_shown(client, staff, participant):
    data = post_data({0: {"sensitivity": "421", "expanded_uncertainty": "8",
                          "repeat_sd": "0.42", "n_repeats": "5"},
                      1: {"sensitivity": "420", "expanded_uncertainty": "8"}})  # fmt: skip
    assert client.post(GRID, data).status_code == 302
    submission = Submission.objects.get(participant=participant)
    points = grid_rows(participant)
    r0 = submission.results.get(measurement_point=points[0])
    r1 = submission.results.get(measurement_point=points[1])
    assert (r0.repeat_sd, r0.n_repeats) == (0.42, 5)
    assert (r1.repeat_sd, r1.n_repeats) == (None, None)
    body = visible(client.get(GRID))
    assert 'name="r0-repeat_sd" id="id_r0-repeat_sd" value="0.42"' in body
    assert 'name="r0-n_repeats" id="id_r0-n_repeats" value="5"' in body
    page = visible(client.get(reverse("labs:submission", args=["CMP-G", 1])))
    assert '<td data-label="s">0.42</td>' in page and '<td data-label="n">5</td>' in page


def test_count_without_deviation_is_shown_next_to_the_input(client, staff, participant):
    data = post_data({0: {"sensitivity": "421", "expanded_uncertainty": "8", "n_repeats": "3"}})
    body = visible(client.post(GRID, data))
    assert "Nothing was saved." in body
    assert (
        '<div id="id_r0-repeat_sd-error" class="invalid-feedback">is required when n_repeats is '
        "given: the within-laboratory standard deviation and its number of repeats go together"
    ) in body
    assert not Submission.objects.filter(participant=participant).exists()


def test_a_row_with_only_repeat_data_is_not_blank(client, staff, participant):
    body = visible(client.post(GRID, post_data({3: {"repeat_sd": "0.4", "n_repeats": "4"}})))
    assert '<div id="id_r3-sensitivity-error" class="invalid-feedback">is required' in body
