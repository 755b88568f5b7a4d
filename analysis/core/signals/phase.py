"""Phase of the sensitivity and the gyroscope's angular-rate sensitivity from raw records
(docs/domain.md §12.1).

Both come from the same three-parameter sine fits (IEEE 1057 §8.5, with the first three
harmonics modelled) as the magnitude.  A fit gives each channel's phase at the middle
sample of its record; a channel's phase at a common instant t = 0 is
φ(0) = φ_mid − 2π·f·t_mid, with t_mid the time of the middle sample on a common clock.
The phase of the sensitivity is the output's phase minus the input's, wrapped into
(−180°, 180°].

A common time base exists when both channels are in one record (one clock, the same
samples), or when the DUT record's sidecar gives ``trigger_offset_s`` — the time of its
first sample minus that of the reference record's first sample — optionally with its
standard uncertainty ``u_trigger_offset_s``, or when both sidecars give ``start_time_s``
of their first sample on one clock.  Otherwise the result is "phase not determinable: no
common time base", never a number.

The gyroscope on the oscillating rotating table: the encoder gives the table's angle
θ(t) = θ₀ cos(2πft + φ_θ) (channel ``encoder_rad``, radians, as on the curvilinear
bench), so the angular rate ω = dθ/dt has the amplitude
ω₀ = 2πf·θ₀ (°/s) and leads θ by 90°.  The angular-rate sensitivity is the gyroscope
output's amplitude over ω₀ (digits per °/s), its phase φ_gyro − (φ_θ + 90°).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from analysis.core.groups import FloatArray
from analysis.core.phase import wrap
from analysis.core.signals.budget import Budget, Input, sensitivity_budget
from analysis.core.signals.records import Record, SignalInputError
from analysis.core.signals.sinefit import fit_known_frequency

NO_TIME_BASE = "phase not determinable: no common time base"
HARMONICS = (1, 2, 3)


@dataclass(frozen=True)
class PhaseResult:
    """The phase of a sensitivity in degrees with its standard uncertainty, or None with
    the reason in ``note``."""

    phase_deg: float | None
    u_phase_deg: float | None
    note: str = ""


@dataclass(frozen=True)
class ChannelFit:
    """One channel fitted at f: amplitude, phase at the common instant t = 0 (degrees,
    wrapped) and their standard uncertainties from the residuals."""

    amplitude: float
    u_amplitude: float
    phase_deg: float
    u_phase_deg: float
    dof: float = float("inf")


def fit_channel(samples: FloatArray, f_hz: float, fs_hz: float, start_s: float = 0.0) -> ChannelFit:
    """Three-parameter fit of one channel at f (ν = f/fs), its phase carried back from
    the middle sample to t = 0 with the record's first sample at ``start_s``."""
    if not (np.isfinite(f_hz) and f_hz > 0 and np.isfinite(fs_hz) and fs_hz > 2 * f_hz):
        raise SignalInputError(f"a sine fit needs 0 < f < fs/2 (f = {f_hz!r}, fs = {fs_hz!r})")
    y = np.asarray(samples, dtype=np.float64)
    fit = fit_known_frequency(y[None, :], f_hz / fs_hz, HARMONICS)
    t_mid = start_s + (y.size - 1) / 2.0 / fs_hz
    phase = float(np.rad2deg(fit.phase[0, 0]) - 360.0 * f_hz * t_mid)
    return ChannelFit(
        amplitude=float(fit.amplitude[0, 0]),
        u_amplitude=float(fit.u_amplitude[0, 0]),
        phase_deg=float(wrap(phase)),
        u_phase_deg=float(np.rad2deg(fit.u_phase[0, 0])),
        dof=float(fit.dof),
    )


def _seconds(meta: dict[str, Any], key: str, where: str) -> float | None:
    if meta.get(key) is None:
        return None
    value = meta[key]
    if isinstance(value, bool) or not isinstance(value, int | float | str):
        raise SignalInputError(f"{where}: {key} must be a number of seconds, got {value!r}")
    try:
        out = float(value)
    except ValueError:
        raise SignalInputError(
            f"{where}: {key} must be a number of seconds, got {value!r}"
        ) from None
    if not np.isfinite(out):
        raise SignalInputError(f"{where}: {key} must be finite, got {value!r}")
    return out


def time_base(dut: Record, reference: Record | None) -> tuple[float, float, float] | None:
    """(start of the DUT record, start of the reference record, u of their offset) in
    seconds on a common clock, or None where there is no common time base.  Start times
    are taken relative to the reference's (a clock time of 1.7e9 s would otherwise cost
    digits in 360°·f·t)."""
    if reference is None or reference is dut:
        return 0.0, 0.0, 0.0
    offset = _seconds(dut.meta, "trigger_offset_s", dut.name)
    u_offset = _seconds(dut.meta, "u_trigger_offset_s", dut.name) or 0.0
    if u_offset < 0:
        raise SignalInputError(f"{dut.name}: u_trigger_offset_s must be >= 0")
    if offset is not None:
        return offset, 0.0, u_offset
    starts = (_seconds(dut.meta, "start_time_s", dut.name),
              _seconds(reference.meta, "start_time_s", reference.name))  # fmt: skip
    if starts[0] is not None and starts[1] is not None:
        return starts[0] - starts[1], 0.0, u_offset
    return None


