"""pt_sensitivity's phase and gyroscope figures (docs/interfaces.md §5, docs/domain.md §12.1)
on files of known truth: phase to 0.1°, angular-rate sensitivity to 0.05 %, and the note
where the records share no time base."""

import json
from io import StringIO
from pathlib import Path

import numpy as np
import pytest
from django.core.management import call_command
from django.core.management.base import CommandError

from analysis.core.phase import difference
from analysis.core.signals.synthetic import gyro_record, imu_records, linear_phase_records
from tests.analysis.test_pt_sensitivity import run, write_bin, write_csv

NOTE = "phase not determinable: no common time base"


def _files(tmp_path, dut, ref, **extra):
    path = write_bin(tmp_path, dut, "dut.bin", **extra)
    meta = {k: list(v) if isinstance(v, tuple) else v for k, v in ref.meta.items()}
    return str(path), str(write_csv(tmp_path, ref, "ref.csv", meta))


@pytest.mark.parametrize(
    ("truth", "base"), [(-12.5, "trigger"), (37.0, "start"), (179.8, "trigger")]
)
def test_the_phase_of_each_axis_is_recovered_to_a_tenth_degree(tmp_path, truth, base):
    dut, ref = linear_phase_records(phase_deg=truth, time_base=base, seed=3)
    path, ref_path = _files(tmp_path, dut, ref)
    axes = {a["axis"]: a for a in run(path, "--reference", ref_path)["axes"]}
    for axis in ("X", "Z"):
        assert axes[axis]["sensor"] == "accelerometer" and axes[axis]["phase_note"] == ""
        assert abs(float(difference(axes[axis]["phase_deg"], truth))) < 0.1
        assert 0 < axes[axis]["u_phase_deg"] < 0.05
        assert axes[axis]["sensitivity"] == pytest.approx(420.0 if axis == "X" else 425.0, rel=5e-4)
    assert axes["Y"]["phase_deg"] is None
    assert axes["Y"]["phase_note"] == "phase not determined: component too small"


def test_without_a_common_time_base_the_phase_is_a_sentence_never_a_number(tmp_path):
    dut, ref = linear_phase_records(time_base=None)
    path, ref_path = _files(tmp_path, dut, ref)
    doc = run(path, "--reference", ref_path)
    for a in doc["axes"]:
        if a["sensitivity"] is not None:
            assert (a["phase_deg"], a["u_phase_deg"], a["phase_note"]) == (None, None, NOTE)
            assert a["sensitivity"] == pytest.approx(420.0 if a["axis"] == "X" else 425.0, rel=5e-4)
    out = StringIO()
    call_command("pt_sensitivity", path, "--reference", ref_path, stdout=out)
    assert "PHASE against the reference" in out.getvalue() and NOTE in out.getvalue()


def test_the_offset_uncertainty_enters_u_phase_as_360_f_u(tmp_path):
    dut, ref = linear_phase_records()
    path, ref_path = _files(tmp_path, dut, ref)
    plain = {a["axis"]: a for a in run(path, "--reference", ref_path)["axes"]}
    path2, _ = _files(tmp_path, dut, ref, u_trigger_offset_s=2e-6)
    more = {a["axis"]: a for a in run(path2, "--reference", ref_path)["axes"]}
    assert more["X"]["u_phase_deg"] == pytest.approx(
        np.hypot(plain["X"]["u_phase_deg"], 360 * 80 * 2e-6), rel=1e-9
    )


