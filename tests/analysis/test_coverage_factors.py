"""One rule for coverage factors other than 2 (ISO 13528:2022 9.6–9.7, Cox 2002 §5).

Outside the assigned value: En = d / √(U_i² + U²(x_pt)), each U as reported.  Inside it:
u²(d) = u_i² − u²(x_pt) on standard uncertainties, U(d) = 2·u(d).  A reference
laboratory's U(x_pt) is its reported U.  Every expected number below is computed by hand
from those formulae (plain Python floats), not by the code under test.
"""

from __future__ import annotations

import json
import math
from io import StringIO
from pathlib import Path

import numpy as np
import pytest
from django.core.management import call_command

from analysis.core.groups import Groups
from analysis.core.scores import compute_scores

HEADER = (
    "lab,device,axis,frequency_hz,bench,direction,sensitivity,expanded_uncertainty,coverage_factor"
)


def weighted(x: list[float], u: list[float]) -> tuple[float, float]:
    w = [1 / v**2 for v in u]
    return sum(a * b for a, b in zip(w, x, strict=True)) / sum(w), 1 / math.sqrt(sum(w))


def test_a_contributor_with_k_213_is_corrected_on_standard_uncertainties() -> None:
    x, k = [100.0, 101.0, 99.4], [2.13, 2.0, 2.0]
    big_u = [2.13, 2.0, 3.0]
    u = [b / kk for b, kk in zip(big_u, k, strict=True)]
    y, u_y = weighted(x, u)
    s = compute_scores(
        x, u, big_u, Groups.from_index([0, 0, 0]), y, u_y, U_pt=2 * u_y,
        contributes=np.ones(3, dtype=bool),
    )  # fmt: skip
    d0 = x[0] - y
    en_standard = d0 / (2 * math.sqrt(u[0] ** 2 - u_y**2))
    en_mixed = d0 / math.sqrt(big_u[0] ** 2 - (2 * u_y) ** 2)  # the old, wrong form
    assert s.en[0] == pytest.approx(en_standard, rel=1e-12)
    assert abs(en_standard - en_mixed) > 0.01 * abs(en_standard)  # the test can tell them apart
    assert s.zeta[0] == pytest.approx(d0 / math.sqrt(u[0] ** 2 - u_y**2), rel=1e-12)
    assert s.correlation_applied.all() and not s.correlation_failed.any()


def test_k_1_input_is_corrected_not_silently_uncorrected() -> None:
    # U = u (k = 1): U² − (2·u_y)² is negative for both; the standard form is not
    x, u = [10.0, 10.5], [0.3, 0.3]
    y, u_y = weighted(x, u)
    s = compute_scores(
        x, u, u, Groups.from_index([0, 0]), y, u_y, U_pt=2 * u_y,
        contributes=np.ones(2, dtype=bool),
    )  # fmt: skip
    assert u[0] ** 2 - (2 * u_y) ** 2 < 0
    expected = (x[0] - y) / (2 * math.sqrt(u[0] ** 2 - u_y**2))
    assert s.en[0] == pytest.approx(expected, rel=1e-12)
    assert s.correlation_applied.all() and not s.correlation_failed.any()


def test_outside_the_assigned_value_each_u_as_reported() -> None:
    # a non-contributor with k = 3 against a reference with k = 2.4
    s = compute_scores([101.0], [1.0], [3.0], Groups.from_index([0]), 100.0, 0.5, U_pt=1.2)
    assert s.en[0] == pytest.approx(1.0 / math.sqrt(3.0**2 + 1.2**2), rel=1e-12)
    assert s.zeta[0] == pytest.approx(1.0 / math.sqrt(1.0 + 0.25), rel=1e-12)


def write(tmp_path: Path, rows: list[str]) -> Path:
    path = tmp_path / "round.csv"
    path.write_text("\n".join([HEADER, *rows]) + "\n")
    return path


def pt_compare(path: Path, *args: str) -> dict:
    out = StringIO()
    call_command("pt_compare", str(path), *args, "--format", "json", stdout=out)
    return json.loads(out.getvalue())


