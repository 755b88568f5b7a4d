"""Phases and angular rates at the edges the importer accepts, through an analysis run and
the reports, on PostgreSQL (docs/domain.md §2, §12; the companion of test_extreme_values).

A value that passes validation and breaks the run later would stop the round for every
laboratory: phases of ±1e30° (stored as ±16°), ±1e-30°, 0 and −0, ±180° and 540°, a phase
U from 1e-29° to 1e30°, and angular rates per rad/s at the ends of the range, reported by
three laboratories at once, give a run that succeeds with finite assigned values and
scores, every phase D wrapped into (−180°, 180°], and both reports issued.
"""

from __future__ import annotations

import math

import pytest

from analysis.models import AnalysisRun, AssignedValue, Score
from analysis.services import analysis_run_start
from labs.models import Submission
from labs.review import submission_decide
from labs.services import submission_from_records
from proficiency.models import AssignedValueMethod, ComparisonStatus
from proficiency.services import measurement_points_generate
from tests.factories import ComparisonFactory, DeviceFactory, ParticipantFactory
from tests.security.reports import assert_reports_name_and_finite

pytestmark = pytest.mark.django_db

FREQUENCIES = (5, 10, 20, 40, 80, 160)
#: per frequency, what labs A, B and C report: (phase, its U) each
PHASES = {
    5: (("1e30", "0.5"), ("-1e30", "0.5"), ("16", "1e-29")),
    10: (("180", "1e30"), ("-180", "0.5"), ("540", "2")),
    20: (("1e-30", "1e-29"), ("-1e-30", "1e-29"), ("0", "1e30")),
    40: (("179.99999999999997", "0.1"), ("-179.99999999999997", "0.1"), ("180", "0.1")),
    80: (("-0", "0.3"), ("0.1", "0.3"), ("-0.1", "1e-29")),
    160: (("1e22", "0.5"), ("-80", "0.5"), ("-79.9", "0.5")),
}
#: per frequency, the angular rates per rad/s of labs A, B and C: (value, its U)
RATES = {
    5: (("1e30", "1e30"), ("5.7e29", "1%"), ("1e30", "40%")),
    10: (("2e-28", "2e-28"), ("1e-27", "2e-28"), ("3e-28", "2e-28")),
    20: (("3280", "1e-27%"), ("3281", "16"), ("3279", "1e27")),
    40: (("3280", "16"), ("3280", "16"), ("3280", "16")),
    80: (("1", "0.01"), ("1e29", "1e29"), ("1", "0.01")),
    160: (("57.29577951308232", "1%"), ("57.3", "0.5"), ("57.2", "0.5")),
}


def _records(lab: int) -> list[dict]:
    rows = []
    for f in FREQUENCIES:
        point = {"device": "IMU 1", "axis": "X", "frequency_hz": f, "bench": "curvilinear",
                 "direction": "tangential"}  # fmt: skip
        phase, u_phase = PHASES[f][lab]
        rate, u_rate = RATES[f][lab]
        rows += [
            {**point, "quantity": "phase", "sensitivity": phase, "expanded_uncertainty": u_phase},
            {**point, "quantity": "angular_rate", "sensitivity": rate,
             "expanded_uncertainty": u_rate, "unit": "D/(rad/s)"},
        ]  # fmt: skip
    return rows


#: the consensus methods (a reference laboratory or a nominal value: no extremes to meet)
CONSENSUS = [m for m in AssignedValueMethod if m not in ("reference", "nominal")]


@pytest.mark.parametrize("method", CONSENSUS)
def test_accepted_extremes_are_carried_to_the_scores_and_the_reports(
    django_capture_on_commit_callbacks, needs_postgres, method
):
    comparison = ComparisonFactory.create(
        code="SWEEP-Q", status=ComparisonStatus.OPEN, protocol="custom",
        assigned_value_method=method,
        authorised_by_name="Dana Quality", authorised_by_role="Quality manager",
    )  # fmt: skip
    device = DeviceFactory.create(comparison=comparison, name="IMU 1", unit="D/(m/s^2)")
    measurement_points_generate(
        comparison=comparison, devices=[device], axes=["X"], frequencies_hz=FREQUENCIES,
        benches=["curvilinear"], directions=["tangential"], quantities=["phase", "angular_rate"],
    )  # fmt: skip
    for lab, code in enumerate(("SQA", "SQB", "SQC")):
        participant = ParticipantFactory.create(comparison=comparison, code=code)
        submission_from_records(participant=participant, records=_records(lab), source="api",
                                user=None, submit=True)  # fmt: skip
    comparison.status = ComparisonStatus.CLOSED
    comparison.save(update_fields=["status"])
    for submission in Submission.objects.filter(participant__comparison=comparison):
        submission_decide(submission=submission, decision="accept", message="", user=None)
    with django_capture_on_commit_callbacks(execute=True):
        run = analysis_run_start(comparison=comparison, user=None)
    run.refresh_from_db()
    assert run.status == AnalysisRun.Status.SUCCEEDED, run.error
    scores = Score.objects.filter(run=run).select_related("result__measurement_point")
    assert scores.count() == 3 * 2 * len(FREQUENCIES)
    for s in scores:
        for value in (s.d, s.en, s.zeta):
            assert value is None or math.isfinite(value), (s.result.measurement_point, s.d)
        if s.result.measurement_point.quantity == "phase":
            assert s.d is not None and -180.0 < s.d <= 180.0 and s.d_percent is None
    for a in AssignedValue.objects.filter(run=run).select_related("measurement_point"):
        assert math.isfinite(a.value) and math.isfinite(a.standard_uncertainty), a
        if a.measurement_point.quantity == "phase":
            assert -180.0 < a.value <= 180.0
    assert_reports_name_and_finite(comparison, "SQA")
