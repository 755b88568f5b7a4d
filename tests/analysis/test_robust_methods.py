"""The robust assigned-value methods median (MADe), median-niqr and q-hampel:
selectable in pt_compare, in a comparison's settings and per measurement point; a
service run gives the offline tool's numbers, and the robust sigma_pt of a Q/Hampel point
is the Q method's s*."""

import json
from io import StringIO
from pathlib import Path
from typing import cast

import numpy as np
import pytest
from django import forms
from django.contrib.auth import get_user_model
from django.core.management import call_command
from django.core.management.base import CommandError
from rest_framework.test import APIClient

from analysis.core import robust
from analysis.core.groups import Groups
from analysis.models import AssignedValue, Score
from analysis.pipeline import AssignedSpec
from analysis.reports.assemble import method_label
from analysis.services import analysis_run_start
from coordination.forms import PointOverrideForm
from proficiency.models import AssignedValueMethod, Comparison

HEADER = "lab,device,axis,frequency_hz,bench,direction,sensitivity,expanded_uncertainty"
# two points, seven laboratories, one outlier at each; three-decimal results (ties)
POINTS = {
    ("MEMS 1", "X"): [418.2, 419.0, 419.0, 417.6, 418.8, 430.5, 418.1],
    ("MEMS 1", "Y"): [421.3, 420.7, 421.9, 420.2, 408.0, 421.1, 420.9],
}
CORE = {
    "median": robust.median_made,
    "median-niqr": robust.median_niqr,
    "q-hampel": robust.q_hampel,
}
STORED = {"median": "median_made", "median-niqr": "median_niqr", "q-hampel": "q_hampel"}


def results_csv(tmp_path: Path) -> Path:
    lines = [HEADER]
    for (device, axis), values in POINTS.items():
        lines += [
            f"L{i:02d},{device},{axis},80,linear,vertical,{v},4" for i, v in enumerate(values)
        ]
    path = tmp_path / "results.csv"
    path.write_text("\n".join(lines) + "\n")
    return path


def pt_compare(*args: str) -> dict:
    out = StringIO()
    call_command("pt_compare", *args, "--format", "json", stdout=out)
    return json.loads(out.getvalue())


@pytest.mark.parametrize("method", ["median", "median-niqr", "q-hampel"])
def test_pt_compare_methods_give_the_core_estimates(tmp_path, method):
    doc = pt_compare(str(results_csv(tmp_path)), "--assigned", method, "--sigma-pt", "robust")
    for a in doc["assigned_values"]:
        x = np.array(POINTS[(a["device"], a["axis"])])
        core = CORE[method](x, Groups.from_index([0] * x.size))
        assert a["method"] == STORED[method]
        assert a["value"] == core.value[0]
        assert a["standard_uncertainty"] == core.standard_uncertainty[0]
        assert a["s_star"] == core.diagnostics["s_star"][0]
        # sigma_pt "robust": the Q method's s* with Q/Hampel, Algorithm A's otherwise
        if method == "q-hampel":
            assert a["sigma_pt"] == core.diagnostics["s_star"][0]
        else:
            s_a = robust.algorithm_a(x, Groups.from_index([0] * x.size)).diagnostics["s_star"]
            assert a["sigma_pt"] == s_a[0]
    assert {s["in_assigned_value"] for s in doc["scores"]} == {True}


def test_pt_compare_q_hampel_by_hand(tmp_path):
    """The outlier 430.5 is beyond 4.5 s* of the others: psi gives it no weight, the rest
    lie within 1.5 s* of x*, so x* is their mean."""
    doc = pt_compare(str(results_csv(tmp_path)), "--assigned", "q-hampel")
    a = next(a for a in doc["assigned_values"] if a["axis"] == "X")
    rest = [v for v in POINTS[("MEMS 1", "X")] if v != 430.5]
    assert a["value"] == pytest.approx(np.mean(rest), rel=1e-14)
    assert (430.5 - a["value"]) / a["s_star"] > 4.5
    assert max(abs(v - a["value"]) for v in rest) / a["s_star"] < 1.5


