"""Analysis runs: persisted, claimed once, idempotent, failures visible, results = offline tool."""

import json
from io import StringIO

import pytest
from django.core.management import call_command
from django.db import transaction

from analysis import services
from analysis.models import AnalysisRun, AssignedValue, CompatibilityMatrix, Score
from analysis.services import analysis_run_execute, analysis_run_start
from common.errors import StateConflict
from labs.models import Participant
from proficiency.models import Comparison

pytestmark = pytest.mark.django_db(transaction=True)


def outputs(run):
    return (
        sorted(AssignedValue.objects.filter(run=run).values_list(
            "measurement_point_id", "value", "standard_uncertainty", "method")),
        sorted(Score.objects.filter(run=run).values_list("result_id", "d", "en", "zeta", "flag")),
        sorted(CompatibilityMatrix.objects.filter(run=run).values_list(
            "factor", "group_key", "incompatible_pairs")),
    )  # fmt: skip


def test_run_succeeds_and_matches_the_offline_tool(demo, tmp_path):
    run = analysis_run_start(comparison=demo, user=None)  # eager: runs on commit
    run.refresh_from_db()
    assert (run.status, run.progress, run.stage, run.error) == ("succeeded", 100, "done", "")
    assert run.started_at and run.finished_at and run.started_at <= run.finished_at
    assert run.parameters["assigned_value_method"] == "nominal"
    demo.refresh_from_db()
    assert demo.status == "analysed"
    assert AssignedValue.objects.filter(run=run).count() == 81
    assert Score.objects.filter(run=run).count() == 891
    # the same numbers as pt_compare on the exported table, nominal 418 ± 1 % rectangular
    export = tmp_path / "demo.csv"
    call_command("export_results", demo.code, "--output", str(export), stderr=StringIO())
    out = StringIO()
    call_command("pt_compare", str(export), "--assigned", "nominal:418:1%:rect",
                 "--sigma-pt", "1%", "--format", "json", stdout=out)  # fmt: skip
    offline = json.loads(out.getvalue())
    by_key = {(s["lab"], s["device"], s["axis"], s["frequency_hz"], s["bench"], s["direction"]):
              s for s in offline["scores"]}  # fmt: skip
    stored = Score.objects.filter(run=run).select_related(
        "result__measurement_point__device", "result__submission__participant"
    )
    for score in stored:
        p = score.result.measurement_point
        key = (score.result.submission.participant.code, p.device.name, p.axis, p.frequency_hz,
               p.bench, p.direction)  # fmt: skip
        ref = by_key[key]
        assert score.en == pytest.approx(ref["en"], rel=1e-12, abs=1e-15)
        assert score.z == pytest.approx(ref["z"], rel=1e-12, abs=1e-15)
        assert score.flag == ref["flag"]
    # 5 factors stored (lab x lab is computed on request, never stored for a whole round)
    assert set(CompatibilityMatrix.objects.filter(run=run).values_list("factor", flat=True)) == {
        "axis", "frequency", "device", "bench", "direction"}  # fmt: skip
    bench = CompatibilityMatrix.objects.get(
        run=run, factor="bench", group_key="device=MEMS 1, axis=X"
    )
    assert bench.levels == ["curvilinear", "linear"]
    assert bench.en[0][1] == bench.en[1][0] and bench.en[0][0] == 0


def test_second_delivery_and_re_execution_never_duplicate(demo):
    run = analysis_run_start(comparison=demo, user=None)
    first = outputs(run)
    assert analysis_run_execute(run_id=run.pk) == "succeeded"  # a second delivery: no-op
    assert outputs(run) == first
    # a redelivery after a lost worker (run still "running"): the same rows, no duplicates
    AnalysisRun.objects.filter(pk=run.pk).update(status="pending")
    assert analysis_run_execute(run_id=run.pk) == "succeeded"
    assert outputs(run) == first
    assert Score.objects.filter(run=run).count() == 891


def test_a_running_run_is_not_claimed_twice(demo):
    run = AnalysisRun.objects.create(comparison=demo, status="running")
    from django.utils import timezone

    AnalysisRun.objects.filter(pk=run.pk).update(started_at=timezone.now())
    assert analysis_run_execute(run_id=run.pk) == "running"
    assert Score.objects.count() == 0


def test_failure_is_shown_and_previous_results_stay(demo, monkeypatch):
    good = analysis_run_start(comparison=demo, user=None)
    before = outputs(good)

    def boom(run, loaded):
        raise RuntimeError("disk full")

    monkeypatch.setattr(services, "_compute", boom)
    bad = analysis_run_start(comparison=demo, user=None)
    bad.refresh_from_db()
    assert bad.status == "failed" and bad.error == "RuntimeError: disk full"
    assert bad.finished_at is not None
    assert outputs(good) == before
    assert Score.objects.filter(run=bad).count() == 0
    from analysis.selectors import current_run

    assert current_run(demo) == good


def test_rule_errors_fail_the_run_with_a_clear_message(demo):
    demo.assigned_value_method = "reference"
    demo.save()
    run = analysis_run_start(comparison=demo, user=None)
    run.refresh_from_db()
    assert run.status == "failed"
    assert run.error == "No participant is marked as the reference laboratory of this comparison."


def test_per_point_override(demo):
    point = demo.measurement_points.get(
        device__name="MEMS 2", axis="Z", frequency_hz=10, bench="linear"
    )
    point.assigned_value_method = "weighted_mean"
    point.save()
    run = analysis_run_start(comparison=demo, user=None)
    run.refresh_from_db()
    assert run.status == "succeeded", run.error
    methods = dict(
        AssignedValue.objects.filter(run=run).values_list("measurement_point_id", "method")
    )
    # MEMS 2 carries the demo's outlier: the weighted mean of all 11 is inconsistent,
    # the largest consistent subset leaves exactly that lab out
    assert methods.pop(point.pk) == "largest_consistent_subset"
    assert set(methods.values()) == {"nominal"}
    av = AssignedValue.objects.get(run=run, measurement_point=point)
    assert (av.diagnostics["n"], av.diagnostics["n_excluded"]) == (10, 1)
    assert av.diagnostics["consistent"] is True and av.diagnostics["consistent_all"] is False
    outlier = Score.objects.get(
        run=run, result__measurement_point=point,
        result__submission__participant__laboratory__name="Outlier Metrology Services",
    )  # fmt: skip
    assert outlier.flag == "action" and not outlier.correlation_applied


@pytest.mark.parametrize("status", ["draft", "open", "published"])
def test_start_refused_unless_closed_or_analysed(demo, status):
    Comparison.objects.filter(pk=demo.pk).update(status=status)
    demo.refresh_from_db()
    with pytest.raises(StateConflict, match=f"is {status}"):
        analysis_run_start(comparison=demo, user=None)
    assert AnalysisRun.objects.count() == 0


def test_enqueued_only_after_commit(demo, monkeypatch):
    sent: list[object] = []
    monkeypatch.setattr("analysis.tasks.analysis_run_task.delay", sent.append)
    with transaction.atomic():
        run = analysis_run_start(comparison=demo, user=None)
        assert sent == []
    assert sent == [run.pk]


def test_reference_method_uses_the_pilot(demo):
    pilot = Participant.objects.get(comparison=demo, laboratory__name__startswith="Linear")
    pilot.is_reference = True
    pilot.save()
    demo.assigned_value_method = "reference"
    demo.save()
    # the pilot measured the linear bench only: curvilinear points have no reference value
    run = analysis_run_start(comparison=demo, user=None)
    run.refresh_from_db()
    assert run.status == "failed"
    assert "no result for 54 measurement points" in run.error
