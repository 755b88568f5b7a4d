"""The offline command pt_sensitivity (docs/interfaces.md §5) on synthetic files of known truth."""

import json
import subprocess
import sys
from io import StringIO
from pathlib import Path

import numpy as np
import pytest
from django.core.management import call_command
from django.core.management.base import CommandError
from scipy import stats

from analysis.core.signals.synthetic import Imperfections, curvilinear_records, linear_record

ROOT = Path(__file__).resolve().parents[2]
TRUTH = (420.0, 418.0, 425.0)
AXIS_KEYS = {
    "dof_eff",
    "axis",
    "direction",
    "frequency_hz",
    "output_amplitude",
    "reference_amplitude_m_s2",
    "sensitivity",
    "standard_uncertainty",
    "budget",
}


def write_bin(tmp_path: Path, rec, name="run1.bin", **meta) -> Path:
    path = tmp_path / name
    path.write_bytes(np.round(rec.data.T).astype("<i2").tobytes())
    sidecar = {k: (list(v) if isinstance(v, tuple) else v) for k, v in rec.meta.items()} | meta
    Path(f"{path}.json").write_text(json.dumps(sidecar))
    return path


def write_csv(tmp_path: Path, rec, name: str, meta: dict) -> Path:
    path = tmp_path / name
    header = ",".join(rec.channels)
    np.savetxt(path, rec.data.T, delimiter=",", header=header, comments="", fmt="%.10g")
    Path(f"{path}.json").write_text(json.dumps(meta))
    return path


def run(*args: str) -> dict:
    out = StringIO()
    call_command("pt_sensitivity", *args, "--format", "json", stdout=out)
    return json.loads(out.getvalue())


def test_linear_binary_record_json(tmp_path):
    rec = linear_record(
        TRUTH, tilt=75, rotation=0, imp=Imperfections(noise_digits=3, quantise=True)
    )
    doc = run(str(write_bin(tmp_path, rec)))
    assert {"fs_hz", "u_fs_hz", "axes", "method", "software_version"} <= doc.keys()
    assert doc["method"] == "sine-fit" and doc["fs_hz"] == pytest.approx(1663.7, abs=0.01)
    axes = {a["axis"]: a for a in doc["axes"]}
    assert all(a.keys() >= AXIS_KEYS for a in doc["axes"])
    assert axes["X"]["sensitivity"] == pytest.approx(420.0, rel=5e-4)
    assert axes["Z"]["sensitivity"] == pytest.approx(425.0, rel=5e-4)
    assert axes["Y"]["sensitivity"] is None and axes["Y"]["status"] == "component too small"
    assert axes["X"]["reference_amplitude_m_s2"] == pytest.approx(10 * np.sin(np.radians(75)))
    u = np.sqrt(sum(c["contribution"] ** 2 for c in axes["X"]["budget"]))
    assert axes["X"]["standard_uncertainty"] == pytest.approx(u, rel=1e-12)
    # ν_eff by Welch–Satterthwaite from the budget's own components (JCGM 100 G.4), and
    # k the Student t quantile for 95 % at ν_eff (scipy as the independent reference)
    finite = [c for c in axes["X"]["budget"] if c["dof"] is not None and c["contribution"] > 0]
    nu_eff = u**4 / sum(c["contribution"] ** 4 / c["dof"] for c in finite)
    assert axes["X"]["dof_eff"] == pytest.approx(nu_eff, rel=1e-12)
    assert axes["X"]["coverage_factor"] == pytest.approx(stats.t.ppf(0.975, nu_eff), rel=1e-9)
    assert axes["Y"]["dof_eff"] is None  # no budget where the component is too small


def test_options_override_the_sidecar_and_paper_mode_is_worse(tmp_path):
    rec = linear_record(TRUTH, f=20.0, tilt=75, rotation=0)
    path = write_bin(tmp_path, rec, frequency_hz=5.0, bench="curvilinear")
    fit = run(str(path), "--frequency-hz", "20", "--bench", "linear")
    study = run(str(path), "--frequency-hz", "20", "--bench", "linear", "--method", "paper")
    assert study["method"] == "paper" and study["fs_hz"] == 1664.0
    for a_fit, a_study in zip(fit["axes"], study["axes"], strict=True):
        if a_fit["sensitivity"]:
            truth = TRUTH["XYZ".index(a_fit["axis"])]
            assert abs(a_fit["sensitivity"] - truth) < abs(a_study["sensitivity"] - truth)


def test_curvilinear_csv_with_encoder_reference_table(tmp_path):
    mems, encoder = curvilinear_records(TRUTH, f=5.0, angle_deg=34.0)
    meta = dict(mems.meta, channels=list(mems.channels))
    path = write_csv(tmp_path, mems, "mems.csv", meta)
    ref = write_csv(tmp_path, encoder, "enc.csv", {"fs_hz": 1000.0})
    doc = run(str(path), "--reference", str(ref))
    axes = {a["axis"]: a for a in doc["axes"]}
    assert axes["X"]["direction"] == "tangential" and axes["Y"]["direction"] == "radial"
    assert axes["X"]["reference_amplitude_m_s2"] == pytest.approx(49.78, abs=0.01)
    assert axes["Y"]["analysis_frequency_hz"] == pytest.approx(10.0, rel=1e-6)
    assert axes["X"]["sensitivity"] == pytest.approx(420.0, rel=5e-4)
    assert axes["Y"]["sensitivity"] == pytest.approx(418.0, rel=5e-4)
    out = StringIO()
    call_command("pt_sensitivity", str(path), "--reference", str(ref), stdout=out)
    text = out.getvalue()
    assert "curvilinear bench, f = 5 Hz, method sine-fit" in text
    assert "BUDGET X (tangential)" in text and "radius r (m)" in text


@pytest.mark.parametrize(
    ("setup", "message"),
    [
        (lambda p: p.write_bytes(b"\x01\x00\x02"), "3 bytes is not a whole number of int16"),
        (lambda p: p.write_bytes(b"\x01\x00"), "needs its JSON sidecar"),
    ],
)
def test_bad_input_exits_2(tmp_path, setup, message):
    path = tmp_path / "bad.bin"
    setup(path)
    if "sidecar" not in message:
        Path(f"{path}.json").write_text(json.dumps({"channels": ["x"]}))
    with pytest.raises(CommandError, match=message) as err:
        call_command("pt_sensitivity", str(path), stdout=StringIO())
    assert err.value.returncode == 2


def test_truncated_csv_exit_code_2_in_a_real_process(tmp_path):
    path = tmp_path / "cut.csv"
    path.write_text("x,y,z\n1,2,3\n4,5\n")
    proc = subprocess.run(
        [sys.executable, "manage.py", "pt_sensitivity", str(path)],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 2
    assert "cut.csv line 3: 2 fields, expected 3 (x, y, z) (the last line: truncated" in proc.stderr
    assert proc.stdout == ""
