"""Amplitudes at f (and its harmonics) of the channels of one record, by method.

``sine-fit`` (default): ν from four-parameter fits (IEEE 1057 §8.6), giving the actual
rate fs = f / ν (or, with a trusted clock, the actual excitation frequency f = ν·fs);
amplitudes from three-parameter fits (§8.5) of equal segments, each with its own phase
(:func:`segmented_amplitudes`), so that dropped samples are seen and left out.
``paper``: the study's scan and filters (:mod:`analysis.core.signals.paper`).
Both return the same :class:`Measured`, with ∂ln A/∂fs for the budget: exactly 0 for
the sine fit (ν is fitted, the time scale never enters the amplitude), a finite
difference over ±½ scan step for paper mode.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np

from analysis.core.groups import FloatArray
from analysis.core.signals import paper
from analysis.core.signals.sinefit import estimate_rate, fit_known_frequency

Method = Literal["sine-fit", "paper"]
Bench = Literal["linear", "curvilinear"]
N_SEGMENTS = 10
MAX_SEGMENTS = 16
SEGMENT_OUTLIER = 3.0
FIT_HARMONICS = (1, 2, 3)
"""The sine fit always models the first three harmonics: distortion then cannot leak
into the amplitude at f over a non-integer number of periods."""
LOWPASS_SETTLE_S = 0.25


@dataclass(frozen=True)
class Measured:
    """Amplitudes (C, H) at the harmonics of ``frequency_hz`` and the rate used."""

    fs_hz: float
    u_fs_hz: float
    frequency_hz: float
    u_frequency_hz: float
    harmonics: tuple[int, ...]
    amplitude: FloatArray
    u_amplitude: FloatArray
    dof: float
    dln_dfs: FloatArray
    n_segments: int = 1
    left_out: tuple[int, ...] = ()
    """Per row: segments left out of the sine-fit mean (dropped samples, disturbances)."""

    def left_out_note(self, row: int) -> str:
        if not self.left_out or not self.left_out[row]:
            return ""
        return (
            f"{self.left_out[row]} of {self.n_segments} segments left out: residual above "
            f"{SEGMENT_OUTLIER:g}× the others' (dropped samples or a disturbance?)"
        )


def measure(
    y: FloatArray,
    frequency_hz: float,
    fs_hz: float,
    *,
    trusted: bool,
    method: Method,
    bench: Bench,
    harmonics: Sequence[int] = (1,),
) -> Measured:
    """Amplitudes of every row of ``y`` (C, N).  ``trusted``: ``fs_hz`` is exact, and
    the four-parameter fit measures the actual excitation frequency f = ν·fs instead of
    the rate (a generator a little off its nominal frequency would otherwise bias a fit
    at f / fs over a long record)."""
    if method == "sine-fit":
        return _sine_fit(y, frequency_hz, fs_hz, trusted, tuple(harmonics))
    if bench == "linear":
        return _paper_linear(y, frequency_hz, fs_hz, trusted)
    return _paper_curvilinear(y, frequency_hz, fs_hz, trusted, tuple(harmonics))


def _sine_fit(
    y: FloatArray, f: float, fs: float, trusted: bool, harmonics: tuple[int, ...]
) -> Measured:
    rate = estimate_rate(y, f, fs)
    seg = segmented_amplitudes(y, rate.nu, harmonics)
    nu, u_nu = rate.nu, rate.u_nu
    best = rate.rows_used[int(np.argmax(seg.amplitude[list(rate.rows_used), 0]))]
    if seg.left_out[best]:  # dropped samples bias a whole-record fit of ν
        nu, u_nu = _rate_from_segment_phases(seg, best, rate.nu)
    if trusted:  # the clock is exact: what the fit measures is the excitation frequency
        f, u_f, u_fs = nu * fs, u_nu * fs, 0.0
    else:
        fs, u_fs, u_f = f / nu, f / nu * u_nu / nu, 0.0
    zero = np.zeros_like(seg.amplitude)
    return Measured(fs, u_fs, f, u_f, harmonics, seg.amplitude, seg.u_amplitude, seg.dof, zero,
                    seg.n_segments, seg.left_out)  # fmt: skip


@dataclass(frozen=True)
class Segmented:
    amplitude: FloatArray
    u_amplitude: FloatArray
    dof: float
    n_segments: int
    segment_length: int
    left_out: tuple[int, ...]
    phase: FloatArray
    """(C, K) phase of the fundamental at each segment's middle sample."""


def _rate_from_segment_phases(seg: Segmented, row: int, nu: float) -> tuple[float, float]:
    """ν from the phase advance between consecutive segments, 2π·ν·L: the median
    advance ignores the few steps that contain a dropped sample.  u from the scaled MAD
    (1.4826) of the advances and the median's efficiency (1.2533)."""
    length = seg.segment_length
    step = np.diff(seg.phase[row]) - 2 * np.pi * nu * length
    dnu = np.angle(np.exp(1j * step)) / (2 * np.pi * length)
    med = float(np.median(dnu))
    mad = 1.4826 * float(np.median(np.abs(dnu - med)))
    return nu + med, 1.2533 * mad / np.sqrt(dnu.size)


