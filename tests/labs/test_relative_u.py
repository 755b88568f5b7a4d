"""A relative U is kept as the laboratory wrote it, beside the absolute value every
computation uses (docs/domain.md §3.1): grid, upload, API, checksum."""

import hashlib
import re

import pytest
from django.urls import reverse

from common.quantities import unit_text
from labs import services
from labs.importers import ImportErrors, parse_rows, parse_table
from labs.models import Result, Submission
from tests.factories import MembershipFactory, ParticipantFactory
from tests.labs.test_web import open_comparison, visible
from tests.labs.test_web_grid import grid_rows, post_data

pytestmark = pytest.mark.django_db

CODE = "CMP-REL"
GRID = reverse("labs:grid", args=[CODE])
SENSITIVITY = 418.7  # 418.7 × 1.2 / 100 is one ulp off 418.7 × 0.012


@pytest.fixture
def participant():
    return ParticipantFactory.create(comparison=open_comparison(CODE), code="L66")


@pytest.fixture
def staff(client, participant):
    user = MembershipFactory.create(laboratory=participant.laboratory).user
    client.force_login(user)
    return user


def test_grid_keeps_a_relative_u_as_entered_and_stores_the_absolute_value(
    client, staff, participant
):
    assert SENSITIVITY * 1.2 / 100 != SENSITIVITY * 0.012
    data = post_data({0: {"sensitivity": str(SENSITIVITY), "expanded_uncertainty": "1.2%"},
                      1: {"sensitivity": "419.5", "expanded_uncertainty": "5.034"}})  # fmt: skip
    assert client.post(GRID, data).status_code == 302
    submission = Submission.objects.get(participant=participant)
    points = grid_rows(participant)
    relative = submission.results.get(measurement_point=points[0])
    absolute = submission.results.get(measurement_point=points[1])
    assert relative.expanded_uncertainty == SENSITIVITY * 0.012  # exactly, every computation
    assert relative.standard_uncertainty == SENSITIVITY * 0.012 / 2
    assert relative.expanded_uncertainty_entered == "1.2 %"
    assert (absolute.expanded_uncertainty, absolute.expanded_uncertainty_entered) == (5.034, "")

    grid = visible(client.get(GRID))  # pre-filled from the draft: as entered
    assert 'name="r0-expanded_uncertainty" id="id_r0-expanded_uncertainty" value="1.2 %"' in grid
    assert 'name="r1-expanded_uncertainty" id="id_r1-expanded_uncertainty" value="5.034"' in grid

    version = visible(client.get(reverse("labs:submission", args=[CODE, 1])))
    cells = [re.sub(r"<[^>]+>", "", c).strip() for c in re.findall(r"<td[^>]*>(.*?)</td>", version)]
    unit = unit_text(relative.unit)  # as pages write it: m/s²
    assert f"1.2 % (5.0 {unit})" in cells  # 418.7 × 0.012 = 5.0244
    assert "5.0" in cells and "419.5" in cells  # the absolute one: U to two digits


def test_saving_the_prefilled_grid_again_changes_nothing(client, staff, participant):
    data = post_data({0: {"sensitivity": str(SENSITIVITY), "expanded_uncertainty": "1.2%"}})
    client.post(GRID, data)
    first = Submission.objects.get(participant=participant)
    again = post_data({0: {"sensitivity": str(SENSITIVITY), "expanded_uncertainty": "1.2 %"}})
    client.post(GRID, again)  # the grid's own text, saved again: the same draft
    assert Submission.objects.get(participant=participant).pk == first.pk
    assert Submission.objects.get().content_sha256 == first.content_sha256


def test_upload_and_api_rows_keep_the_text():
    [row] = parse_rows(
        [{"device": "MEMS 1", "axis": "X", "frequency_hz": 5, "bench": "linear",
          "sensitivity": SENSITIVITY, "expanded_uncertainty": " 1.20  %"}]
    )  # fmt: skip
    assert row.expanded_uncertainty == SENSITIVITY * 0.012
    assert row.expanded_uncertainty_entered == "1.20 %"  # the digits as typed
    [plain] = parse_rows(
        [{"device": "MEMS 1", "axis": "X", "frequency_hz": 5, "bench": "linear",
          "sensitivity": SENSITIVITY, "expanded_uncertainty": 5.0244}]
    )  # fmt: skip
    assert plain.expanded_uncertainty_entered == ""


def test_a_file_keeps_the_text_too():
    data = (
        b"device,axis,frequency_hz,bench,sensitivity,expanded_uncertainty\n"
        b"MEMS 1,X,5,linear,418.7,1.2%\n"
    )
    [row] = parse_table(data, filename="results.csv")
    assert (row.expanded_uncertainty, row.expanded_uncertainty_entered) == (418.7 * 0.012, "1.2 %")


def test_a_percentage_too_long_to_keep_is_refused_naming_its_cell():
    text = "1." + "0" * 40 + "%"
    with pytest.raises(ImportErrors) as caught:
        parse_rows(
            [{"device": "MEMS 1", "axis": "X", "frequency_hz": 5, "bench": "linear",
              "sensitivity": SENSITIVITY, "expanded_uncertainty": text}]
        )  # fmt: skip
    [error] = caught.value.as_dicts()
    assert (error["row"], error["field"]) == (1, "expanded_uncertainty")
    assert error["message"] == ("a percentage is kept as written: at most 40 characters, got 44")


def test_api_submission_stores_the_text_through_the_bulk_insert(participant, staff):
    row = {"device": "MEMS 1", "axis": "Y", "frequency_hz": 10, "bench": "linear",
           "sensitivity": SENSITIVITY, "expanded_uncertainty": "0.7%"}  # fmt: skip
    saved = services.submission_from_records(
        participant=participant, records=[row], source="api", user=staff, submit=False
    )
    result = Result.objects.get(submission=saved)
    assert result.expanded_uncertainty == SENSITIVITY * 0.007  # 0.7 / 100 is not 0.007
    assert result.expanded_uncertainty_entered == "0.7 %"


def test_checksum_of_an_absolute_u_is_the_one_stored_before_the_text_was_kept():
    """An old submission (absolute U) sent again still matches its stored checksum."""
    values = [(7, 419.5, "mV/(m/s²)", 5.034, 2.0, None, "", None, None, "", None)]
    old = hashlib.sha256(repr((7, 419.5, "mV/(m/s²)", 5.034, 2.0, None, "", None, None)).encode())
    old.update(b"\n")
    assert services._content_sha256(values) == old.hexdigest()
    relative = [(*values[0][:-2], "1.2 %", None)]
    assert services._content_sha256(relative) != old.hexdigest()  # what was entered counts
