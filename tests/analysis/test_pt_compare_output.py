"""pt_compare's column-wise JSON and CSV against the per-result code it replaced
(tests/analysis/pt_compare_reference.py) and against the upload's importer."""

import json
import math
import re
from pathlib import Path

import numpy as np
import orjson
import pytest

from analysis.management.commands.pt_compare import result_table
from analysis.offline import consistency_csv, render
from analysis.offline_json import score_json_chunks
from analysis.pipeline import (
    AssignedSpec,
    ResultTable,
    SigmaPtSpec,
    analyse,
    analyse_grouped,
    score_record_chunks,
    score_records,
)
from labs.importers import parse_table
from labs.importers.local import read_local_table
from tests.analysis import pt_compare_reference as reference

HEADER = (
    "lab,device,axis,frequency_hz,bench,direction,sensitivity,expanded_uncertainty,"
    "coverage_factor,note"
)


def varied_csv(path: Path) -> Path:
    """Linear and curvilinear points, outliers (left out of the largest consistent subset),
    a point with a single result (no robust σ_pt there), a relative uncertainty, blank and
    given coverage factors, text that a spreadsheet would execute, non-ASCII names."""
    rng = np.random.default_rng(16)
    labs = ["A", "B", "C", "D", "E", "-minus", "Labö", "=1+1"]
    points: list[tuple[str, str, float, str, str]]
    points = [(d, a, f, "linear", "vertical") for d in ("MEMS 1", "MEMS 2")
              for a in "XYZ" for f in (10, 160)]  # fmt: skip
    points += [("MEMS 1", "X", 1.5, "curvilinear", "tangential"),
               ("MEMS 1", "Y", 1.5, "curvilinear", "radial")]  # fmt: skip
    lines = [HEADER]
    for p, (device, axis, f, bench, direction) in enumerate(points):
        for i, lab in enumerate(labs):
            x = 418 + rng.normal(0, 2) + (40 if (i == 3 and p % 3 == 0) else 0)
            u = f"{rng.uniform(1, 3):.3f}%" if i == 2 else repr(float(rng.uniform(4, 12)))
            k = "" if i % 2 else "2"
            lines.append(f"{lab},{device},{axis},{f},{bench},{direction},{x!r},{u},{k},n{i}")
    lines.append("A,MEMS 3,Z,10,linear,vertical,420.5,4,,alone")
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


CASES = [
    ("weighted-mean", None, [("lab", None), ("bench", None)]),
    ("algorithm-a", "1%", []),
    ("median", "1%", [("axis", ["device"])]),
    ("nominal:418:1%:rect", "2", []),
    ("dersimonian-laird", None, []),
]


@pytest.fixture(scope="module")
def varied(tmp_path_factory):
    return varied_csv(tmp_path_factory.mktemp("varied") / "varied.csv")


def _old_analysis(path: Path, assigned: str, sigma: str | None, compare):
    rows = parse_table(path.read_bytes(), filename=path.name, lab_column="required")
    spec, s = AssignedSpec.parse(assigned), SigmaPtSpec.parse(sigma)
    return analyse(ResultTable.from_rows(rows), spec, sigma_pt=s, compare=compare)


def _new_analysis(path: Path, assigned: str, sigma: str | None, compare):
    spec, s = AssignedSpec.parse(assigned), SigmaPtSpec.parse(sigma)
    return analyse(result_table(read_local_table(path)), spec, sigma_pt=s, compare=compare)


def _nulls(doc):
    """NaN and inf as null, as the JSON writer gives them."""
    if isinstance(doc, float) and not math.isfinite(doc):
        return None
    if isinstance(doc, dict):
        return {k: _nulls(v) for k, v in doc.items()}
    if isinstance(doc, list):
        return [_nulls(v) for v in doc]
    return doc


def without_consistency(doc: dict) -> dict:
    """The document less its ``consistency`` key (added since the per-result code), which
    must hold one record per point in the points' order."""
    records = doc.pop("consistency")
    assert [r["device"] for r in records] == [a["device"] for a in doc["assigned_values"]]
    return doc


def csv_without_consistency(text: str, analysis) -> str:
    """The CSV less its last section, which must be exactly the consistency section."""
    tail = "".join(consistency_csv(analysis))
    assert text.endswith(tail) and tail.startswith("\n")
    return text[: len(text) - len(tail)]