def test_pt_compare_lists_the_methods(tmp_path, capsys):
    src = str(results_csv(tmp_path))
    with pytest.raises(CommandError, match="median, median-niqr, q-hampel or dersimonian") as err:
        call_command("pt_compare", src, "--assigned", "qn", stdout=StringIO())
    assert err.value.returncode == 2
    assert AssignedSpec.parse("Median-NIQR").method == "median_niqr"
    assert AssignedSpec.parse("q-hampel").method == "q_hampel"
    with pytest.raises(SystemExit):
        call_command("pt_compare", "--help")
    assert "median (MADe) | median-niqr | q-hampel" in " ".join(capsys.readouterr().out.split())


def test_labels_of_the_methods():
    assert method_label("median_made") == "Median with MADe"
    assert method_label("median_niqr") == "Median with nIQR"
    assert method_label("q_hampel") == "Q/Hampel (ISO 13528 Q method and Hampel estimator)"
    field = PointOverrideForm().fields["assigned_value_method"]
    assert isinstance(field, forms.ChoiceField)
    # a ChoiceField normalises its choices to a list of (value, label) pairs
    choices = dict(cast(list[tuple[str, str]], field.choices))
    assert {"median", "median_niqr", "q_hampel"} <= choices.keys()


# --- service runs ---------------------------------------------------------------------


def offline(demo, tmp_path: Path, method: str) -> dict:
    export = tmp_path / "demo.csv"
    call_command("export_results", demo.code, "--output", str(export), stderr=StringIO())
    return pt_compare(str(export), "--assigned", method, "--sigma-pt", "robust")


def key(p) -> tuple:
    return (p.device.name, p.axis, p.frequency_hz, p.bench, p.direction)


@pytest.mark.django_db(transaction=True)
@pytest.mark.parametrize("chunk_results", [10**9, 300], ids=["one-task", "chunks"])
@pytest.mark.parametrize("method", ["median_niqr", "q_hampel"])
def test_a_run_with_the_method_gives_the_offline_numbers(
    demo, tmp_path, settings, method, chunk_results
):
    settings.ANALYSIS_CHUNK_RESULTS = chunk_results
    Comparison.objects.filter(pk=demo.pk).update(
        assigned_value_method=method, sigma_pt_mode="robust", sigma_pt_value=None
    )
    demo.refresh_from_db()
    run = analysis_run_start(comparison=demo, user=None)
    run.refresh_from_db()
    assert run.status == "succeeded", run.error
    assert run.parameters["assigned_value_method"] == method
    doc = offline(demo, tmp_path, method.replace("_", "-"))
    ref = {tuple(a[k] for k in ("device", "axis", "frequency_hz", "bench", "direction")): a
           for a in doc["assigned_values"]}  # fmt: skip
    stored = AssignedValue.objects.filter(run=run).select_related("measurement_point__device")
    assert stored.count() == 81
    for av in stored:
        a = ref[key(av.measurement_point)]
        assert av.method == method
        assert av.value == pytest.approx(a["value"], rel=1e-14)
        assert av.standard_uncertainty == pytest.approx(a["standard_uncertainty"], rel=1e-14)
        assert av.sigma_pt == pytest.approx(a["sigma_pt"], rel=1e-14)
        assert av.diagnostics["s_star"] == pytest.approx(a["s_star"], rel=1e-14)
    by_key = {(s["lab"], s["device"], s["axis"], s["frequency_hz"], s["bench"], s["direction"]):
              s for s in doc["scores"]}  # fmt: skip
    scores = Score.objects.filter(run=run).select_related(
        "result__measurement_point__device", "result__submission__participant"
    )
    for s in scores:
        ref_s = by_key[(s.result.submission.participant.code, *key(s.result.measurement_point))]
        assert s.z == pytest.approx(ref_s["z"], rel=1e-12, abs=1e-15)
        assert s.en == pytest.approx(ref_s["en"], rel=1e-12, abs=1e-15)


