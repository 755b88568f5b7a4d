"""The offline command pt_compare (docs/interfaces.md §4) against the published reference data."""

import csv
import json
import math
import subprocess
import sys
from io import StringIO
from pathlib import Path

import numpy as np
import pytest
from django.core.management import call_command
from django.core.management.base import CommandError

ROOT = Path(__file__).resolve().parents[2]
REFERENCE = ROOT / "docs" / "reference-data"
HEADER = "lab,device,axis,frequency_hz,bench,direction,sensitivity,expanded_uncertainty"


def table1_csv(tmp_path: Path) -> Path:
    """Table 1 as a results table: each bench is a laboratory (as in the study)."""
    lines = [HEADER]
    for r in csv.DictReader((REFERENCE / "chiominto2024_table1.csv").open()):
        direction = "vertical" if r["bench"] == "linear" else "tangential"
        lines.append(
            f"{r['bench']}-lab,{r['device']},{r['axis']},10,{r['bench']},{direction},"
            f"{r['sensitivity']},{r['expanded_uncertainty']}"
        )
    path = tmp_path / "table1.csv"
    path.write_text("\n".join(lines) + "\n")
    return path


def run(*args: str) -> dict:
    out = StringIO()
    call_command("pt_compare", *args, "--format", "json", stdout=out)
    return json.loads(out.getvalue())


def table2() -> dict[tuple[str, str], dict[str, float]]:
    rows = csv.DictReader((REFERENCE / "chiominto2024_table2.csv").open())
    return {
        (r["device"], r["axis"]): {
            k: float(r[k]) for k in ("en_published", "en_from_rounded_table1")
        }
        for r in rows
    }


def test_table2_reproduced_from_table1(tmp_path):
    doc = run(str(table1_csv(tmp_path)), "--compare", "bench")
    matrices = {(m["device"], m["axis"]): m for m in doc["compatibility"]}
    expected = table2()
    assert matrices.keys() == expected.keys()
    for key, ref in expected.items():
        m = matrices[key]
        assert m["factor"] == "bench" and m["levels"] == ["curvilinear", "linear"]
        en = m["en"][0][1]
        assert en == m["en"][1][0] and m["en"][0][0] == 0.0
        # 4 decimals; the shipped 0.2974 for MEMS 2 Z is 4/sqrt(181) = 0.29732, so the
        # tolerance is one unit of the 4th decimal, not half of it.
        assert en == pytest.approx(ref["en_from_rounded_table1"], abs=1e-4), key
        assert en == pytest.approx(ref["en_published"], abs=0.05), key
        assert m["incompatible_pairs"] == 0
    # hand calculation, MEMS 1 Y: |422 - 419| / sqrt(11^2 + 12^2)
    assert matrices[("MEMS 1", "Y")]["en"][0][1] == pytest.approx(3 / math.sqrt(265), rel=1e-12)


def test_every_table1_value_compatible_with_nominal(tmp_path):
    doc = run(str(table1_csv(tmp_path)), "--assigned", "nominal:418:1%:rect")
    assert len(doc["scores"]) == 18
    u_nominal = 4.18 / math.sqrt(3)
    for a in doc["assigned_values"]:
        assert a["value"] == 418.0 and a["method"] == "nominal"
        assert a["standard_uncertainty"] == pytest.approx(u_nominal, rel=1e-12)
    for s in doc["scores"]:
        assert s["en"] <= 1.0 and s["flag"] == "satisfactory", s
    closest = max(doc["scores"], key=lambda s: s["en"])
    assert (closest["lab"], closest["device"], closest["axis"]) == (
        "curvilinear-lab",
        "MEMS 3",
        "Y",
    )
    assert closest["en"] == pytest.approx(12 / math.sqrt(11**2 + (2 * u_nominal) ** 2), rel=1e-12)
    assert round(closest["en"], 4) == 0.9990


