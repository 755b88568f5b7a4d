"""Phase and gyroscope axes wired onto the benches' results (docs/domain.md §12.1):
``record_analysis`` on synthetic records of known truth."""

from __future__ import annotations

import numpy as np
import pytest

from analysis.core.phase import difference
from analysis.core.signals.records import Record, SignalInputError, parse_meta
from analysis.core.signals.sensitivity import record_analysis
from analysis.core.signals.synthetic import imu_records, linear_phase_records


def _axes(result):
    return {a["axis"]: a for a in result.to_dict()["axes"]}


def test_a_negative_projection_on_the_plate_is_taken_out_of_the_phase():
    """Tilt 105°: cos θ < 0, so z sees −a·|cos θ|; the sensitivity's phase is still 20°."""
    dut, ref = linear_phase_records(phase_deg=20.0, tilt=105.0, fs_nominal=None)
    axes = _axes(record_analysis(dut, ref))
    assert abs(float(difference(axes["Z"]["phase_deg"], 20.0))) < 0.1
    assert abs(float(difference(axes["X"]["phase_deg"], 20.0))) < 0.1


def test_a_ref_channel_in_the_same_record_needs_no_time_keys():
    dut, ref = linear_phase_records(phase_deg=-30.0, fs_nominal=None, fs_ref=1663.7, offset_s=0.0)
    both = Record("both", ("x", "y", "z", "ref"), np.vstack([dut.data, ref.data]),
                  {k: v for k, v in dut.meta.items() if k != "trigger_offset_s"}
                  | {"channels": ("x", "y", "z", "ref")})  # fmt: skip
    axes = _axes(record_analysis(both))
    assert abs(float(difference(axes["X"]["phase_deg"], -30.0))) < 0.1


def test_no_reference_channel_says_so():
    dut, _ = linear_phase_records(time_base=None)
    rec = Record(dut.name, dut.channels, dut.data, dut.meta | {"a_ref_m_s2": 10.0})
    axes = _axes(record_analysis(rec))
    assert axes["X"]["phase_deg"] is None
    assert axes["X"]["phase_note"] == "phase not determinable: no reference channel"


def test_a_reference_record_with_a_nominal_rate_gives_no_phase_number():
    """Its fit at a nominal rate would drift by degrees over the record: no number."""
    dut, ref = linear_phase_records()
    meta = {k: v for k, v in ref.meta.items() if k != "fs_hz"} | {"fs_nominal_hz": 5000.0}
    nominal = Record(ref.name, ref.channels, ref.data, meta)
    axes = _axes(record_analysis(dut, nominal))
    assert axes["X"]["sensitivity"] == pytest.approx(420.0, rel=5e-4)
    assert axes["X"]["phase_deg"] is None
    assert axes["X"]["phase_note"].endswith("only nominal (give its fs_hz)")


def test_gyroscope_channels_on_the_linear_bench_or_without_an_encoder_are_not_computed():
    mems, enc = imu_records()
    axes = _axes(record_analysis(mems, enc))
    assert axes["GZ"]["status"] == "ok"
    data = mems.data[[0, 1, 2, 5]]
    no_encoder = Record(
        "imu", ("x", "y", "z", "gz"), data, mems.meta | {"channels": ("x", "y", "z", "gz")}
    )
    with pytest.raises(SignalInputError, match="ref or encoder_rad"):
        record_analysis(no_encoder)  # the accelerometer's bench needs it first


def test_a_clipped_gyroscope_axis_is_not_used():
    mems, enc = imu_records(gyro_dps=130.0)  # 130 × 267 °/s is beyond the int16 rail
    data = np.clip(mems.data, -32768, 32767)
    clipped = Record(mems.name, mems.channels, data, mems.meta,
                     clipped={"gz": (int((np.abs(data[5]) >= 32767).sum()), 0)})  # fmt: skip
    axes = _axes(record_analysis(clipped, enc))
    assert axes["GZ"]["status"] == "clipped" and axes["GZ"]["sensitivity"] is None
    assert axes["GZ"]["phase_note"] == "phase not determined: clipped"


@pytest.mark.parametrize(
    ("key", "value", "message"),
    [
        ("trigger_offset_s", float("nan"), "must be finite"),
        ("trigger_offset_s", 1e308, "must be within"),
        ("start_time_s", -1e308, "must be within"),
        ("u_trigger_offset_s", -0.001, "must be >= 0"),
        ("u_trigger_offset_s", "1\x00", "holds the control character U\\+0000"),
        ("gyro_full_scale_dps", 0, "must be > 0"),
        ("u_encoder_scale_rel", -0.1, "must be >= 0"),
    ],
)
def test_hostile_metadata_is_refused_by_key(key, value, message):
    with pytest.raises(SignalInputError, match=f"sidecar: {key} {message}"):
        parse_meta({key: value}, "sidecar")


def test_the_time_keys_are_kept_as_numbers():
    meta = parse_meta({"trigger_offset_s": "-0.5", "u_trigger_offset_s": 0, "start_time_s": 1.7e9,
                       "gyro_unit": "deg/s", "channels": ["gx", "encoder_rad"]}, "m")  # fmt: skip
    assert meta["trigger_offset_s"] == -0.5 and meta["start_time_s"] == 1.7e9
    assert meta["channels"] == ("gx", "encoder_rad")