def test_the_imu_on_the_rotating_table_gives_the_gyroscope_and_the_phases(tmp_path):
    """gz: S = 57.14 digits per °/s to 0.05 %, phase against ω to 0.1°; the tangential
    accelerometer's phase against r·θ̈ to 0.1°; the budget adds relative u's in quadrature."""
    mems, enc = imu_records(gyro_dps=57.14, gyro_phase_deg=-3.2, accel_phase_deg=-4.0)
    path, ref_path = _files(tmp_path, mems, enc)
    doc = run(path, "--reference", ref_path, "--frequency-hz", "10")
    axes = {a["axis"]: a for a in doc["axes"]}
    gz = axes["GZ"]
    assert gz["sensor"] == "gyroscope" and gz["sensitivity_unit"] == "digits/(°/s)"
    assert abs(gz["sensitivity"] / 57.14 - 1) < 5e-4
    assert gz["sensitivity_per_rad_s"] == pytest.approx(gz["sensitivity"] * 180 / np.pi)
    assert gz["omega_deg_s"] == pytest.approx(2 * np.pi * 10 * 4.25, rel=1e-4)
    assert abs(gz["phase_deg"] + 3.2) < 0.1 and gz["phase_note"] == ""
    rel = [c["contribution"] / gz["sensitivity"] for c in gz["budget"]]
    assert gz["standard_uncertainty"] / gz["sensitivity"] == pytest.approx(
        np.sqrt(sum(r * r for r in rel)), rel=1e-12
    )
    names = [c["name"] for c in gz["budget"]]
    assert names[:4] == [
        "output amplitude (fit residuals)",
        "encoder amplitude θ₀ (rad, fit residuals)",
        "excitation frequency f (Hz, encoder fit)",
        "encoder angle scale",
    ]
    assert axes["GX"]["status"] == "not excited" and axes["GX"]["sensitivity"] is None
    assert abs(axes["X"]["phase_deg"] + 4.0) < 0.1
    assert axes["X"]["sensitivity"] == pytest.approx(420.0, rel=5e-4)
    assert axes["Y"]["phase_note"] == "phase not determined: a radial axis is read at 2f"
    out = StringIO()
    call_command("pt_sensitivity", path, "--reference", ref_path, stdout=out)
    assert "ANGULAR RATE (gyroscope" in out.getvalue() and "BUDGET GZ (axial)" in out.getvalue()


def test_the_encoder_scale_uncertainty_is_a_budget_line(tmp_path):
    mems, enc = imu_records()
    path, ref_path = _files(tmp_path, mems, enc)
    plain = {a["axis"]: a for a in run(path, "--reference", ref_path)["axes"]}["GZ"]
    path2, _ = _files(tmp_path, mems, enc, u_encoder_scale_rel=1e-3)
    more = {a["axis"]: a for a in run(path2, "--reference", ref_path)["axes"]}["GZ"]
    rel0 = plain["standard_uncertainty"] / plain["sensitivity"]
    assert more["standard_uncertainty"] / more["sensitivity"] == pytest.approx(
        np.hypot(rel0, 1e-3), rel=1e-9
    )


def test_a_gyroscope_record_without_a_time_base_keeps_its_sensitivity_but_no_phase(tmp_path):
    mems, enc = imu_records(offset_s=None)
    path, ref_path = _files(tmp_path, mems, enc)
    axes = {a["axis"]: a for a in run(path, "--reference", ref_path)["axes"]}
    assert abs(axes["GZ"]["sensitivity"] / 57.14 - 1) < 5e-4
    assert (axes["GZ"]["phase_deg"], axes["GZ"]["phase_note"]) == (None, NOTE)
    assert (axes["X"]["phase_deg"], axes["X"]["phase_note"]) == (None, NOTE)


def test_a_gyroscope_and_encoder_in_one_record_csv(tmp_path):
    rec = gyro_record(sensitivity_dps=114.3, phase_deg=-3.2)
    meta = {k: list(v) if isinstance(v, tuple) else v for k, v in rec.meta.items()}
    doc = run(str(write_csv(tmp_path, rec, "gyro.csv", meta)))
    (gz,) = doc["axes"]
    assert abs(gz["sensitivity"] / 114.3 - 1) < 5e-4 and abs(gz["phase_deg"] + 3.2) < 0.1
    assert doc["fs_hz"] == 833.0 and doc["reference_source"] == "encoder of gyro.csv"


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        ({"trigger_offset_s": "NaN"}, "trigger_offset_s must be finite"),
        ({"start_time_s": 1e308}, "start_time_s must be within ±1e\\+10 s"),
        ({"u_trigger_offset_s": -1e-6}, "u_trigger_offset_s must be >= 0"),
        ({"trigger_offset_s": "0.01\u0000"}, "trigger_offset_s holds the control character"),
        ({"gyro_unit": "rad/s"}, "gyro_unit must be one of digits, deg/s"),
        ({"u_encoder_scale_rel": 2.0}, "u_encoder_scale_rel must be within ±1"),
    ],
)
def test_hostile_time_keys_exit_2_naming_the_key(tmp_path, extra, message):
    mems, enc = imu_records()
    path, ref_path = _files(tmp_path, mems, enc)
    sidecar = Path(f"{path}.json")
    sidecar.write_text(json.dumps(json.loads(sidecar.read_text()) | extra))
    with pytest.raises(CommandError, match=message) as err:
        call_command("pt_sensitivity", path, "--reference", ref_path, stdout=StringIO())
    assert err.value.returncode == 2
