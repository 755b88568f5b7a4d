"""pt_compare's consistency tools (ISO 5725-2) against independent computations: pt13528's
Grubbs and Cochran, Mandel's h and k and the double Grubbs ratio written out with numpy."""

from __future__ import annotations

import csv
import io
import json
from io import StringIO
from pathlib import Path

import numpy as np
import pytest
from django.core.management import call_command
from pt13528 import outliers as oracle
from scipy import stats

HEADER = "lab,device,axis,frequency_hz,bench,sensitivity,expanded_uncertainty,repeat_sd,n_repeats"
VERDICT = ("correct", "straggler", "outlier")


def round_table(tmp_path: Path) -> tuple[Path, dict[str, list[tuple[str, float, float, int]]]]:
    """Four points: X (a biased lab and a noisy one, n = 5 everywhere), Y (n = 4, nothing
    unusual), Z (unequal repeats), and the 20 Hz X point without repeat data."""
    rng = np.random.default_rng(16_7)
    points: dict[str, list[tuple[str, float, float, int]]] = {"X": [], "Y": [], "Z": [], "X20": []}
    for j in range(9):
        lab = f"L{j + 1:02d}"
        points["X"].append(
            (lab, 418 + rng.normal(0, 0.6) + 5.0 * (j == 3), 0.3 + 0.1 * rng.random() + 1.5 *
             (j == 6), 5)
        )  # fmt: skip
        points["Y"].append((lab, 420 + rng.normal(0, 0.6), 0.3 + 0.1 * rng.random(), 4))
        points["Z"].append((lab, 421 + rng.normal(0, 0.6), 0.35, 3 + (j % 2)))
        points["X20"].append((lab, 418 + rng.normal(0, 0.6), float("nan"), 0))
    lines = [HEADER]
    for key, rows in points.items():
        axis, f = key[0], 20 if key == "X20" else 10
        for lab, v, sd, n in rows:
            repeats = f"{sd!r},{n}" if n else ","
            lines.append(f"{lab},MEMS 1,{axis},{f},linear,{v!r},4.2,{repeats}")
    path = tmp_path / "round.csv"
    path.write_text("\n".join(lines) + "\n")
    return path, points


def pt_compare(path: Path, fmt: str = "json") -> str:
    out = StringIO()
    call_command("pt_compare", str(path), "--format", fmt, stdout=out)
    return out.getvalue()


@pytest.fixture
def doc_and_points(tmp_path):
    path, points = round_table(tmp_path)
    doc = json.loads(pt_compare(path))
    by_point = {(r["axis"], r["frequency_hz"]): r for r in doc["consistency"]}
    return path, by_point, points


def verdict(statistic: float, c5: float, c1: float, lower: bool = False) -> str:
    if lower:
        statistic, c5, c1 = -statistic, -c5, -c1
    return VERDICT[2 if statistic > c1 else 1 if statistic > c5 else 0]


def test_grubbs_single_agrees_with_pt13528(doc_and_points):
    _, doc, points = doc_and_points
    for key, (axis, f) in {"X": ("X", 10.0), "Y": ("Y", 10.0), "X20": ("X", 20.0)}.items():
        values = [v for _, v, _, _ in points[key]]
        g_high, g_low, c1 = oracle.grubbs(values, 0.01)
        c5 = oracle.grubbs_critical(len(values), 0.05)
        t = doc[(axis, f)]["grubbs_single"]
        assert t["applicable"] is True
        assert t["high"]["statistic"] == pytest.approx(g_high, rel=1e-13)
        assert t["low"]["statistic"] == pytest.approx(g_low, rel=1e-13)
        assert (t["critical_5"], t["critical_1"]) == pytest.approx((c5, c1), rel=1e-13)
        labs = [lab for lab, *_ in points[key]]
        assert t["high"]["labs"] == [labs[int(np.argmax(values))]]
        assert t["low"]["labs"] == [labs[int(np.argmin(values))]]
        assert t["high"]["verdict"] == verdict(g_high, c5, c1)
        assert t["low"]["verdict"] == verdict(g_low, c5, c1)
    assert doc[("X", 10.0)]["grubbs_single"]["high"] == {
        "labs": ["L04"], "statistic": pytest.approx(oracle.grubbs(
            [v for _, v, _, _ in points["X"]])[0], rel=1e-13), "verdict": "outlier",
    }  # fmt: skip


