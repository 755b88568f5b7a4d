"""Synthetic records of known truth (tests, benchmark and documentation).

A MEMS record is what an LSM6DSR-like sensor would output on the benches of
docs/domain.md §8: digits = S · acceleration (+ gravity), with white noise, an optional
second harmonic, rounding to int16 and a few dropped samples, sampled at an actual
rate ``fs`` that differs from the nominal one written in the metadata.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from analysis.core.groups import FloatArray
from analysis.core.signals.linear import expected_components
from analysis.core.signals.records import INT16_RAIL, Record
from analysis.core.uncertainty import G_N

XYZ = ("x", "y", "z")  # a MEMS accelerometer's channels


@dataclass(frozen=True)
class Imperfections:
    """What the sensor adds to the ideal acceleration."""

    noise_digits: float = 0.0
    harmonic: float = 0.0
    quantise: bool = False
    dropped: int = 0
    gravity: bool = True
    seed: int = 0


def _finish(digits: FloatArray, imp: Imperfections, rng: np.random.Generator) -> FloatArray:
    out = digits + rng.normal(0.0, imp.noise_digits, digits.shape) if imp.noise_digits else digits
    if imp.quantise:
        out = np.clip(np.round(out), -INT16_RAIL - 1, INT16_RAIL)
    if imp.dropped:
        keep = np.ones(out.shape[1], dtype=bool)
        keep[rng.choice(np.arange(100, out.shape[1] - 100), imp.dropped, replace=False)] = False
        out = out[:, keep]
    return np.asarray(out, dtype=np.float64)


def _wave(f: float, fs: float, duration: float, phase: float, harmonic: float) -> FloatArray:
    t = np.arange(round(duration * fs)) / fs
    x = np.cos(2 * np.pi * f * t + phase)
    return np.asarray(x + harmonic * np.cos(2 * (2 * np.pi * f * t + phase)), dtype=np.float64)


def _mems_meta(
    channels: tuple[str, ...], bench: str, f: float, fs_nominal: float, **extra: object
) -> dict[str, object]:
    """The sidecar of a MEMS record on ``bench`` whose clock is only nominal
    (docs/interfaces.md §2), then ``extra``."""
    return {"channels": channels, "fs_nominal_hz": fs_nominal, "bench": bench,
            "frequency_hz": f, **extra}  # fmt: skip


def _on_the_table(radius: float, angle_deg: float) -> dict[str, object]:
    """The sidecar keys of a record on the oscillating rotating table (x tangential)."""
    return {"radius_m": radius, "oscillation_angle_deg": angle_deg,
            "orientation": {"x": "tangential", "y": "radial", "z": "axial"}}  # fmt: skip


def _reference(name: str, a_ref: float, f: float, fs: float, duration: float,
               **extra: object) -> Record:  # fmt: skip
    """The reference accelerometer's record (``ref``, m/s²) on its trusted clock ``fs``:
    a_ref·cos(2πft + 0.4), the phase every DUT record here is written against."""
    w = 2 * np.pi * f
    ref = a_ref * np.cos(w * (np.arange(round(duration * fs)) / fs) + 0.4)
    meta = {"channels": ("ref",), "fs_hz": fs, "frequency_hz": f, **extra}
    return Record(name, ("ref",), ref[None, :], meta)


def linear_record(
    sensitivity: tuple[float, float, float] = (420.0, 418.0, 425.0),
    *,
    fs: float = 1663.7,
    fs_nominal: float = 1660.0,
    f: float = 10.0,
    a_ref: float = 10.0,
    tilt: float = 75.0,
    rotation: float = 0.0,
    duration: float = 40.0,
    phase: float = 0.3,
    imp: Imperfections | None = None,
) -> Record:
    """x, y, z in digits on the tilt plate; gravity along the plate normal."""
    imp = imp or Imperfections()
    rng = np.random.default_rng(imp.seed)
    s = np.asarray(sensitivity)[:, None]
    comp = expected_components(a_ref, tilt, rotation)[:, None]
    static = expected_components(G_N, tilt, rotation)[:, None] if imp.gravity else 0.0
    digits = s * (comp * _wave(f, fs, duration, phase, imp.harmonic)[None, :] + static)
    meta = _mems_meta(XYZ, "linear", f, fs_nominal, a_ref_m_s2=a_ref, tilt_deg=tilt,
                      rotation_deg=rotation)  # fmt: skip
    return Record("synthetic-linear", XYZ, _finish(digits, imp, rng), meta)


def curvilinear_records(
    sensitivity: tuple[float, float, float] = (420.0, 418.0, 425.0),
    *,
    fs: float = 1663.7,
    fs_nominal: float = 1660.0,
    f: float = 10.0,
    angle_deg: float = 8.5,
    radius: float = 0.170,
    duration: float = 40.0,
    phase: float = 0.3,
    encoder_fs: float = 1000.0,
    encoder_noise_rad: float = 0.0,
    imp: Imperfections | None = None,
) -> tuple[Record, Record]:
    """MEMS record (x tangential, y radial, z axial with gravity) and encoder record."""
    imp = imp or Imperfections()
    rng = np.random.default_rng(imp.seed + 1)
    theta0 = np.radians(angle_deg) / 2
    w = 2 * np.pi * f
    base = _wave(f, fs, duration, phase, 0.0)
    double = _wave(2 * f, fs, duration, 2 * phase, 0.0)
    a_t = -radius * theta0 * w**2 * (base + imp.harmonic * double)
    a_r = radius * (w * theta0) ** 2 / 2 * (1 - double)
    a_z = np.full_like(base, G_N if imp.gravity else 0.0)
    digits = np.asarray(sensitivity)[:, None] * np.stack([a_t, a_r, a_z])
    meta = _mems_meta(XYZ, "curvilinear", f, fs_nominal, **_on_the_table(radius, angle_deg))
    mems = Record("synthetic-curvilinear", XYZ, _finish(digits, imp, rng), meta)
    enc = theta0 * _wave(f, encoder_fs, duration, phase, 0.0)
    enc = enc + rng.normal(0.0, encoder_noise_rad, enc.size) if encoder_noise_rad else enc
    enc_meta = {"channels": ("encoder_rad",), "fs_hz": encoder_fs}
    return mems, Record("synthetic-encoder", ("encoder_rad",), enc[None, :], enc_meta)


def phase_records(
    sensitivity: float = 420.0,
    phase_deg: float = -12.5,
    *,
    f: float = 80.0,
    fs: float = 1666.0,
    a_ref: float = 10.0,
    duration: float = 20.0,
    offset_s: float | None = 0.0123,
    noise_digits: float = 2.0,
    seed: int = 0,
) -> tuple[Record, Record]:
    """A DUT axis (``z``, digits) whose sensitivity has the phase ``phase_deg`` against
    the acceleration, and the reference accelerometer's record (``ref``, m/s²) started
    ``offset_s`` earlier on the same clock (its sidecar ``trigger_offset_s``; None: no
    common time base written): two records, as two instruments write them."""
    rng = np.random.default_rng(seed)
    n = round(duration * fs)
    start = offset_s if offset_s is not None else 0.0123
    t_dut = start + np.arange(n) / fs
    w = 2 * np.pi * f
    dut = sensitivity * a_ref * np.cos(w * t_dut + 0.4 + np.radians(phase_deg))
    dut = dut + rng.normal(0.0, noise_digits, n)
    meta: dict = {"channels": ("z",), "fs_hz": fs, "frequency_hz": f}
    if offset_s is not None:
        meta["trigger_offset_s"] = offset_s
    return (Record("synthetic-phase-dut", ("z",), dut[None, :], meta),
            _reference("synthetic-phase-ref", a_ref, f, fs, duration))  # fmt: skip


def gyro_record(
    sensitivity_dps: float = 114.3,
    phase_deg: float = -3.2,
    *,
    f: float = 2.0,
    fs: float = 833.0,
    angle_deg: float = 30.0,
    duration: float = 30.0,
    noise_digits: float = 20.0,
    encoder_noise_rad: float = 1e-5,
    seed: int = 0,
) -> Record:
    """A gyroscope axis (``gz``, digits) on the oscillating rotating table and the table's
    encoder angle (``encoder_rad``) in one record: θ(t) = θ₀ cos(2πft), θ₀ half the peak-
    to-peak ``angle_deg``; gz = S·(dθ/dt in °/s) shifted by ``phase_deg`` (a filter lag)."""
    rng = np.random.default_rng(seed)
    t = np.arange(round(duration * fs)) / fs
    w = 2 * np.pi * f
    theta0 = np.radians(angle_deg) / 2
    theta = theta0 * np.cos(w * t)
    omega0_dps = np.degrees(theta0) * w
    # dθ/dt = −θ₀ω sin(ωt) = θ₀ω cos(ωt + 90°)
    gz = sensitivity_dps * omega0_dps * np.cos(w * t + np.pi / 2 + np.radians(phase_deg))
    data = np.stack([gz + rng.normal(0.0, noise_digits, t.size),
                     theta + rng.normal(0.0, encoder_noise_rad, t.size)])  # fmt: skip
    meta = {"channels": ("gz", "encoder_rad"), "fs_hz": fs, "frequency_hz": f,
            "bench": "curvilinear"}  # fmt: skip
    return Record("synthetic-gyro", ("gz", "encoder_rad"), data, meta)


def linear_phase_records(
    sensitivity: tuple[float, float, float] = (420.0, 418.0, 425.0),
    phase_deg: float = -12.5,
    *,
    f: float = 80.0,
    fs: float = 1663.7,
    fs_nominal: float | None = 1660.0,
    fs_ref: float = 5000.0,
    tilt: float = 75.0,
    a_ref: float = 10.0,
    duration: float = 20.0,
    offset_s: float = 0.0123,
    time_base: str | None = "trigger",
    noise_digits: float = 2.0,
    seed: int = 0,
) -> tuple[Record, Record]:
    """A linear-bench record (x, y, z digits, tilt θ, α = 0) whose sensitivity lags the
    acceleration by ``phase_deg`` on every axis, and the reference accelerometer's record
    (``ref``, m/s², trusted clock ``fs_ref``) started ``offset_s`` earlier.  ``time_base``:
    ``"trigger"`` writes ``trigger_offset_s``, ``"start"`` both ``start_time_s``, None
    neither.  With ``fs_nominal`` the MEMS clock is only nominal (actual ``fs``)."""
    rng = np.random.default_rng(seed)
    w = 2 * np.pi * f
    t_dut = offset_s + np.arange(round(duration * fs)) / fs
    t_rad = np.radians(tilt)
    comp = a_ref * np.array([np.sin(t_rad), 0.0, np.cos(t_rad)])[:, None]  # signed projection
    static = expected_components(G_N, tilt, 0.0)[:, None]
    wave = np.cos(w * t_dut + 0.4 + np.radians(phase_deg))[None, :]
    digits = np.asarray(sensitivity)[:, None] * (comp * wave + static)
    digits = np.round(digits + rng.normal(0.0, noise_digits, digits.shape))
    meta: dict = {"channels": XYZ, "bench": "linear", "frequency_hz": f,
                  "tilt_deg": tilt, "rotation_deg": 0.0}  # fmt: skip
    meta |= {"fs_nominal_hz": fs_nominal} if fs_nominal else {"fs_hz": fs}
    ref_meta: dict = {}
    if time_base == "trigger":
        meta["trigger_offset_s"] = offset_s
    elif time_base == "start":
        meta["start_time_s"], ref_meta["start_time_s"] = 1.7e9 + offset_s, 1.7e9
    return (Record("synthetic-linear-phase", XYZ, digits, meta),
            _reference("synthetic-linear-ref", a_ref, f, fs_ref, duration, **ref_meta))  # fmt: skip


def imu_records(
    sensitivity: tuple[float, float, float] = (420.0, 418.0, 425.0),
    gyro_dps: float = 57.14,
    *,
    accel_phase_deg: float = -4.0,
    gyro_phase_deg: float = -3.2,
    f: float = 10.0,
    fs: float = 1663.7,
    fs_nominal: float = 1660.0,
    angle_deg: float = 8.5,
    radius: float = 0.170,
    duration: float = 20.0,
    encoder_fs: float = 1000.0,
    offset_s: float | None = 0.0071,
    noise_digits: float = 2.0,
    seed: int = 0,
) -> tuple[Record, Record]:
    """An IMU on the oscillating rotating table (x tangential, y radial, z axial; gx, gy,
    gz about the same axes, digits) and the table's encoder record (``encoder_rad``,
    trusted clock).  θ(t) = θ₀ cos(2πft) with θ₀ half the swing; the tangential axis lags
    r·θ̈ by ``accel_phase_deg``, gz = ``gyro_dps``·ω shifted by ``gyro_phase_deg``.  The
    IMU record starts ``offset_s`` after the encoder's (its ``trigger_offset_s``; None:
    no common time base written)."""
    rng = np.random.default_rng(seed)
    w, theta0 = 2 * np.pi * f, np.radians(angle_deg) / 2
    t = (offset_s or 0.0) + np.arange(round(duration * fs)) / fs
    a_t = radius * theta0 * w**2 * np.cos(w * t + np.pi + np.radians(accel_phase_deg))
    a_r = radius * (w * theta0) ** 2 / 2 * (1 - np.cos(2 * w * t))
    omega_dps = np.degrees(theta0) * w * np.cos(w * t + np.pi / 2 + np.radians(gyro_phase_deg))
    accel = np.asarray(sensitivity)[:, None] * np.stack([a_t, a_r, np.full_like(t, G_N)])
    gyro = np.stack([np.zeros_like(t), np.zeros_like(t), gyro_dps * omega_dps])
    data = np.round(np.vstack([accel, gyro]) + rng.normal(0.0, noise_digits, (6, t.size)))
    channels = (*XYZ, "gx", "gy", "gz")
    meta = _mems_meta(channels, "curvilinear", f, fs_nominal, **_on_the_table(radius, angle_deg),
                      gyro_unit="digits", gyro_full_scale_dps=500.0)  # fmt: skip
    if offset_s is not None:
        meta["trigger_offset_s"] = offset_s
    enc = theta0 * np.cos(w * np.arange(round(duration * encoder_fs)) / encoder_fs)
    enc_meta = {"channels": ("encoder_rad",), "fs_hz": encoder_fs, "frequency_hz": f}
    return (Record("synthetic-imu", channels, data, meta),
            Record("synthetic-imu-encoder", ("encoder_rad",), enc[None, :], enc_meta))  # fmt: skip
