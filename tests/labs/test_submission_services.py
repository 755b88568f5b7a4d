"""The one submission path (grid, upload, API): atomic, versioned, deadline- and state-aware."""

import datetime as dt

import pytest
from django.utils import timezone

from common.errors import StateConflict, ValidationFailed
from labs.models import Result, Submission
from labs.services import submission_from_file, submission_from_records
from proficiency.services import measurement_points_generate
from tests.factories import ComparisonFactory, DeviceFactory, ParticipantFactory, UserFactory

pytestmark = pytest.mark.django_db


@pytest.fixture
def setup():
    comparison = ComparisonFactory.create(status="open")
    device = DeviceFactory.create(comparison=comparison, name="MEMS 1")
    measurement_points_generate(
        comparison=comparison, devices=[device], axes=["X", "Y"], frequencies_hz=[5, 10],
        benches=["linear"],
    )  # fmt: skip
    participant = ParticipantFactory.create(comparison=comparison)
    return participant, UserFactory.create()


def rows(n_axes=("X", "Y"), value=420.0, **extra):
    return [
        {"device": "MEMS 1", "axis": a, "frequency_hz": f, "bench": "linear",
         "sensitivity": value, "expanded_uncertainty": 8.4, **extra}
        for a in n_axes for f in (5, 10)
    ]  # fmt: skip


def test_complete_submission_is_stored_and_submitted(setup):
    participant, user = setup
    sub = submission_from_records(
        participant=participant, records=rows(), source="api", user=user, submit=True
    )
    assert (sub.version, sub.status, sub.source) == (1, "submitted", "api")
    assert sub.submitted_at is not None and sub.submitted_by == user
    assert sub.results.count() == 4
    r = sub.results.get(measurement_point__axis="Y", measurement_point__frequency_hz=10)
    assert (r.value, r.expanded_uncertainty, r.coverage_factor) == (420.0, 8.4, 2.0)
    assert r.standard_uncertainty == pytest.approx(4.2)


def test_partial_results_only_as_draft(setup):
    participant, user = setup
    with pytest.raises(ValidationFailed) as err:
        submission_from_records(
            participant=participant, records=rows(("X",)), source="web", user=user, submit=True
        )
    assert "2 measurement points have no result" in err.value.message
    assert {e["message"] for e in err.value.errors} == {
        "missing result for MEMS 1, Y, 5 Hz, linear vertical",
        "missing result for MEMS 1, Y, 10 Hz, linear vertical",
    }
    assert Submission.objects.count() == 0
    draft = submission_from_records(
        participant=participant, records=rows(("X",)), source="web", user=user, submit=False
    )
    assert (draft.status, draft.results.count()) == ("draft", 2)
    # saving the draft again replaces its results, same version
    again = submission_from_records(
        participant=participant, records=rows(value=421.0), source="web", user=user, submit=False
    )
    assert again.pk == draft.pk and again.results.count() == 4
    assert set(again.results.values_list("value", flat=True)) == {421.0}
    final = submission_from_records(
        participant=participant, records=rows(value=422.0), source="web", user=user, submit=True
    )
    assert final.pk == draft.pk and final.status == "submitted" and final.version == 1


def test_one_bad_row_stores_nothing_and_lists_every_bad_row(setup):
    participant, user = setup
    records = rows()
    records[1]["expanded_uncertainty"] = -3
    records[3]["axis"] = "Z"
    with pytest.raises(ValidationFailed) as err:
        submission_from_records(
            participant=participant, records=records, source="api", user=user, submit=True
        )
    by_row = {(e["row"], e["field"]) for e in err.value.errors}
    assert (2, "expanded_uncertainty") in by_row and (4, "axis") in by_row
    assert Submission.objects.count() == 0 and Result.objects.count() == 0


def test_correction_is_a_new_version_and_old_is_kept(setup):
    participant, user = setup
    v1 = submission_from_records(
        participant=participant, records=rows(), source="api", user=user, submit=True
    )
    v2 = submission_from_records(
        participant=participant, records=rows(value=425.0), source="api", user=user, submit=True
    )
    assert (v1.version, v2.version) == (1, 2)
    v1.refresh_from_db()
    assert set(v1.results.values_list("value", flat=True)) == {420.0}
    assert set(v2.results.values_list("value", flat=True)) == {425.0}


def test_file_upload_same_rules(setup):
    participant, user = setup
    csv = (
        "device;axis;frequency_hz;bench;sensitivity;expanded_uncertainty\n"
        "MEMS 1;X;5;linear;420,5;1%\n"
        "mems 1;X;10;linear;0,2392;1%;\n"
    )
    with pytest.raises(ValidationFailed):
        submission_from_file(
            participant=participant, data=csv.encode(), filename="r.csv", user=user, submit=True
        )
    good = (
        "device;axis;frequency_hz;bench;sensitivity;unit;expanded_uncertainty\n"
        "MEMS 1;X;5;linear;420,5;;1%\n"
        "mems 1;X;10;linear;0,2392;mg/LSB;1%\n"
    )
    sub = submission_from_file(
        participant=participant, data=good.encode(), filename="r.csv", user=user, submit=False
    )
    values = dict(sub.results.values_list("measurement_point__frequency_hz", "value"))
    assert values[5.0] == 420.5
    assert values[10.0] == pytest.approx(1 / (0.2392e-3 * 9.80665), rel=1e-12)
    r10 = sub.results.get(measurement_point__frequency_hz=10.0)
    assert r10.expanded_uncertainty == pytest.approx(0.01 * r10.value, rel=1e-12)
    assert sub.source == "file"


def test_lab_column_is_refused_for_participants(setup):
    participant, user = setup
    with pytest.raises(ValidationFailed) as err:
        submission_from_records(
            participant=participant, records=rows(lab="L99"), source="api", user=user,
            submit=True,
        )  # fmt: skip
    assert any(e["field"] == "lab" for e in err.value.errors)


@pytest.mark.parametrize("status", ["draft", "closed", "analysed", "published"])
def test_only_open_comparisons_take_results(setup, status):
    participant, user = setup
    participant.comparison.status = status
    participant.comparison.save()
    with pytest.raises(StateConflict, match=f"is {status}"):
        submission_from_records(
            participant=participant, records=rows(), source="api", user=user, submit=True
        )
    assert Submission.objects.count() == 0


def test_deadline_passed_is_a_conflict(setup):
    participant, user = setup
    participant.comparison.submission_deadline = timezone.now() - dt.timedelta(minutes=1)
    participant.comparison.save()
    with pytest.raises(StateConflict, match=r"deadline .* passed") as err:
        submission_from_records(
            participant=participant, records=rows(), source="api", user=user, submit=True
        )
    assert err.value.status_code == 409
