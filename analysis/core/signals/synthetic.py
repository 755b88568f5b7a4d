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
    meta = {
        "channels": ("x", "y", "z"),
        "fs_nominal_hz": fs_nominal,
        "bench": "linear",
        "frequency_hz": f,
        "a_ref_m_s2": a_ref,
        "tilt_deg": tilt,
        "rotation_deg": rotation,
    }
    return Record("synthetic-linear", ("x", "y", "z"), _finish(digits, imp, rng), meta)


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
    meta = {
        "channels": ("x", "y", "z"),
        "fs_nominal_hz": fs_nominal,
        "bench": "curvilinear",
        "frequency_hz": f,
        "radius_m": radius,
        "oscillation_angle_deg": angle_deg,
        "orientation": {"x": "tangential", "y": "radial", "z": "axial"},
    }
    mems = Record("synthetic-curvilinear", ("x", "y", "z"), _finish(digits, imp, rng), meta)
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
    t_ref = np.arange(n) / fs
    start = offset_s if offset_s is not None else 0.0123
    t_dut = start + np.arange(n) / fs
    w = 2 * np.pi * f
    ref = a_ref * np.cos(w * t_ref + 0.4)
    dut = sensitivity * a_ref * np.cos(w * t_dut + 0.4 + np.radians(phase_deg))
    dut = dut + rng.normal(0.0, noise_digits, n)
    meta: dict = {"channels": ("z",), "fs_hz": fs, "frequency_hz": f}
    if offset_s is not None:
        meta["trigger_offset_s"] = offset_s
    ref_meta = {"channels": ("ref",), "fs_hz": fs, "frequency_hz": f}
    return (Record("synthetic-phase-dut", ("z",), dut[None, :], meta),
            Record("synthetic-phase-ref", ("ref",), ref[None, :], ref_meta))  # fmt: skip


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