def segmented_amplitudes(y: FloatArray, nu: float, harmonics: tuple[int, ...]) -> Segmented:
    """Amplitudes (C, H) from three-parameter fits (with FIT_HARMONICS) of K equal
    segments, each with its own phase, K = min(16, periods/10).  A dropped sample
    shifts the phase inside one segment, which shows as a residual far above the other
    segments' (> SEGMENT_OUTLIER × their median): such segments are left out and the
    others averaged.  u: the residual-based u of the mean, or the scatter of the
    segment values when that is larger (non-stationary record), with ν = K' − 1 then."""
    n_ch, n = y.shape
    k = int(max(1, min(MAX_SEGMENTS, np.floor(n * nu / 10.0))))
    n_seg = n // k
    fit_h = tuple(sorted(set(harmonics) | set(FIT_HARMONICS)))
    fit = fit_known_frequency(y[:, : k * n_seg].reshape(n_ch * k, n_seg), nu, fit_h)
    cols = [fit_h.index(h) for h in harmonics]
    amp = fit.amplitude[:, cols].reshape(n_ch, k, -1)
    u_seg = fit.u_amplitude[:, cols].reshape(n_ch, k, -1)
    rr = fit.residual_rms.reshape(n_ch, k)
    keep = (rr <= SEGMENT_OUTLIER * np.median(rr, axis=1, keepdims=True))[:, :, None]
    used = keep.sum(axis=1)  # (C, 1)
    mean = np.sum(amp * keep, axis=1) / used
    u = np.sqrt(np.sum(u_seg**2 * keep, axis=1)) / used
    dof = float(int(used.min()) * fit.dof)
    if k > 1:
        dev2 = np.sum((amp - mean[:, None, :]) ** 2 * keep, axis=1)
        u_scatter = np.sqrt(dev2 / np.maximum(used - 1, 1) / used)
        if np.any(u_scatter > u):
            u, dof = np.maximum(u, u_scatter), float(max(int(used.min()) - 1, 1))
    left_out = tuple(int(v) for v in k - used[:, 0])
    phase = fit.phase[:, fit_h.index(1)].reshape(n_ch, k)
    return Segmented(mean, u, dof, k, n_seg, left_out, phase)


def _strongest(y: FloatArray) -> int:
    return int(np.argmax(np.std(y, axis=1)))


def _scan_range(fs: float) -> tuple[float, float, float]:
    lo, hi, _ = paper.SCAN_RANGE_HZ
    return paper.SCAN_RANGE_HZ if lo <= fs <= hi else (round(0.94 * fs), round(1.06 * fs), 1.0)


def _paper_linear(y: FloatArray, f: float, fs: float, trusted: bool) -> Measured:
    step = 0.0 if trusted else _scan_range(fs)[2]
    if not trusted:
        fs = paper.scan_rate(y[_strongest(y)], f, _scan_range(fs))[0]
    out = paper.bandpassed(y, f, fs)
    amp = np.sqrt(2.0 * np.mean(out**2, axis=1))
    n = out.shape[1] // N_SEGMENTS
    seg = out[:, : n * N_SEGMENTS].reshape(out.shape[0], N_SEGMENTS, n)
    per_seg = np.sqrt(2.0 * np.mean(seg**2, axis=2))  # (C, segments)
    u_amp = per_seg.std(axis=1, ddof=1) / np.sqrt(N_SEGMENTS)
    dln = _dln_dfs(lambda r: paper.bandpass_rms_amplitude(y, f, r, fs), fs, amp, step)
    return Measured(
        fs,
        step / np.sqrt(12.0),
        f,
        0.0,
        (1,),
        amp[:, None],
        u_amp[:, None],
        N_SEGMENTS - 1,
        dln[:, None],
    )


def _paper_curvilinear(
    y: FloatArray, f: float, fs: float, trusted: bool, harmonics: tuple[int, ...]
) -> Measured:
    low = paper.lowpass(y, fs)
    ref = _strongest(low)
    trimmed = low[:, paper.whole_periods(low[ref], int(LOWPASS_SETTLE_S * fs))]
    step = 0.0 if trusted else _scan_range(fs)[2]
    if not trusted:
        fs = paper.scan_rate(trimmed[ref], f, _scan_range(fs))[0]
    h = np.asarray(harmonics, dtype=np.float64)

    def amplitudes(x: FloatArray, rate: float) -> FloatArray:
        return np.stack([paper.dft_amplitude(x, hk * f, rate)[0] for hk in h], axis=1)

    amp = amplitudes(trimmed, fs)
    n = trimmed.shape[1] // N_SEGMENTS
    per_seg = np.stack([amplitudes(trimmed[:, i * n : (i + 1) * n], fs) for i in range(N_SEGMENTS)])
    u_amp = per_seg.std(axis=0, ddof=1) / np.sqrt(N_SEGMENTS)
    dln = _dln_dfs(lambda r: amplitudes(trimmed, r), fs, amp, step)
    return Measured(fs, step / np.sqrt(12.0), f, 0.0, harmonics, amp, u_amp, N_SEGMENTS - 1, dln)


def _dln_dfs(amp_at: object, fs: float, amp: FloatArray, step: float) -> FloatArray:
    """∂ln A/∂fs by a central difference over ±½ step (0 when the rate is trusted)."""
    if step == 0.0 or not callable(amp_at):
        return np.zeros_like(amp)
    hi, lo = amp_at(fs + step / 2), amp_at(fs - step / 2)
    return np.asarray((hi - lo) / (step * np.where(amp > 0, amp, 1.0)), dtype=np.float64)
