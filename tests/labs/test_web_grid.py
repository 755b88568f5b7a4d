"""The results grid: drafts, submission, inline errors, prefill, htmx, closed comparisons."""

import datetime as dt

import pytest
from django.urls import reverse
from django.utils import timezone

from labs.models import Result, Submission
from tests.factories import MembershipFactory, ParticipantFactory
from tests.labs.test_web import open_comparison, submitted, visible

pytestmark = pytest.mark.django_db

GRID = reverse("labs:grid", args=["CMP-G"])


@pytest.fixture
def participant():
    comparison = open_comparison("CMP-G")
    return ParticipantFactory.create(comparison=comparison, code="L55")


@pytest.fixture
def staff(client, participant):
    user = MembershipFactory.create(laboratory=participant.laboratory).user
    client.force_login(user)
    return user


def grid_rows(participant):
    """Grid order = the comparison's point order (the page shows the same order)."""
    from labs.selectors import comparison_points

    return list(comparison_points(participant.comparison).values())


def post_data(values: dict[int, dict[str, str]], action: str = "draft") -> dict[str, str]:
    data = {"action": action}
    for i, cells in values.items():
        for column, text in cells.items():
            data[f"r{i}-{column}"] = text
    return data


def full(value="420.5", u="8.4"):
    return {
        i: {"sensitivity": value, "expanded_uncertainty": u, "coverage_factor": "2"}
        for i in range(4)
    }


def test_grid_shows_one_row_per_point_with_default_k(client, staff, participant):
    body = visible(client.get(GRID))
    assert body.count('<tr id="row-') == 4
    assert body.count('value="2"') == 4  # k defaults to 2
    assert "No results stored yet" in body


def test_save_partial_draft(client, staff, participant):
    data = post_data({0: {"sensitivity": "421", "expanded_uncertainty": "8"},
                      2: {"sensitivity": "419", "expanded_uncertainty": "2%", "dof": "50",
                          "note": "mounted twice"}})  # fmt: skip
    response = client.post(GRID, data)
    assert response.status_code == 302 and response["Location"] == GRID
    submission = Submission.objects.get(participant=participant)
    assert (submission.status, submission.source, submission.submitted_by) == (
        "draft",
        "web",
        staff,
    )
    points = grid_rows(participant)
    r0 = submission.results.get(measurement_point=points[0])
    r2 = submission.results.get(measurement_point=points[2])
    assert (r0.value, r0.expanded_uncertainty, r0.coverage_factor) == (421, 8, 2)
    assert r2.expanded_uncertainty == pytest.approx(419 * 0.02) and r2.dof == 50
    assert r2.note == "mounted twice"
    body = visible(client.get(GRID))  # pre-filled from the draft
    assert 'value="421"' in body and "Editing your draft, version 1" in body
    assert "Draft saved" in body


def test_submit_complete_grid(client, staff, participant):
    response = client.post(GRID, post_data(full(), action="submit"))
    assert response.status_code == 302
    assert response["Location"] == reverse("labs:comparison", args=["CMP-G"])
    submission = Submission.objects.get(participant=participant)
    assert submission.status == "submitted" and submission.results.count() == 4


def test_partial_submit_is_refused_with_missing_points_listed(client, staff, participant):
    response = client.post(GRID, post_data({0: full()[0]}, action="submit"))
    assert response.status_code == 200
    body = visible(response)
    assert "3 measurement points have no result" in body
    assert "missing result for MEMS 1" in body
    assert body.count("result needed to submit") == 3
    assert not Submission.objects.exists()
    # the same rows are accepted as a draft
    assert client.post(GRID, post_data({0: full()[0]})).status_code == 302
    assert Submission.objects.get().status == "draft"


def test_bad_values_are_shown_inline_and_nothing_is_stored(client, staff, participant):
    values = full()
    values[1]["sensitivity"] = "-3"
    values[3]["expanded_uncertainty"] = "abc"
    response = client.post(GRID, post_data(values, action="submit"))
    assert response.status_code == 200
    body = visible(response)
    assert "Nothing was saved" in body and "2 rows need attention" in body
    assert 'id="id_r1-sensitivity-error"' in body and "must be &gt; 0, got -3" in body
    assert 'id="id_r3-expanded_uncertainty-error"' in body
    assert 'aria-invalid="true" aria-describedby="id_r1-sensitivity-error"' in body
    assert 'value="-3"' in body  # what was typed stays in the grid
    assert not Submission.objects.exists() and not Result.objects.exists()


def test_empty_grid_is_not_saved(client, staff, participant):
    response = client.post(GRID, {"action": "draft"})
    assert response.status_code == 200
    assert "Enter at least one result" in visible(response)
    assert not Submission.objects.exists()


def test_correction_starts_from_the_last_submitted_version(client, staff, participant):
    submitted(participant, value=417.25)
    body = visible(client.get(GRID))
    assert 'value="417.25"' in body and "Saving starts a correction: version 2" in body
    assert client.post(GRID, post_data(full(value="418"))).status_code == 302
    versions = dict(participant.submissions.values_list("version", "status"))
    assert versions == {1: "submitted", 2: "draft"}


def test_htmx_saves_a_draft_in_place(client, staff, participant):
    response = client.post(GRID, post_data({0: full()[0]}), HTTP_HX_REQUEST="true")
    assert response.status_code == 200
    body = visible(response)
    assert body.lstrip().startswith('<form id="grid-form"') and "<html" not in body
    assert "Draft saved (version 1, 1 result)" in body
    assert Submission.objects.get().results.count() == 1


def test_htmx_submit_redirects_the_browser(client, staff, participant):
    response = client.post(GRID, post_data(full(), action="submit"), HTTP_HX_REQUEST="true")
    assert response["HX-Redirect"] == reverse("labs:comparison", args=["CMP-G"])
    assert Submission.objects.get().status == "submitted"


def test_htmx_errors_come_back_in_the_partial(client, staff, participant):
    values = {0: {"sensitivity": "abc", "expanded_uncertainty": "8"}}
    response = client.post(GRID, post_data(values), HTTP_HX_REQUEST="true")
    assert response.status_code == 200
    assert 'id="id_r0-sensitivity-error"' in visible(response)
    assert not Submission.objects.exists()


@pytest.mark.parametrize(
    "change, reason",
    [
        ({"status": "closed"}, "is closed: results can be submitted only while it is open"),
        (
            {"submission_deadline": timezone.now() - dt.timedelta(hours=1)},
            "submission deadline of CMP-G passed",
        ),
    ],
)
def test_closed_comparison_disables_the_grid(client, staff, participant, change, reason):
    type(participant.comparison).objects.filter(pk=participant.comparison_id).update(**change)
    body = visible(client.get(GRID))
    assert reason in body
    assert 'value="submit" class="btn btn-primary" disabled' in body
    response = client.post(GRID, post_data(full(), action="submit"))
    assert reason in visible(response)
    assert not Submission.objects.exists()