def test_grubbs_double_written_out(doc_and_points):
    _, doc, points = doc_and_points
    values = np.sort([v for _, v, _, _ in points["Y"]])
    ss0 = ((values - values.mean()) ** 2).sum()
    high = ((values[:-2] - values[:-2].mean()) ** 2).sum() / ss0
    low = ((values[2:] - values[2:].mean()) ** 2).sum() / ss0
    t = doc[("Y", 10.0)]["grubbs_double"]
    assert t["high"]["statistic"] == pytest.approx(high, rel=1e-12)
    assert t["low"]["statistic"] == pytest.approx(low, rel=1e-12)
    # ISO 5725-2 Table 5, p = 9: 0.1492 (5 %), 0.0851 (1 %); small values reject
    assert (t["critical_5"], t["critical_1"]) == (0.1492, 0.0851)
    assert t["high"]["verdict"] == verdict(high, 0.1492, 0.0851, lower=True) == "correct"
    # where the single test finds an outlier the double test is not applied (§7.3.4)
    assert doc[("X", 10.0)]["grubbs_double"] == {
        "applicable": False, "verdict": "not applicable",
        "reason": "the single test found an outlier (ISO 5725-2 §7.3.4 applies the double test "
                  "only when it finds none)",
    }  # fmt: skip


def test_cochran_agrees_with_pt13528(doc_and_points):
    _, doc, points = doc_and_points
    for key, n in (("X", 5), ("Y", 4)):
        variances = [sd**2 for _, _, sd, _ in points[key]]
        c, c1, i = oracle.cochran(variances, n, 0.01)
        c5 = oracle.cochran_critical(len(variances), n, 0.05)
        t = doc[(key, 10.0)]["cochran"]
        assert t["statistic"] == pytest.approx(c, rel=1e-13)
        assert (t["critical_5"], t["critical_1"]) == pytest.approx((c5, c1), rel=1e-13)
        assert t["labs"] == [points[key][i][0]]
        assert t["verdict"] == verdict(c, c5, c1)
        assert doc[(key, 10.0)]["n_repeats"] == n
    assert doc[("X", 10.0)]["cochran"]["verdict"] == "outlier"
    assert doc[("X", 10.0)]["cochran"]["labs"] == ["L07"]


def _mandel_critical(p: int, n: int, alpha: float) -> tuple[float, float]:
    """ISO 5725-2 §7.3.2 (the formulas of Table 6's notes), written out here."""
    t = stats.t.ppf(1 - alpha / 2, p - 2)
    h = (p - 1) * t / np.sqrt(p * (t * t + p - 2))
    f = stats.f.ppf(1 - alpha, n - 1, (p - 1) * (n - 1))
    return float(h), float(np.sqrt(p / (1 + (p - 1) / f)))


def test_mandel_h_and_k_agree_with_iso_5725_2_written_out(doc_and_points):
    _, doc, points = doc_and_points
    for key, n in (("X", 5), ("Y", 4)):
        labs = [lab for lab, *_ in points[key]]
        means = np.array([v for _, v, _, _ in points[key]])
        sds = np.array([sd for _, _, sd, _ in points[key]])
        h = (means - means.mean()) / means.std(ddof=1)
        k = sds * np.sqrt(len(sds)) / np.sqrt((sds**2).sum())
        rec = doc[(key, 10.0)]
        assert [e["lab"] for e in rec["labs"]] == labs
        np.testing.assert_allclose([e["h"] for e in rec["labs"]], h, rtol=1e-12)
        np.testing.assert_allclose([e["k"] for e in rec["labs"]], k, rtol=1e-12)
        (h5, k5), (h1, k1) = _mandel_critical(9, n, 0.05), _mandel_critical(9, n, 0.01)
        assert (rec["mandel_h"]["critical_5"], rec["mandel_h"]["critical_1"]) == pytest.approx(
            (h5, h1), rel=1e-12)  # fmt: skip
        assert (rec["mandel_k"]["critical_5"], rec["mandel_k"]["critical_1"]) == pytest.approx(
            (k5, k1), rel=1e-12)  # fmt: skip
        assert [e["h_flag"] for e in rec["labs"]] == [verdict(abs(v), h5, h1) for v in h]
        assert [e["k_flag"] for e in rec["labs"]] == [verdict(v, k5, k1) for v in k]
    x = {e["lab"]: e for e in doc[("X", 10.0)]["labs"]}
    assert (x["L04"]["h_flag"], x["L07"]["k_flag"]) == ("outlier", "outlier")
    assert doc[("X", 10.0)]["signals"] is True and doc[("Y", 10.0)]["signals"] is False