def test_weighted_mean_by_hand(tmp_path):
    path = tmp_path / "three.csv"
    path.write_text(
        HEADER + "\n"
        "A,MEMS 1,X,10,linear,vertical,420,4\n"
        "B,MEMS 1,X,10,linear,vertical,424,8\n"
        "C,MEMS 1,X,10,linear,vertical,418,4\n"
    )
    doc = run(str(path))
    (a,) = doc["assigned_values"]
    # u = 2, 4, 2 -> weights 1/4, 1/16, 1/4; y = (105 + 26.5 + 104.5) / (9/16) = 419.5555...
    assert a["value"] == pytest.approx(236 / (9 / 16), rel=1e-14)
    assert a["standard_uncertainty"] == pytest.approx((9 / 16) ** -0.5, rel=1e-14)
    assert a["method"] == "weighted_mean" and a["consistent"] is True
    chi2 = (
        ((420 - a["value"]) / 2) ** 2
        + ((424 - a["value"]) / 4) ** 2
        + ((418 - a["value"]) / 2) ** 2
    )
    assert a["chi2_obs"] == pytest.approx(chi2, rel=1e-12)
    assert a["birge_ratio"] == pytest.approx(math.sqrt(chi2 / 2), rel=1e-12)
    score_b = next(s for s in doc["scores"] if s["lab"] == "B")
    # B contributes to x_pt: u^2(d) = u^2(x) - u^2(x_pt) (Cox 2002)
    u_d = math.sqrt(16 - a["standard_uncertainty"] ** 2)
    assert score_b["correlation_applied"] is True
    assert score_b["en"] == pytest.approx((424 - a["value"]) / (2 * u_d), rel=1e-12)
    assert set(score_b) >= {
        "device",
        "axis",
        "frequency_hz",
        "bench",
        "direction",
        "lab",
        "value",
        "expanded_uncertainty",
        "d",
        "en",
        "zeta",
        "flag",
    }
    assert "z" not in score_b  # no sigma_pt given


def test_compare_lab_defaults_to_the_measurement_point(tmp_path):
    doc = run(str(table1_csv(tmp_path)), "--compare", "lab")
    # each point (device, axis, 10 Hz, bench, direction) has one lab: 18 one-level matrices
    assert len(doc["compatibility"]) == 18
    m = doc["compatibility"][0]
    assert set(m) >= {
        "factor",
        "device",
        "axis",
        "frequency_hz",
        "bench",
        "direction",
        "levels",
        "en",
        "incompatible_pairs",
    }
    assert m["en"] == [[0.0]]


def test_compare_axis_by_device(tmp_path):
    doc = run(str(table1_csv(tmp_path)), "--compare", "axis", "--by", "device")
    assert [m["device"] for m in doc["compatibility"]] == ["MEMS 1", "MEMS 2", "MEMS 3"]
    m1 = doc["compatibility"][0]
    assert m1["levels"] == ["X", "Y", "Z"]
    # MEMS 1, X aggregates linear 422 (U 13) and curvilinear 423 (U 13): mean 422.5,
    # u = sqrt(6.5^2 + 0.5) (s^2 of (422, 423) with ddof = 1 is 0.5)
    assert m1["value"][0] == 422.5
    assert m1["expanded_uncertainty"][0] == pytest.approx(2 * math.sqrt(6.5**2 + 0.5), rel=1e-12)


