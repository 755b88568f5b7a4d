"""Readers of raw records (docs/interfaces.md §2): good files and every error named by place."""

import json

import numpy as np
import pytest

from analysis.core.signals.records import SignalInputError, load_record, read_csv, read_int16


def test_csv_with_time_column_and_sidecar_metadata():
    rec = read_csv(b"t_s,x,ref\n0,1,0.5\n0.001,-2,0.25\n0.002,3,0\n", "a.csv", {"bench": "linear"})
    assert rec.channels == ("x", "ref")
    np.testing.assert_array_equal(rec.data, [[1, -2, 3], [0.5, 0.25, 0]])
    assert rec.t_s is not None
    np.testing.assert_allclose(rec.t_s, [0, 0.001, 0.002])
    assert rec.sampling_rate() == (pytest.approx(1000.0), False)
    assert rec.meta["bench"] == "linear" and rec.clipped == {}


def test_csv_without_time_column_semicolons_and_bom():
    rec = read_csv("\ufeffX;Y\n1;2\n3;4\n".encode(), "b.csv", {"fs_hz": 100})
    assert rec.channels == ("x", "y") and rec.t_s is None
    assert rec.sampling_rate() == (100.0, True)


@pytest.mark.parametrize(
    ("content", "message"),
    [
        (
            b"x,y\n1,2\n3,4\n5",
            "b.csv line 4: 1 field, expected 2 (x, y) (the last line: truncated",
        ),
        (b"x,y\n1,2\n3,4,5\n6,7\n", "b.csv line 3: 3 fields, expected 2"),
        (b"x,y\n1,2\n3,abc\n", "b.csv line 3, channel y: not a number: 'abc'"),
        (b"x,y\n1,2\n3,\n", "b.csv line 3, channel y: not a number: ''"),
        (b"x,y\n1,2\n3,4\nnan,5\n", "b.csv line 4, channel x: non-finite sample nan"),
        (b"x,y\n1,inf\n", "b.csv line 2, channel y: non-finite sample inf"),
        (b"x,w\n1,2\n", "unknown channel 'w'"),
        (b"x,y\n", "no samples after the header"),
        (b"t_s,x\n0,1\n0,2\n", "b.csv line 3: t_s does not increase"),
    ],
)
def test_csv_errors_name_file_line_and_channel(content, message):
    with pytest.raises(SignalInputError) as exc:
        read_csv(content, "b.csv")
    assert message in str(exc.value)


def test_csv_header_disagreeing_with_sidecar_channels():
    with pytest.raises(
        SignalInputError, match="header has channels x, y but the metadata says x, y, z"
    ):
        read_csv(b"x,y\n1,2\n", "c.csv", {"channels": ["x", "y", "z"]})


def test_int16_interleaved_little_endian():
    frames = np.array([[1, -2, 300], [-32000, 5, 6]], dtype="<i2")
    rec = read_int16(
        frames.tobytes(), "r.bin", {"channels": ["x", "y", "z"], "fs_nominal_hz": 1660}
    )
    np.testing.assert_array_equal(rec.data, [[1, -32000], [-2, 5], [300, 6]])
    assert rec.sampling_rate() == (1660.0, False)


def test_int16_truncated_and_wrong_channel_count():
    raw = np.arange(7, dtype="<i2").tobytes()
    with pytest.raises(
        SignalInputError,
        match=r"r.bin: 7 samples do not fill frames of 3 channels "
        r"\(x, y, z\): the last frame \(sample 2\) has 1 of 3 values, channel y missing",
    ):
        read_int16(raw, "r.bin", {"channels": ["x", "y", "z"]})
    with pytest.raises(SignalInputError, match="13 bytes is not a whole number of int16 samples"):
        read_int16(raw[:13], "r.bin", {"channels": ["x"]})
    with pytest.raises(SignalInputError, match="must list 'channels'"):
        read_int16(raw, "r.bin", {})


def test_clipping_is_flagged_per_axis_with_first_sample():
    frames = np.array([[0, 1], [32767, 2], [-32768, 3], [5, -32767]], dtype="<i2")
    rec = read_int16(frames.tobytes(), "r.bin", {"channels": ["x", "y"]})
    assert rec.clipped == {"x": (2, 1), "y": (1, 3)}
    ok = read_int16(np.array([[32766, -32766]], "<i2").tobytes(), "r.bin", {"channels": ["x", "y"]})
    assert ok.clipped == {}


def test_clipping_not_checked_for_accelerations_in_m_s2():
    rec = read_csv(b"x,ref\n40000,40000\n", "m.csv", {"unit": "m/s^2"})
    assert rec.clipped == {}
    digits = read_csv(b"x,ref\n40000,40000\n", "m.csv")
    assert digits.clipped == {"x": (1, 0)}


@pytest.mark.parametrize(
    ("meta", "message"),
    [
        ({"fs_hz": -3}, "fs_hz must be > 0, got -3"),
        ({"tilt_deg": "abc"}, "tilt_deg must be a number, got 'abc'"),
        ({"bench": "spiral"}, "bench must be one of linear, curvilinear, got 'spiral'"),
        ({"orientation": {"x": "up"}}, "orientation 'x': 'up'"),
        ({"zones": {"before": [3, 1]}}, "zone 'before' ends before it starts"),
    ],
)
def test_metadata_errors(meta, message):
    with pytest.raises(SignalInputError, match=message):
        read_csv(b"x\n1\n", "m.csv", meta)


def test_load_record_reads_binary_with_sidecar_and_overrides(tmp_path):
    path = tmp_path / "run1.bin"
    path.write_bytes(np.array([[1, 2], [3, 4]], "<i2").tobytes())
    (tmp_path / "run1.bin.json").write_text(json.dumps({"channels": ["x", "y"], "frequency_hz": 5}))
    rec = load_record(path, overrides={"frequency_hz": 10.0, "bench": None})
    assert rec.meta["frequency_hz"] == 10.0 and "bench" not in rec.meta
    np.testing.assert_array_equal(rec.data, [[1, 3], [2, 4]])
    (tmp_path / "run1.bin.json").unlink()
    with pytest.raises(SignalInputError, match=r"run1.bin: a binary record needs its JSON sidecar"):
        load_record(path)
    with pytest.raises(SignalInputError, match="no such file"):
        load_record(tmp_path / "missing.csv")
    bad = tmp_path / "bad.json"
    bad.write_text("{nope")
    with pytest.raises(SignalInputError, match=r"bad\.json: not valid JSON"):
        load_record(path, sidecar=bad)


def test_csv_with_crlf_line_endings_and_trailing_blank_line():
    rec = read_csv(b"t_s,x\r\n0,1\r\n0.5,2\r\n\r\n", "w.csv")
    np.testing.assert_array_equal(rec.data, [[1, 2]])
    assert rec.sampling_rate() == (2.0, False)