@pytest.mark.django_db(transaction=True)
def test_per_point_q_hampel_and_median_niqr_with_robust_sigma_pt(demo):
    Comparison.objects.filter(pk=demo.pk).update(
        assigned_value_method=AssignedValueMethod.ALGORITHM_A, sigma_pt_mode="robust"
    )
    demo.refresh_from_db()
    points = list(demo.measurement_points.filter(device__name="MEMS 2", axis="Z", bench="linear"))
    q_point, niqr_point = points[0], points[1]
    q_point.assigned_value_method = AssignedValueMethod.Q_HAMPEL
    q_point.save()
    niqr_point.assigned_value_method = AssignedValueMethod.MEDIAN_NIQR
    niqr_point.save()
    run = analysis_run_start(comparison=demo, user=None)
    run.refresh_from_db()
    assert run.status == "succeeded", run.error
    stored = {av.measurement_point_id: av for av in AssignedValue.objects.filter(run=run)}
    assert stored.pop(q_point.pk).method == "q_hampel"
    assert stored.pop(niqr_point.pk).method == "median_niqr"
    assert {av.method for av in stored.values()} == {"algorithm_a"}
    for point in (q_point, niqr_point):
        x = np.array(
            Score.objects.filter(run=run, result__measurement_point=point)
            .order_by("result_id")
            .values_list("result__value", flat=True)
        )
        g = Groups.from_index([0] * x.size)
        av = AssignedValue.objects.get(run=run, measurement_point=point)
        core = (robust.q_hampel if point is q_point else robust.median_niqr)(x, g)
        assert av.value == pytest.approx(core.value[0], rel=1e-14)
        # robust sigma_pt: the Q method's s* at the Q/Hampel point, Algorithm A's elsewhere
        expected = (
            core.diagnostics["s_star"][0]
            if point is q_point
            else robust.algorithm_a(x, g).diagnostics["s_star"][0]
        )
        assert av.sigma_pt == pytest.approx(expected, rel=1e-14)


# --- settings: web form, per-point override, API schema --------------------------------


@pytest.mark.django_db
def test_coordinator_chooses_q_hampel_and_median_niqr_by_label(client, demo):
    client.force_login(get_user_model().objects.get(username="coordinator"))
    settings = {
        "code": "IMU-QH", "title": "Q/Hampel round", "assigned_value_method": "q_hampel",
        "sigma_pt_mode": "robust", "en_limit": "1",
    }  # fmt: skip
    assert client.post("/coordinator/new/", settings).status_code == 302
    c = Comparison.objects.get(code="IMU-QH")
    assert c.assigned_value_method == "q_hampel"
    client.post("/coordinator/IMU-QH/devices/new/", {"name": "D1", "unit": "mV/(m/s^2)",
                "tolerance_distribution": "rectangular"})  # fmt: skip
    client.post("/coordinator/IMU-QH/points/generate/",
                {"axes": ["X"], "frequencies": "80", "benches": ["linear"]})  # fmt: skip
    point = c.measurement_points.get()
    url = f"/coordinator/IMU-QH/points/{point.pk}/"
    assert "Median with nIQR" in client.get(url).content.decode()
    assert client.post(url, {"assigned_value_method": "median_niqr"}).status_code == 302
    point.refresh_from_db()
    assert point.assigned_value_method == "median_niqr"
    page = client.get("/coordinator/IMU-QH/").content.decode()
    assert "Q/Hampel (ISO 13528 Q method and Hampel estimator)" in page
    assert "Median with nIQR" in page


@pytest.mark.django_db
def test_api_schema_lists_the_methods():
    schema = APIClient().get("/api/schema/?format=json").json()
    enums = [s.get("enum", []) for s in schema["components"]["schemas"].values()]
    methods = next(e for e in enums if "dersimonian_laird" in e)
    assert {"median", "median_niqr", "q_hampel"} <= set(methods)
