"""Every numeric field of a result, swept through its extremes: upload → run → report.

A value is either refused at validation, with a 400 naming its row and column and nothing
stored, or it is accepted, and then the statistics carry it: the analysis run of the round
succeeds, every stored score and assigned value is finite (or absent where a score does not
apply), and the participant's report and the summary are issued. A value that passes
validation and breaks the run later would stop the round for every laboratory.

The accepted values of one field go into one submission, one value at each measurement
point, so that the round-wide steps (bench and laboratory matrices, the report's tables)
meet all of them at once.
"""

from __future__ import annotations

import math

import pytest
from rest_framework.test import APIClient

from analysis.models import AnalysisRun, AssignedValue, Score
from analysis.services import analysis_run_start
from labs.models import Participant, Result, Submission
from labs.review import submission_decide
from labs.services import api_key_create
from proficiency.models import AssignedValueMethod, ComparisonStatus, SigmaPtMode
from tests.factories import (
    ComparisonFactory,
    DeviceFactory,
    LaboratoryFactory,
    MeasurementPointFactory,
)
from tests.security.reports import assert_reports_name_and_finite

pytestmark = pytest.mark.django_db

CODE = "SWEEP-01"
SUBMIT = f"/api/v1/comparisons/{CODE}/submissions/"
AXES, FREQUENCIES = ("X", "Y", "Z"), (5.0, 10.0, 20.0, 40.0, 80.0, 160.0)

#: the edges of double precision and a little inside them, as a lab's software would send
EXTREMES = (
    "5e-324", "2.2250738585072014e-308", "1e-300", "1e-200", "1e-160", "1e-150", "1e-100",
    "1e-30", "1e-20", "1e20", "1e30", "1e100", "1e150", "1e160", "1e200", "1e300", "1e308",
    "1.7976931348623157e308", "1e309", "-1e308", "-1e-300", "0", "-0", "inf", "-inf", "nan",
)  # fmt: skip
FIELDS = (
    "sensitivity", "expanded_uncertainty", "relative_uncertainty", "coverage_factor", "dof",
    "sensitivity_over_uncertainty",  # x = v, u = 1/v: x/u and 1/u² at their extremes at once
    "repeat_sd", "n_repeats",  # the repeats behind a result: Mandel's k, Cochran's test
)  # fmt: skip
#: more values for one field: the edges of the whole numbers n_repeats takes
MORE = {"n_repeats": ("1", "2", "2.5", "5.0", "1000000000", "1000000001")}
#: the partner of a field that is given only with it (docs/interfaces.md §1)
PARTNER = {"repeat_sd": ("n_repeats", "5"), "n_repeats": ("repeat_sd", "0.4")}


def _row(point, value=420.0, u="8"):
    return {
        "device": point.device.name, "axis": point.axis, "frequency_hz": point.frequency_hz,
        "bench": point.bench, "sensitivity": value, "expanded_uncertainty": u,
    }  # fmt: skip


def _client(key):
    c = APIClient()
    c.credentials(HTTP_AUTHORIZATION=f"Api-Key {key}")
    return c


@pytest.fixture
def round_(django_capture_on_commit_callbacks):
    comparison = ComparisonFactory.create(
        code=CODE, status=ComparisonStatus.OPEN,
        assigned_value_method=AssignedValueMethod.WEIGHTED_MEAN,
        sigma_pt_mode=SigmaPtMode.RELATIVE, sigma_pt_value=1.0,
        authorised_by_name="Dana Quality", authorised_by_role="Quality manager",
    )  # fmt: skip
    device = DeviceFactory.create(comparison=comparison, name="MEMS 1", nominal_sensitivity=420.0)
    points = [
        MeasurementPointFactory.create(device=device, axis=a, frequency_hz=f)
        for a in AXES
        for f in FREQUENCIES
    ]
    keys = {}
    for i, code in enumerate(("SWA", "SWB", "SWC")):
        lab = LaboratoryFactory.create(name=f"Sweep lab {code}")
        Participant.objects.create(comparison=comparison, laboratory=lab, code=code)
        keys[code] = api_key_create(laboratory=lab, name="soft", user=None)[1]
        if code != "SWA":
            rows = [_row(p, 420.0 + 0.5 * i + 0.01 * j) for j, p in enumerate(points)]
            for row in rows:  # repeats from two labs: the consistency tools have work to do
                row.update(repeat_sd=0.3 + 0.1 * i, n_repeats=5)
            answer = _client(keys[code]).post(SUBMIT, {"results": rows}, format="json")
            assert answer.status_code == 201, answer.content
    return comparison, points, keys, django_capture_on_commit_callbacks


