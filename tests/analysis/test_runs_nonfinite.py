"""Results that make the analysis non-finite (value 1e308, U 1e-300), put straight into
the database as old data or another path could: the run fails cleanly, naming the
participant and the measurement point, and stores none of its outputs (never a database
error: PostgreSQL refuses NaN and Infinity in JSON)."""

import pytest

from analysis.models import AnalysisChunk, AnalysisRun, AssignedValue, CompatibilityMatrix, Score
from analysis.selectors import current_run
from analysis.services import analysis_run_start
from labs.models import Result
from proficiency.models import Comparison

pytestmark = pytest.mark.django_db(transaction=True)


def corrupt(demo, nth: int, **values) -> Result:
    """Overwrite one accepted result behind the validation's back."""
    result = (
        Result.objects.filter(
            submission__participant__comparison=demo, submission__status="accepted"
        )
        .select_related("submission__participant", "measurement_point__device")
        .order_by("measurement_point_id", "submission__participant__code")[nth]
    )
    Result.objects.filter(pk=result.pk).update(**values)
    return result


def run(demo, settings, chunk_results: int) -> AnalysisRun:
    settings.ANALYSIS_CHUNK_RESULTS = chunk_results
    started = analysis_run_start(comparison=demo, user=None)  # eager: runs inline
    started.refresh_from_db()
    return started


def assert_failed_cleanly(failed: AnalysisRun, *culprits: Result) -> None:
    assert failed.status == "failed"
    assert "Error" not in failed.error and "invalid input" not in failed.error, failed.error
    assert "non-finite" in failed.error
    for r in culprits:
        assert f"participant {r.submission.participant.code} at {r.measurement_point}" in (
            failed.error
        )
    assert str(culprits[0].measurement_point).count(",") == 3  # device, axis, f, bench direction
    assert not Score.objects.filter(run=failed).exists()
    assert not AssignedValue.objects.filter(run=failed).exists()
    assert not CompatibilityMatrix.objects.filter(run=failed).exists()
    for moments in AnalysisChunk.objects.filter(run=failed).values_list("moments", flat=True):
        assert "Infinity" not in str(moments) and "nan" not in str(moments).lower()


@pytest.mark.parametrize("chunk_results", [10**9, 300], ids=["one-task", "three-chunks"])
def test_huge_value_and_tiny_uncertainty_fail_the_run_naming_lab_and_point(
    demo, settings, chunk_results
):
    good = run(demo, settings, 10**9)
    assert good.status == "succeeded"
    # in the last of three chunks, so that the first two are stored before it fails
    culprit = corrupt(demo, 800, value=1e308, expanded_uncertainty=1e-300)
    failed = run(demo, settings, chunk_results)
    assert_failed_cleanly(failed, culprit)
    assert "(sensitivity 1e+308, U 1e-300)" in failed.error
    if chunk_results == 300:
        assert AnalysisChunk.objects.filter(run=failed, done=True).count() == 2
    assert current_run(demo) == good  # the previous results stay the ones shown
    assert Score.objects.filter(run=good).count() == 891


def test_a_sensitivity_of_1e308_alone_fails_cleanly_not_with_a_json_error(demo, settings):
    """Was: DataError: invalid input syntax for type json, Token "Infinity" (the moments)."""
    Comparison.objects.filter(pk=demo.pk).update(assigned_value_method="median")
    demo.refresh_from_db()
    culprit = corrupt(demo, 5, value=1e308)
    assert_failed_cleanly(run(demo, settings, 10**9), culprit)


def test_two_culprits_at_two_points_are_both_named(demo, settings):
    """In one task (a fanned-out run stops at the first chunk that fails)."""
    first = corrupt(demo, 3, value=1e308, expanded_uncertainty=1e-300)
    second = corrupt(demo, 500, value=1e200)  # its square overflows
    assert_failed_cleanly(run(demo, settings, 10**9), first, second)
