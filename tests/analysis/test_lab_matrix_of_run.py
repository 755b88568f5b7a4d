"""The lab x lab matrix belongs to the run it is shown with: computed on request from the
results the run scored, so a version accepted after the run (or after publication) does
not change what the run's pages and API show (docs/domain.md §6)."""

import math

import pytest
from django.utils import timezone
from rest_framework.test import APIClient

from analysis.selectors import lab_matrices
from analysis.services import analysis_run_start
from labs.models import Result, Submission
from labs.selectors import current_submissions

pytestmark = pytest.mark.django_db(transaction=True)
POINT = {"device": "MEMS 2", "axis": "X", "frequency_hz": "5", "bench": "linear"}


def accept_new_version(submission: Submission, point_id: int, shift: float) -> Submission:
    """A later accepted version of ``submission``: the same results, one of them moved."""
    new = Submission.objects.create(
        participant=submission.participant, version=submission.version + 1,
        status=Submission.Status.ACCEPTED, submitted_at=timezone.now(), decided_at=timezone.now(),
    )  # fmt: skip
    for r in submission.results.all():
        value = r.value + shift if r.measurement_point_id == point_id else r.value
        Result.objects.create(
            submission=new, measurement_point_id=r.measurement_point_id, value=value,
            unit=r.unit, expanded_uncertainty=r.expanded_uncertainty,
            coverage_factor=r.coverage_factor,
        )  # fmt: skip
    return new


def test_a_later_accepted_version_does_not_change_the_runs_lab_matrix(demo):
    run = analysis_run_start(comparison=demo, user=None)
    run.refresh_from_db()
    assert run.status == "succeeded", run.error
    (before,) = lab_matrices(run, POINT)
    # the En of the first two labs by hand from the results the run scored
    scored = {
        s.result.submission.participant.code: s.result
        for s in run.scores.select_related("result__submission__participant").filter(
            result__measurement_point__device__name="MEMS 2", result__measurement_point__axis="X",
            result__measurement_point__frequency_hz=5, result__measurement_point__bench="linear",
        )
    }  # fmt: skip
    a, b = (scored[c] for c in before.levels[:2])
    hand = abs(a.value - b.value) / math.hypot(a.expanded_uncertainty, b.expanded_uncertainty)
    assert before.en[0][1] == pytest.approx(hand, rel=1e-12)

    current = current_submissions(demo).filter(status=Submission.Status.ACCEPTED)
    moved = current.get(participant__code=before.levels[0])
    accept_new_version(moved, a.measurement_point_id, shift=10.0)

    (after,) = lab_matrices(run, POINT)
    assert after.levels == before.levels and after.value.tolist() == before.value.tolist()
    assert after.en.tolist() == before.en.tolist()
    response = APIClient()
    response.force_authenticate(demo.coordinators.first())
    shown = response.get(
        f"/api/v1/comparisons/{demo.code}/compatibility/", {"factor": "lab", **POINT}
    )
    assert shown.status_code == 200 and shown.json()[0]["en"] == before.en.tolist()

    newer = analysis_run_start(comparison=demo, user=None)  # the new version counts from now on
    (fresh,) = lab_matrices(newer, POINT)
    assert fresh.value[0] == pytest.approx(before.value[0] + 10.0)
