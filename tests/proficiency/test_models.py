"""Database constraints: every bad value is refused by the database itself."""

import math

import pytest
from django.db import IntegrityError, transaction

from labs.models import Result, Submission
from proficiency.models import MeasurementPoint
from tests.factories import (
    ComparisonFactory,
    DeviceFactory,
    MeasurementPointFactory,
    ParticipantFactory,
    ResultFactory,
    SubmissionFactory,
)

pytestmark = pytest.mark.django_db


def refused(**changes) -> bool:
    """Try to store a result with ``changes``; True when the database refuses it."""
    base = ResultFactory.build()
    submission = SubmissionFactory.create()
    point = MeasurementPointFactory.create(device__comparison=submission.participant.comparison)
    fields = dict(
        submission=submission,
        measurement_point=point,
        value=base.value,
        unit=base.unit,
        expanded_uncertainty=base.expanded_uncertainty,
        coverage_factor=base.coverage_factor,
    )
    fields.update(changes)
    try:
        with transaction.atomic():
            Result.objects.create(**fields)
    except IntegrityError:
        return True
    return False


def test_valid_result_is_stored_with_derived_standard_uncertainty():
    r = ResultFactory.create(value=423.0, expanded_uncertainty=13.0, coverage_factor=2.0)
    r.refresh_from_db()
    assert r.standard_uncertainty == 6.5
    r2 = ResultFactory.create(value=423.0, expanded_uncertainty=9.0, coverage_factor=3.0)
    r2.refresh_from_db()
    assert r2.standard_uncertainty == pytest.approx(3.0, rel=1e-15)


def test_a_valid_result_passes_the_helper():
    assert refused() is False


@pytest.mark.parametrize(
    "field,bad",
    [
        # 0 and negative values are a phase's (docs/domain.md §12): only the importers,
        # which know the point's kind, refuse them for a magnitude
        ("value", math.inf),
        ("value", -math.inf),
        ("value", math.nan),
        ("expanded_uncertainty", 0.0),
        ("expanded_uncertainty", -3.0),
        ("expanded_uncertainty", math.inf),
        ("expanded_uncertainty", math.nan),
        ("coverage_factor", 0.0),
        ("coverage_factor", -2.0),
        ("coverage_factor", math.nan),
        ("dof", 0.0),
        ("dof", -5.0),
    ],
)
def test_result_constraint_refuses(field, bad):
    assert refused(**{field: bad})


def test_one_result_per_point_per_submission_version():
    r = ResultFactory.create()
    with pytest.raises(IntegrityError), transaction.atomic():
        ResultFactory.create(submission=r.submission, measurement_point=r.measurement_point)
    v2 = SubmissionFactory.create(participant=r.submission.participant, version=2)
    ResultFactory.create(submission=v2, measurement_point=r.measurement_point)  # a new version may
    assert Result.objects.filter(measurement_point=r.measurement_point).count() == 2


def test_submission_versions_are_unique_per_participant():
    s = SubmissionFactory.create()
    with pytest.raises(IntegrityError), transaction.atomic():
        SubmissionFactory.create(participant=s.participant, version=1)
    with pytest.raises(IntegrityError), transaction.atomic():
        SubmissionFactory.create(participant=s.participant, version=0)
    assert Submission.objects.count() == 1


def test_measurement_point_unique_with_and_without_amplitude():
    device = DeviceFactory.create()
    key = dict(device=device, axis="Y", frequency_hz=8.0, bench="curvilinear", direction="radial")
    MeasurementPointFactory.create(**key)
    with pytest.raises(IntegrityError), transaction.atomic():
        MeasurementPointFactory.create(**key)
    MeasurementPointFactory.create(**key, amplitude_m_s2=5.53)
    with pytest.raises(IntegrityError), transaction.atomic():
        MeasurementPointFactory.create(**key, amplitude_m_s2=5.53)
    MeasurementPointFactory.create(**key, amplitude_m_s2=14.77)
    assert MeasurementPoint.objects.filter(device=device).count() == 3


@pytest.mark.parametrize(
    "field,bad", [("frequency_hz", 0.0), ("frequency_hz", -5.0), ("amplitude_m_s2", 0.0)]
)
def test_measurement_point_constraints(field, bad):
    with pytest.raises(IntegrityError), transaction.atomic():
        MeasurementPointFactory.create(**{field: bad})


def test_participant_code_and_lab_unique_per_comparison():
    p = ParticipantFactory.create(code="L07")
    with pytest.raises(IntegrityError), transaction.atomic():
        ParticipantFactory.create(comparison=p.comparison, code="L07")
    with pytest.raises(IntegrityError), transaction.atomic():
        ParticipantFactory.create(comparison=p.comparison, laboratory=p.laboratory, code="L08")
    other = ComparisonFactory.create()
    ParticipantFactory.create(comparison=other, laboratory=p.laboratory, code="L07")


@pytest.mark.parametrize("field,bad", [("en_limit", 0.0), ("sigma_pt_value", -1.0)])
def test_comparison_constraints(field, bad):
    with pytest.raises(IntegrityError), transaction.atomic():
        ComparisonFactory.create(**{field: bad})


def test_device_nominal_must_be_positive():
    with pytest.raises(IntegrityError), transaction.atomic():
        DeviceFactory.create(nominal_sensitivity=-418.0)