def _with(field: str, text: str, point) -> dict:
    row = _row(point)
    if field == "relative_uncertainty":
        row["expanded_uncertainty"] = f"{text}%"
    elif field == "sensitivity_over_uncertainty":
        row["sensitivity"] = text
        value = float(text)
        row["expanded_uncertainty"] = repr(2.0 / value) if value else "0"  # u = 1/v
    else:
        row[field] = text
    if field in PARTNER:
        partner, given = PARTNER[field]
        row[partner] = given
    return row


def _finite_or_none(*values) -> bool:
    return all(v is None or math.isfinite(v) for v in values)


def _json_finite(value) -> bool:
    if isinstance(value, dict):
        return all(_json_finite(v) for v in value.values())
    if isinstance(value, list):
        return all(_json_finite(v) for v in value)
    return not isinstance(value, float) or math.isfinite(value)


@pytest.mark.parametrize("field", FIELDS)
def test_a_value_is_refused_at_validation_or_carried_to_the_report(round_, field):
    comparison, points, keys, on_commit = round_
    lab = _client(keys["SWA"])
    column = {
        "relative_uncertainty": "expanded_uncertainty",
        "sensitivity_over_uncertainty": "sensitivity",
    }.get(field, field)
    accepted: list[str] = []
    for text in EXTREMES + MORE.get(field, ()):
        rows = [_row(p) for p in points]
        rows[0] = _with(field, text, points[0])
        before = Result.objects.count()
        answer = lab.post(SUBMIT, {"results": rows, "submit": False}, format="json")
        assert answer.status_code in (201, 400), (text, answer.status_code, answer.content)
        if answer.status_code == 400:
            errors = answer.json()["errors"]
            # k and U are refused together when u = U/k leaves the range
            fields = {column, "expanded_uncertainty"}
            if field == "sensitivity_over_uncertainty":  # both cells may be out
                fields.add("sensitivity")
            assert 1 <= len(errors) <= 2 and {e["row"] for e in errors} == {1}, (text, errors)
            assert {e["field"] for e in errors} <= fields, (text, errors)
            assert Result.objects.count() == before, text
        else:
            accepted.append(text)
    # what a metrologist would type must still pass (the bounds are far from real values)
    if field == "n_repeats":
        assert set(accepted) == {"2", "5.0", "1000000000"}, accepted
    else:
        assert {"1e-20", "1e20"} <= set(accepted) or field == "coverage_factor", accepted
    # an infinite number of degrees of freedom is the GUM's "known exactly"
    never = {"-inf", "nan"} if field == "dof" else {"inf", "-inf", "nan", "1e309"}
    assert not never & set(accepted), accepted

    rows = [_row(p) for p in points]
    for i, text in enumerate(accepted):
        rows[i] = _with(field, text, points[i])
    final = lab.post(SUBMIT, {"results": rows}, format="json")
    assert final.status_code == 201, final.content
    comparison.status = ComparisonStatus.CLOSED
    comparison.save(update_fields=["status"])
    for submission in Submission.objects.filter(
        participant__comparison=comparison, status=Submission.Status.SUBMITTED
    ):
        submission_decide(submission=submission, decision="accept", message="", user=None)
    with on_commit(execute=True):
        run = analysis_run_start(comparison=comparison, user=None)
    run.refresh_from_db()
    assert run.status == AnalysisRun.Status.SUCCEEDED, (field, accepted, run.error)
    scores = Score.objects.filter(run=run)
    assert scores.count() == 3 * len(points)
    assert all(_finite_or_none(s.en, s.zeta, s.z, s.d) for s in scores), field
    assigned = AssignedValue.objects.filter(run=run)
    assert all(_finite_or_none(a.value, a.standard_uncertainty) for a in assigned), field
    # the consistency records (Mandel's h and k, Cochran's C from the repeats) too
    assert all(_json_finite(a.consistency) for a in assigned), field
    if field in PARTNER:
        repeats = sorted(a.consistency["p_repeats"] for a in assigned)
        assert repeats == [2] * (len(points) - len(accepted)) + [3] * len(accepted), repeats

    assert_reports_name_and_finite(comparison, "SWA")