def test_bad_rows_all_listed_and_exit_code_2(tmp_path):
    path = tmp_path / "bad.csv"
    path.write_text(
        HEADER + "\n"
        "A,MEMS 1,X,10,linear,vertical,420,4\n"
        "B,MEMS 1,X,10,linear,vertical,-3,4\n"
        "C,MEMS 1,W,10,linear,vertical,418,4\n"
        "D,MEMS 1,X,10,linear,vertical,418,-3\n"
    )
    proc = subprocess.run(
        [sys.executable, "manage.py", "pt_compare", str(path)],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 2
    assert "row 3, column sensitivity" in proc.stderr
    assert "row 4, column axis" in proc.stderr
    assert "row 5, column expanded_uncertainty: must be > 0, got -3" in proc.stderr
    assert proc.stdout == ""


@pytest.mark.parametrize(
    "args,message",
    [
        (["--assigned", "reference:Z-LAB"], "reference laboratory 'Z-LAB' is not in the table"),
        (["--assigned", "nominal:418"], "expected nominal:<value>:<tolerance>"),
        (["--assigned", "mode"], "is not understood"),
        (["--sigma-pt", "-1"], "--sigma-pt '-1'"),
    ],
)
def test_bad_options_exit_2(tmp_path, args, message):
    with pytest.raises(CommandError, match=message) as err:
        call_command("pt_compare", str(table1_csv(tmp_path)), *args, stdout=StringIO())
    assert err.value.returncode == 2


def test_missing_lab_column_is_an_error(tmp_path):
    path = tmp_path / "nolab.csv"
    path.write_text(
        "device,axis,frequency_hz,bench,sensitivity,expanded_uncertainty\n"
        "MEMS 1,X,10,linear,420,4\n"
    )
    with pytest.raises(CommandError, match="lab") as err:
        call_command("pt_compare", str(path), stdout=StringIO())
    assert err.value.returncode == 2


def test_table_and_csv_output(tmp_path):
    src = table1_csv(tmp_path)
    out = StringIO()
    call_command("pt_compare", str(src), "--compare", "bench", stdout=out)
    text = out.getvalue()
    assert "ASSIGNED VALUES" in text and "SCORES" in text
    assert "COMPATIBILITY of bench (device=MEMS 1, axis=Y): 0 incompatible pairs" in text
    target = tmp_path / "out.csv"
    call_command(
        "pt_compare", str(src), "--compare", "bench", "--format", "csv", "--output", str(target)
    )
    scores, pairs, consistency = target.read_text().split("\n\n")
    assert len(list(csv.DictReader(StringIO(scores)))) == 18
    long_form = list(csv.DictReader(StringIO(pairs)))
    assert len(long_form) == 9
    mems1y = next(r for r in long_form if r["group"] == "device=MEMS 1, axis=Y")
    assert float(mems1y["en"]) == pytest.approx(3 / math.sqrt(265), rel=1e-12)
    tests = {r["test"] for r in csv.DictReader(StringIO(consistency))}  # two labs: n/a rows
    assert tests == {"grubbs_single", "grubbs_double", "cochran", "mandel_h", "mandel_k"}


def test_csv_output_escapes_formula_like_cells(tmp_path):
    path = tmp_path / "evil.csv"
    path.write_text(
        HEADER + "\n=cmd|' /C calc'!A0,MEMS 1,X,10,linear,vertical,420,4\n"
        "B,MEMS 1,X,10,linear,vertical,421,4\n"
    )
    out = StringIO()
    call_command("pt_compare", str(path), "--format", "csv", stdout=out)
    assert "\n'=cmd" in out.getvalue()
    assert "\n=cmd" not in out.getvalue()


@pytest.mark.django_db
def test_demo_export_reproduces_table2(tmp_path):
    """The demo's two bench labs, exported and analysed offline, give Table 2."""
    call_command("load_demo", password="demo-password-1", stdout=StringIO())
    export = tmp_path / "demo.csv"
    call_command("export_results", "IMU-2024-DEMO", "--output", str(export), stderr=StringIO())
    rows = list(csv.DictReader(export.open()))
    assert len(rows) == 891
    from labs.models import Participant

    codes = set(
        Participant.objects.filter(laboratory__name__contains="Bench Calibration").values_list(
            "code", flat=True
        )
    )
    bench_labs = tmp_path / "bench_labs.csv"
    with bench_labs.open("w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=rows[0].keys())
        writer.writeheader()
        writer.writerows(r for r in rows if r["lab"] in codes)
    doc = run(str(bench_labs), "--compare", "bench")
    got = {(m["device"], m["axis"]): m["en"][0][1] for m in doc["compatibility"]}
    for key, ref in table2().items():
        assert got[key] == pytest.approx(ref["en_from_rounded_table1"], abs=1e-4), key
    full = run(str(export), "--compare", "bench", "--sigma-pt", "1%")
    assert len(full["scores"]) == 891 and len(full["assigned_values"]) == 81
    outlier_flags = {s["flag"] for s in full["scores"] if s["device"] == "MEMS 2" and s["en"] > 1}
    assert outlier_flags == {"action"}


def manage(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "manage.py", "pt_compare", *args],
        cwd=ROOT, capture_output=True, text=True, timeout=120,
    )  # fmt: skip


def test_stdout_is_the_json_and_nothing_else(tmp_path):
    """A real process: no start-up log line (django-axes' "AXES: BEGIN") on either stream."""
    proc = manage(str(table1_csv(tmp_path)), "--format", "json", "--compare", "bench")
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr == ""
    doc = json.loads(proc.stdout)
    assert set(doc) == {"assigned_values", "scores", "compatibility", "consistency"}
    assert proc.stdout.count("\n") == 1  # compact by default
    assert doc == run(str(table1_csv(tmp_path)), "--compare", "bench")


def test_indent(tmp_path):
    out = StringIO()
    call_command("pt_compare", str(table1_csv(tmp_path)), "--format", "json", "--indent", "4",
                 stdout=out)  # fmt: skip
    text = out.getvalue()
    assert text.startswith('{\n    "assigned_values": [\n        {\n            "device": ')
    assert json.loads(text) == run(str(table1_csv(tmp_path)))
    with pytest.raises(CommandError, match="--indent") as err:
        call_command("pt_compare", str(table1_csv(tmp_path)), "--indent", "-1", stdout=out)
    assert err.value.returncode == 2


def test_more_than_1000_bad_rows_listed_with_a_count(tmp_path):
    lines = [HEADER] + [
        f"L{i},MEMS 1,X,10,linear,vertical,420,{-3 if i % 2 else 4}" for i in range(2500)
    ]
    path = tmp_path / "bad.csv"
    path.write_text("\n".join(lines) + "\n")
    target = tmp_path / "out.json"
    proc = manage(str(path), "--format", "json", "--output", str(target))
    assert proc.returncode == 2
    assert proc.stdout == ""
    listed = [line for line in proc.stderr.splitlines() if line.startswith("row ")]
    assert len(listed) == 1000
    assert listed[0] == "row 3, column expanded_uncertainty: must be > 0, got -3"
    assert "... and 250 more problems" in proc.stderr
    assert not target.exists() and list(tmp_path.iterdir()) == [path]


def test_a_local_file_has_no_upload_limit(tmp_path):
    """A 6 MB file, over a web upload's 5 MB, is analysed whole (the row limit is lifted
    too: tests/labs/test_local_table.py)."""
    from labs.importers import MAX_BYTES, ImportErrors, parse_table

    n = 30_000
    x = 418 + np.random.default_rng(1).normal(0, 2, n)
    path = tmp_path / "round.csv"
    with path.open("w") as f:
        f.write(HEADER + ",note\n")
        f.writelines(
            f"L{i // 100:04d},MEMS 1,X,{10 + i % 100},linear,vertical,{v!r},4.25,{'n' * 150}\n"
            for i, v in enumerate(x.tolist())
        )
    assert path.stat().st_size > MAX_BYTES
    with pytest.raises(ImportErrors, match="the limit is 5 MB"):
        parse_table(path.read_bytes(), lab_column="required")
    target = tmp_path / "round.json"
    call_command("pt_compare", str(path), "--assigned", "algorithm-a", "--format", "json",
                 "--output", str(target))  # fmt: skip
    doc = json.loads(target.read_text())
    assert len(doc["scores"]) == n and len(doc["assigned_values"]) == 100
    assert sum(a["n"] for a in doc["assigned_values"]) == n