def test_what_the_data_do_not_allow_is_not_applicable_with_its_reason(doc_and_points):
    _, doc, _ = doc_and_points
    unequal = doc[("Z", 10.0)]
    reason = "unequal numbers of repeats (n from 3 to 4); the test needs the same n in every "
    for test in ("cochran", "mandel_k"):
        assert unequal[test] == {"applicable": False, "verdict": "not applicable",
                                 "reason": reason + "laboratory"}  # fmt: skip
    assert {(e["k"], e["k_flag"]) for e in unequal["labs"]} == {(None, "not applicable")}
    assert unequal["mandel_h"]["applicable"] and unequal["grubbs_single"]["applicable"]
    none = doc[("X", 20.0)]
    assert none["cochran"]["reason"] == "no repeat data (repeat_sd, n_repeats)"
    assert none["mandel_k"]["reason"] == "no repeat data (repeat_sd, n_repeats)"
    assert (none["p"], none["p_repeats"], none["n_repeats"]) == (9, 0, None)


def test_few_laboratories(tmp_path):
    lines = [HEADER, "A,MEMS 1,X,10,linear,418,4.2,0.3,3", "B,MEMS 1,X,10,linear,419,4.2,0.2,3"]
    path = tmp_path / "two.csv"
    path.write_text("\n".join(lines) + "\n")
    [rec] = json.loads(pt_compare(path))["consistency"]
    assert rec["grubbs_single"]["reason"] == "fewer than 3 laboratories (p = 2)"
    assert rec["grubbs_double"]["reason"] == "fewer than 4 laboratories (p = 2)"
    assert rec["mandel_h"]["reason"] == "fewer than 3 laboratories (p = 2)"
    assert rec["cochran"]["applicable"] and rec["mandel_k"]["applicable"]
    assert [e["h"] for e in rec["labs"]] == [None, None]


def test_csv_section_in_long_form(doc_and_points):
    path, doc, _ = doc_and_points
    text = pt_compare(path, "csv")
    section = text[text.index("device,axis,frequency_hz,bench,direction,quantity,test,") :]
    rows = list(csv.DictReader(io.StringIO(section)))
    x = [r for r in rows if (r["axis"], r["frequency_hz"]) == ("X", "10.0")]
    cochran = next(r for r in x if r["test"] == "cochran")
    assert (cochran["lab"], cochran["verdict"]) == ("L07", "outlier")
    assert float(cochran["statistic"]) == doc[("X", 10.0)]["cochran"]["statistic"]  # full precision
    h = {r["lab"]: r for r in x if r["test"] == "mandel_h"}
    assert len(h) == 9 and h["L04"]["verdict"] == "outlier"
    double = next(r for r in x if r["test"] == "grubbs_double")
    assert (double["verdict"], double["statistic"]) == ("not applicable", "")
    k20 = [r for r in rows if r["test"] == "mandel_k" and r["frequency_hz"] == "20.0"]
    assert [(r["lab"], r["verdict"], r["reason"]) for r in k20] == [
        ("", "not applicable", "no repeat data (repeat_sd, n_repeats)")
    ]


def test_table_section(doc_and_points):
    path, _, _ = doc_and_points
    text = pt_compare(path, "table")
    section = text[text.index("CONSISTENCY (ISO 5725-2") :]
    x_line = next(line for line in section.splitlines() if " X     10 " in line)
    assert "outlier: L04 high (G = " in x_line and "outlier: L07 (C = " in x_line
    assert "L04 outlier (h = " in x_line and "L07 outlier (k = " in x_line
    assert "Cochran, Mandel k: unequal numbers of repeats (n from 3 to 4)" in section


def test_tables_without_repeat_columns_still_get_h_and_grubbs(tmp_path):
    path = tmp_path / "plain.csv"
    rows = [
        f"L{j},MEMS 1,X,10,linear,{418 + j * 0.1 + (3 if j == 5 else 0)!r},4.2" for j in range(6)
    ]
    path.write_text("lab,device,axis,frequency_hz,bench,sensitivity,expanded_uncertainty\n"
                    + "\n".join(rows) + "\n")  # fmt: skip
    [rec] = json.loads(pt_compare(path))["consistency"]
    assert rec["grubbs_single"]["high"]["labs"] == ["L5"]
    assert rec["cochran"]["reason"] == "no repeat data (repeat_sd, n_repeats)"
