"""pt_compare and the quantity column (docs/interfaces.md §4): without the column the output
is that of a table of magnitudes with the added ``quantity`` key; with it, a phase is its
own point, analysed on the circle (docs/domain.md §12), in JSON, CSV and the text table."""

import csv
import io
import json
import math
from io import StringIO
from pathlib import Path

from django.core.management import call_command

HEADER = "lab,device,axis,frequency_hz,bench,direction,sensitivity,expanded_uncertainty"
MAGNITUDES = [("A", 418.0, 4.0), ("B", 420.0, 4.0), ("C", 419.0, 8.0)]
PHASES = [("A", "179", "3"), ("B", "-179", "3"), ("C", "538", "6")]  # 538° is 178°


def pt_compare(path: Path, fmt: str = "json", *args: str) -> str:
    out = StringIO()
    call_command("pt_compare", str(path), "--format", fmt, *args, stdout=out)
    return out.getvalue()


def write(path: Path, lines: list[str]) -> Path:
    path.write_text("\n".join(lines) + "\n")
    return path


def magnitude_lines(quantity: str | None) -> list[str]:
    head = HEADER + (",quantity" if quantity is not None else "")
    tail = f",{quantity}" if quantity is not None else ""
    return [head] + [
        f"{lab},MEMS 1,X,80,curvilinear,tangential,{x},{u}{tail}" for lab, x, u in MAGNITUDES
    ]


def test_without_the_column_only_the_quantity_key_is_added(tmp_path):
    plain = json.loads(pt_compare(write(tmp_path / "a.csv", magnitude_lines(None)), "json",
                                  "--compare", "lab"))  # fmt: skip
    blank = json.loads(pt_compare(write(tmp_path / "b.csv", magnitude_lines("")), "json",
                                  "--compare", "lab"))  # fmt: skip
    assert plain == blank
    for section in ("assigned_values", "scores", "consistency", "compatibility"):
        assert all(r["quantity"] == "magnitude" for r in plain[section]), section
    # the numbers are those of the weighted mean of the magnitudes, by hand
    w = [1 / 4, 1 / 4, 1 / 16]
    x_pt = sum(wi * x for wi, (_, x, _) in zip(w, MAGNITUDES, strict=True)) / sum(w)
    assert plain["assigned_values"][0]["value"] == x_pt
    assert [s["d_percent"] is not None for s in plain["scores"]] == [True] * 3
    # the text table and the matrix's group text do not name the magnitude
    text = pt_compare(tmp_path / "a.csv", "table", "--compare", "lab")
    assert "magnitude" not in text and "quantity" not in text


def test_phases_beside_magnitudes(tmp_path):
    lines = magnitude_lines("magnitude") + [
        f"{lab},MEMS 1,X,80,curvilinear,tangential,{x},{u},phase" for lab, x, u in PHASES
    ]
    path = write(tmp_path / "p.csv", lines)
    doc = json.loads(pt_compare(path, "json", "--compare", "lab"))
    by_kind = {r["quantity"]: r for r in doc["assigned_values"]}
    assert set(by_kind) == {"magnitude", "phase"}
    mean = (4 * 179 + 4 * 181 + 178) / 9  # 179, −179 → 181, 538 → 178 about 180°
    assert by_kind["phase"]["value"] == mean
    phase_scores = [s for s in doc["scores"] if s["quantity"] == "phase"]
    assert [s["value"] for s in phase_scores] == [179.0, -179.0, 178.0]
    expected_d = [179 - mean, (-179 + 360) - mean, 178 - mean]
    for s, d in zip(phase_scores, expected_d, strict=True):
        assert math.isclose(s["d"], d, abs_tol=1e-12) and s["d_percent"] is None
    lab_matrices = {m["quantity"]: m for m in doc["compatibility"]}
    # A vs B: |wrap(179 − (−179))| = 2°, not 358°
    assert math.isclose(lab_matrices["phase"]["en"][0][1], 2 / math.hypot(3, 3), rel_tol=1e-12)
    csv_text = pt_compare(path, "csv")
    rows = list(csv.DictReader(io.StringIO(csv_text.split("\n\n")[0])))
    assert [r["quantity"] for r in rows].count("phase") == 3
    assert {r["d_percent"] for r in rows if r["quantity"] == "phase"} == {""}
    # the text table names the kind by its label; JSON and CSV keep its name
    table = pt_compare(path, "table", "--compare", "lab")
    assert "tangential, sensitivity phase" in table and ", phase" not in table
    assert (
        "(device=MEMS 1, axis=X, frequency_hz=80.0000, bench=curvilinear, direction="
        "tangential, sensitivity phase)"
        in table
        and "quantity" not in table
    )
    consistency = table[table.index("CONSISTENCY") :]
    assert consistency.count("tangential, sensitivity phase") == 1  # its own row
    groups = [r["group"] for r in csv.DictReader(io.StringIO(
        pt_compare(path, "csv", "--compare", "lab").split("\n\n")[1]))]  # fmt: skip
    assert any(g.endswith("quantity=phase") for g in groups)