def relative_phase(
    dut: Record,
    channel: str,
    reference: Record | None,
    reference_channel: str,
    f_hz: float,
    *,
    fs_hz: float | None = None,
    fs_reference_hz: float | None = None,
) -> PhaseResult:
    """Phase of the DUT channel's sensitivity: its output's phase minus the reference
    channel's (of the same record when ``reference`` is None), wrapped, with
    u² = u²(φ_dut) + u²(φ_ref) + (360°·f·u(offset))²; or NO_TIME_BASE."""
    base = time_base(dut, reference)
    if base is None:
        return PhaseResult(None, None, NO_TIME_BASE)
    ref = dut if reference is None else reference
    fs_d = fs_hz if fs_hz is not None else dut.sampling_rate()[0]
    fs_r = fs_reference_hz if fs_reference_hz is not None else ref.sampling_rate()[0]
    out = fit_channel(dut.channel(channel), f_hz, fs_d, base[0])
    inp = fit_channel(ref.channel(reference_channel), f_hz, fs_r, base[1])
    u = float(np.sqrt(out.u_phase_deg**2 + inp.u_phase_deg**2 + (360.0 * f_hz * base[2]) ** 2))
    return PhaseResult(float(wrap(out.phase_deg - inp.phase_deg)), u)


@dataclass(frozen=True)
class AngularRate:
    """Angular-rate sensitivity (output units per °/s) and its standard uncertainty, ω₀
    (°/s), and the phase of the sensitivity against ω (or None with the reason)."""

    sensitivity: float
    u_sensitivity: float
    omega_deg_s: float
    phase: PhaseResult
    budget: Budget | None = None
    """The GUM budget of S (docs/domain.md §12.1): output amplitude, θ₀, f, encoder scale."""

    @property
    def per_rad_s(self) -> float:
        """The same sensitivity per rad/s."""
        return self.sensitivity * 180.0 / np.pi


def angular_rate_sensitivity(
    gyro: Record,
    channel: str,
    encoder: Record | None,
    f_hz: float,
    *,
    encoder_channel: str = "encoder_rad",
    u_f_rel: float = 0.0,
    u_encoder_rel: float = 0.0,
    fs_hz: float | None = None,
    fs_encoder_hz: float | None = None,
) -> AngularRate:
    """The gyroscope channel's sensitivity to angular rate on the rotating table, from the
    encoder's angle (``encoder_channel`` in radians, in the gyro's record when ``encoder``
    is None): S = A/(2πf·θ₀), u_rel² = u_rel²(A) + u_rel²(θ₀) + u_f_rel² + u_encoder_rel²
    (``u_encoder_rel``: the encoder's angle scale, ``u_f_rel``: the frequency's).  The
    rates default to the records' own; pass the rate the sine fit found for a clock that
    is not trusted."""
    enc = gyro if encoder is None else encoder
    base = time_base(gyro, encoder)
    start_g, start_e = (base[0], base[1]) if base else (0.0, 0.0)
    fs_g = fs_hz if fs_hz is not None else gyro.sampling_rate()[0]
    fs_e = fs_encoder_hz if fs_encoder_hz is not None else enc.sampling_rate()[0]
    out = fit_channel(gyro.channel(channel), f_hz, fs_g, start_g)
    theta = fit_channel(enc.channel(encoder_channel), f_hz, fs_e, start_e)
    if theta.amplitude <= 0:
        raise SignalInputError(f"{enc.name}: the encoder shows no oscillation at {f_hz:g} Hz")
    omega = 2.0 * np.pi * f_hz * float(np.rad2deg(theta.amplitude))  # °/s
    s = out.amplitude / omega
    parts = (out.u_amplitude / out.amplitude, theta.u_amplitude / theta.amplitude)
    rel = np.sqrt(parts[0] ** 2 + parts[1] ** 2 + u_f_rel**2 + u_encoder_rel**2)
    if base is None:
        phase = PhaseResult(None, None, NO_TIME_BASE)
    else:
        u_ph = np.sqrt(out.u_phase_deg**2 + theta.u_phase_deg**2 + (360.0 * f_hz * base[2]) ** 2)
        phase = PhaseResult(float(wrap(out.phase_deg - theta.phase_deg - 90.0)), float(u_ph))
    budget = rate_budget(out, theta, f_hz, u_f_rel, u_encoder_rel)
    return AngularRate(float(s), float(s * rel), float(omega), phase, budget)


def rate_budget(
    out: ChannelFit, theta: ChannelFit, f_hz: float, u_f_rel: float, u_encoder_rel: float
) -> Budget:
    """S = A/(2πf·θ₀) as a GUM budget (JCGM 100:2008 §5.1; ν_eff by G.4): each input has
    ∂ln ω₀/∂q = 1/q, so u_rel² = u_rel²(A) + u_rel²(θ₀) + u_rel²(f) + u_rel²(encoder)."""
    omega = 2.0 * np.pi * f_hz * float(np.rad2deg(theta.amplitude))
    t0 = theta.amplitude
    inputs = [
        Input("encoder amplitude θ₀ (rad, fit residuals)", t0, theta.u_amplitude, 1.0 / t0,
              theta.dof, "A"),
        Input("excitation frequency f (Hz, encoder fit)", f_hz, u_f_rel * f_hz, 1.0 / f_hz,
              theta.dof, "A"),
        Input("encoder angle scale", t0, u_encoder_rel * t0, 1.0 / t0),
    ]  # fmt: skip
    return sensitivity_budget(out.amplitude, out.u_amplitude, out.dof, omega, inputs)