@pytest.mark.parametrize("assigned,sigma,compare", CASES)
def test_same_output_as_the_per_result_code(varied, assigned, sigma, compare):
    old = _old_analysis(varied, assigned, sigma, compare)
    new = _new_analysis(varied, assigned, sigma, compare)
    expected = reference.to_json(old)
    assert _nulls(score_records(new)) == _nulls(expected["scores"])
    for indent in (None, 2, 4):
        text = render(new, "json", indent=indent)
        doc = json.loads(text)
        assert without_consistency(doc) == _nulls(expected)
        assert [list(r) for r in doc["scores"]] == [list(r) for r in expected["scores"]]
    assert csv_without_consistency(render(new, "csv"), new) == reference.render_csv(expected)


def test_the_varied_file_covers_what_it_should(varied):
    doc = reference.to_json(_old_analysis(varied, "weighted-mean", None, []))
    assert {s["in_assigned_value"] for s in doc["scores"]} == {True, False}
    assert {s["correlation_applied"] for s in doc["scores"]} == {True, False}
    nominal = reference.to_json(_old_analysis(varied, "nominal:418:1%", None, []))
    assert {s["in_assigned_value"] for s in nominal["scores"]} == {None}


def _numbers_as_0(text: str) -> str:
    """orjson writes 1e-05 as 0.00001 and 1.5e-07 as 1.5e-7; the layout is what counts."""
    return re.sub(r"-?\d+(\.\d+)?([eE][+-]?\d+)?", "0", text)


def test_indent_is_json_dumps_layout(varied):
    new = _new_analysis(varied, "weighted-mean", "1%", [("bench", None)])
    for indent in (0, 2, 3):
        text = render(new, "json", indent=indent)
        laid_out = json.dumps(json.loads(text), indent=indent, ensure_ascii=False) + "\n"
        assert _numbers_as_0(text) == _numbers_as_0(laid_out)
    compact = render(new, "json")
    assert compact.count("\n") == 1 and compact.endswith("}\n")
    assert compact == orjson.dumps(json.loads(compact)).decode() + "\n"


def test_sigma_pt_at_some_points_only(varied, monkeypatch):
    """The service's runs give σ_pt per point, NaN where there is none: those records have
    no z keys, within one chunk and across chunks."""
    new = _new_analysis(varied, "weighted-mean", "1%", [])
    sigma = new.sigma_pt.copy()
    sigma[::2] = np.nan
    mixed = analyse_grouped(new.table, new.groups, new.points, new.assigned, sigma=sigma)
    expected = reference.to_json(mixed)
    assert {"z" in s for s in expected["scores"]} == {True, False}
    assert score_records(mixed) == expected["scores"]
    for size in (3, 1000):
        chunks = list(score_record_chunks(mixed, size))
        assert [r for c in chunks for r in c] == expected["scores"]
    assert without_consistency(json.loads(render(mixed, "json"))) == _nulls(expected)
    assert csv_without_consistency(render(mixed, "csv"), mixed) == reference.render_csv(expected)


def test_empty_compatibility_and_many_chunks(varied, monkeypatch):
    monkeypatch.setattr("analysis.offline.CHUNK", 7)
    monkeypatch.setattr("analysis.offline_json.CHUNK", 7)
    new = _new_analysis(varied, "algorithm-a", None, [])
    expected = _nulls(reference.to_json(_old_analysis(varied, "algorithm-a", None, [])))
    for indent in (None, 2):
        assert without_consistency(json.loads(render(new, "json", indent=indent))) == expected
    assert csv_without_consistency(render(new, "csv"), new) == reference.render_csv(
        reference.to_json(new)
    )


@pytest.mark.parametrize("size", [1, 7, 20_000])
def test_score_json_is_orjson_of_the_records(varied, size):
    """The records joined from column pieces are byte for byte orjson's of the records."""
    new = _new_analysis(varied, "weighted-mean", "1%", [])
    sigma = new.sigma_pt.copy()
    sigma[::3] = np.nan
    for analysis in (new, analyse_grouped(new.table, new.groups, new.points, new.assigned,
                                          sigma=sigma)):  # fmt: skip
        joined = b"[" + b",".join(score_json_chunks(analysis, size)) + b"]"
        option = orjson.OPT_SERIALIZE_NUMPY
        assert joined == orjson.dumps(reference.score_records(analysis), option=option)