def test_reference_lab_with_k_24_gives_en_with_its_reported_u(tmp_path: Path) -> None:
    rows = [
        "PILOT,MEMS 1,X,10,linear,vertical,100.0,1.2,2.4",
        "L2,MEMS 1,X,10,linear,vertical,101.0,1.6,2",
        "L3,MEMS 1,X,10,linear,vertical,98.9,2.0,2",
    ]
    doc = pt_compare(write(tmp_path, rows), "--assigned", "reference:PILOT")
    (a,) = doc["assigned_values"]
    assert a["value"] == 100.0
    assert a["standard_uncertainty"] == pytest.approx(1.2 / 2.4, rel=1e-15)
    assert a["expanded_uncertainty"] == pytest.approx(1.2, rel=1e-15)
    assert a["coverage_factor"] == pytest.approx(2.4, rel=1e-15)
    scores = {s["lab"]: s for s in doc["scores"]}
    assert scores["L2"]["en"] == pytest.approx(1.0 / math.sqrt(1.6**2 + 1.2**2), rel=1e-12)
    assert scores["L3"]["en"] == pytest.approx(-1.1 / math.sqrt(2.0**2 + 1.2**2), rel=1e-12)
    # 2·u_ref = 1.0 would give 1/√(1.6² + 1²) = 0.530, 5 % more than 0.5
    assert scores["L2"]["en"] == pytest.approx(0.5, rel=1e-12)
    # the pilot is the sole contributor of its own x_pt: no correction can be made
    pilot = scores["PILOT"]
    assert pilot["in_assigned_value"] is True and pilot["correlation_failed"] is True
    assert pilot["correlation_applied"] is False and pilot["en"] == 0.0
    assert scores["L2"]["in_assigned_value"] is False
    assert scores["L2"]["correlation_failed"] is False


def test_inclusion_flags_of_a_largest_consistent_subset(tmp_path: Path) -> None:
    rows = [f"L{i},MEMS 1,X,10,linear,vertical,{100 + 0.1 * i},1.0,2" for i in range(1, 6)]
    rows.append("OUT,MEMS 1,X,10,linear,vertical,120.0,1.0,2")
    doc = pt_compare(write(tmp_path, rows))
    (a,) = doc["assigned_values"]
    assert a["method"] == "largest_consistent_subset" and a["n_excluded"] == 1
    assert a["excluded"] == ["OUT"]
    assert (a["n"], a["n_included"]) == (6, 5)  # the point's results; the subset's
    scores = {s["lab"]: s for s in doc["scores"]}
    assert scores["OUT"]["in_assigned_value"] is False
    assert scores["OUT"]["correlation_applied"] is False
    assert all(scores[f"L{i}"]["in_assigned_value"] is True for i in range(1, 6))
    assert all(scores[f"L{i}"]["correlation_applied"] is True for i in range(1, 6))
    nominal = pt_compare(write(tmp_path, rows), "--assigned", "nominal:100:1%")
    assert {s["in_assigned_value"] for s in nominal["scores"]} == {None}
    robust = pt_compare(write(tmp_path, rows), "--assigned", "algorithm-a")
    assert {s["in_assigned_value"] for s in robust["scores"]} == {True}


def test_csv_compatible_follows_the_en_limit(tmp_path: Path) -> None:
    # two labs, En between them = 3 / √(2² + 2²) = 1.0607: incompatible at 1, not at 1.5
    rows = [
        "A,MEMS 1,X,10,linear,vertical,100.0,2.0,2",
        "B,MEMS 1,X,10,linear,vertical,103.0,2.0,2",
    ]
    path = write(tmp_path, rows)
    for limit, compatible in (("1", "FALSE"), ("1.5", "TRUE")):
        out = StringIO()
        call_command(
            "pt_compare", str(path), "--compare", "lab", "--en-limit", limit, "--format", "csv",
            stdout=out,
        )  # fmt: skip
        pairs = out.getvalue().split("\n\n")[1].splitlines()
        assert pairs[0].split(",")[-2:] == ["en", "compatible"]
        en, flag = pairs[1].split(",")[-2:]
        assert float(en) == pytest.approx(3 / math.sqrt(8), rel=1e-12) and flag == compatible
