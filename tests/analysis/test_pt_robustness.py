"""The offline command pt_robustness (docs/interfaces.md §5, docs/domain.md §8.3)."""

import json
from io import StringIO
from pathlib import Path

import numpy as np
import pytest
from django.core.management import call_command
from django.core.management.base import CommandError

FS = 119.0


def write_zone(path: Path, data: np.ndarray) -> str:
    np.savetxt(path, data.T, delimiter=",", header="x,y,z", comments="", fmt="%.12g")
    Path(f"{path}.json").write_text(json.dumps({"fs_hz": FS, "unit": "m/s^2"}))
    return str(path)


def triple(tmp_path: Path, rep: int, leak_db: float) -> list[str]:
    rng = np.random.default_rng(rep)
    n = 3000
    zones = [rng.normal(0, 1e-3, (3, n)) + np.array([[0.0], [0.0], [9.8]]) for _ in range(3)]
    sine = 9.8 * np.cos(2 * np.pi * 5 * np.arange(n) / FS)
    zones[1][1] += sine  # Y excited
    zones[1][0] = 10 ** (leak_db / 20) * zones[1][1]
    return [
        write_zone(tmp_path / f"r{rep}_{z}.csv", d)
        for z, d in zip(("before", "test", "after"), zones, strict=True)
    ]


def test_three_repetitions_give_rr_tables_with_mean_and_sd(tmp_path):
    files = [f for i, leak in enumerate((-24, -26, -28)) for f in triple(tmp_path, i, leak)]
    out = StringIO()
    call_command("pt_robustness", *files, "--excited-axis", "y", "--format", "json", stdout=out)
    doc = json.loads(out.getvalue())
    assert doc["excited_axis"] == "Y" and len(doc["repetitions"]) == 3
    assert [r["rr_db"]["X"] for r in doc["repetitions"]] == pytest.approx([24, 26, 28], abs=1e-9)
    assert doc["summary"]["rr_db"]["X"]["mean"] == pytest.approx(26.0, abs=1e-9)
    assert doc["summary"]["rr_db"]["X"]["sd"] == pytest.approx(2.0, abs=1e-9)
    assert doc["repetitions"][0]["rr_db"]["Y"] is None
    assert doc["repetitions"][0]["before_after"]["Z"]["mean_compatible"] is True
    assert doc["repetitions"][0]["snr_db"]["Y"] > 60
    out = StringIO()
    call_command("pt_robustness", *files, "--excited-axis", "Y", stdout=out)
    assert "RR / dB" in out.getvalue() and "mean" in out.getvalue()


def test_one_file_with_zones_is_one_repetition(tmp_path):
    before, test, after = triple(tmp_path, 0, -26)
    data = np.hstack([np.loadtxt(f, delimiter=",", skiprows=1).T for f in (before, test, after)])
    path = tmp_path / "whole.csv"
    np.savetxt(path, data.T, delimiter=",", header="x,y,z", comments="", fmt="%.12g")
    n = 3000 / FS
    Path(f"{path}.json").write_text(
        json.dumps(
            {"fs_hz": FS, "zones": {"before": [0, n], "test": [n, 2 * n], "after": [2 * n, 3 * n]}}
        )
    )
    out = StringIO()
    call_command("pt_robustness", str(path), "--excited-axis", "Y", "--format", "json", stdout=out)
    assert json.loads(out.getvalue())["repetitions"][0]["rr_db"]["X"] == pytest.approx(26, abs=1e-6)


def test_wrong_number_of_files_exits_2(tmp_path):
    files = triple(tmp_path, 0, -26)[:2]
    with pytest.raises(CommandError, match="2 files given: give BEFORE TEST AFTER") as err:
        call_command("pt_robustness", *files, "--excited-axis", "Y", stdout=StringIO())
    assert err.value.returncode == 2
