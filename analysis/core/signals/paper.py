"""The study's processing ("paper mode"), kept to reproduce Chiominto et al. 2024
(docs/domain.md §8).

* Sampling rate: scan of candidate rates (1560–1760 Hz in 1 Hz steps) for the largest
  FFT amplitude at f.  The amplitude at f for a candidate rate fs_c is the one-bin DFT
  evaluated exactly at f on that rate's frequency axis, 2/N·|Σ y[n] e^{−2πi f n / fs_c}|
  (the FFT bin at f when the record holds whole periods).  Resolution: the step.
* Linear bench (§8.1): first-order Butterworth band-pass centred (geometrically) on f
  with 10 % fractional bandwidth, designed at the estimated rate, causal filtering,
  start-up transient discarded, amplitude = √2 · RMS.
* Curvilinear bench (§8.2): 6-pole Butterworth low-pass at 40 Hz, the record trimmed
  between the first and last upward zero crossings (an integer number of periods), then
  the DFT amplitude at f and 2f with the scanned rate.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike
from scipy import signal

from analysis.core.groups import FloatArray
from analysis.core.signals.records import SignalInputError

SCAN_RANGE_HZ = (1560.0, 1760.0, 1.0)
FRACTIONAL_BANDWIDTH = 0.10
SETTLE_TIME_CONSTANTS = 10.0
LOWPASS_HZ, LOWPASS_ORDER = 40.0, 6
_CHUNK = 16


def dft_amplitude(y: ArrayLike, frequency_hz: float, fs_hz: ArrayLike) -> FloatArray:
    """2/N·|Σ (y − ȳ) e^{−2πi f n / fs}| for each row of ``y`` (C, N) and each rate in
    ``fs_hz`` (K,): returns (K, C).  Candidates are processed in chunks of 16; the
    phasors come from the angle-addition rule on blocks (two small exponentials)."""
    y2 = np.atleast_2d(np.asarray(y, dtype=np.float64))
    y2 = y2 - y2.mean(axis=1, keepdims=True)
    rates = np.atleast_1d(np.asarray(fs_hz, dtype=np.float64))
    n = y2.shape[1]
    out = np.empty((rates.size, y2.shape[0]))
    for i in range(0, rates.size, _CHUNK):
        kernel = _phasors(frequency_hz / rates[i : i + _CHUNK], n)
        out[i : i + _CHUNK] = np.abs(kernel @ y2.T) * 2.0 / n
    return out


def _phasors(nu: FloatArray, n: int, block: int = 256) -> np.ndarray:
    """exp(−2πi ν_k n) for n = 0 … N−1, (K, N)."""
    starts = np.arange(-(-n // block)) * block
    outer = np.exp(-2j * np.pi * nu[:, None, None] * starts[None, :, None])
    inner = np.exp(-2j * np.pi * nu[:, None, None] * np.arange(block)[None, None, :])
    return (outer * inner).reshape(nu.size, -1)[:, :n]


def scan_rate(
    y: ArrayLike, frequency_hz: float, scan: tuple[float, float, float] = SCAN_RANGE_HZ
) -> tuple[float, FloatArray, FloatArray]:
    """The study's rate estimate: the candidate with the largest DFT amplitude at f in
    the sum over rows.  Returns (rate, candidates, amplitude per candidate)."""
    lo, hi, step = scan
    rates = np.arange(lo, hi + step / 2, step)
    amp = dft_amplitude(y, frequency_hz, rates).sum(axis=1)
    return float(rates[int(np.argmax(amp))]), rates, amp


def bandpass(
    frequency_hz: float, fs_hz: float, fraction: float = FRACTIONAL_BANDWIDTH
) -> FloatArray:
    """First-order Butterworth band-pass, edges f1·f2 = f², f2 − f1 = fraction·f (SOS)."""
    half = fraction / 2.0
    f1 = frequency_hz * (np.sqrt(1.0 + half**2) - half)
    sos = signal.butter(
        1, [f1, f1 + fraction * frequency_hz], btype="bandpass", fs=fs_hz, output="sos"
    )
    return np.asarray(sos, dtype=np.float64)


def bandpassed(
    y: ArrayLike,
    frequency_hz: float,
    fs_design_hz: float,
    fs_actual_hz: float | None = None,
    fraction: float = FRACTIONAL_BANDWIDTH,
) -> FloatArray:
    """Each row after the band-pass designed at ``fs_design_hz``, the first
    SETTLE_TIME_CONSTANTS·τ (τ = 1/(π·fraction·f)) discarded (the start-up transient
    of the gravity offset step).  ``fs_actual_hz`` only sets how many samples that is."""
    y2 = np.atleast_2d(np.asarray(y, dtype=np.float64))
    out = signal.sosfilt(bandpass(frequency_hz, fs_design_hz, fraction), y2, axis=1)
    tau = 1.0 / (np.pi * fraction * frequency_hz)
    skip = int(np.ceil(SETTLE_TIME_CONSTANTS * tau * (fs_actual_hz or fs_design_hz)))
    if skip >= y2.shape[1] // 2:
        raise SignalInputError(
            f"the record ({y2.shape[1]} samples) is too short for the band-pass at "
            f"{frequency_hz:g} Hz to settle ({skip} samples)"
        )
    return np.asarray(out[:, skip:], dtype=np.float64)


def bandpass_rms_amplitude(
    y: ArrayLike,
    frequency_hz: float,
    fs_design_hz: float,
    fs_actual_hz: float | None = None,
    fraction: float = FRACTIONAL_BANDWIDTH,
) -> FloatArray:
    """The study's amplitude: √2 · RMS of :func:`bandpassed`, per row."""
    out = bandpassed(y, frequency_hz, fs_design_hz, fs_actual_hz, fraction)
    return np.asarray(np.sqrt(2.0 * np.mean(out**2, axis=1)), dtype=np.float64)


def lowpass(y: ArrayLike, fs_hz: float) -> FloatArray:
    """The study's 6-pole Butterworth low-pass at 40 Hz, causal, per row."""
    sos = signal.butter(LOWPASS_ORDER, LOWPASS_HZ, fs=fs_hz, output="sos")
    return np.asarray(signal.sosfilt(sos, np.atleast_2d(y), axis=1), dtype=np.float64)


def whole_periods(x: ArrayLike, settle: int = 0) -> slice:
    """Samples between the first and the last upward zero crossing of x − mean(x)
    after ``settle`` samples: an integer number of periods of its dominant component."""
    v = np.asarray(x, dtype=np.float64)[settle:]
    v = v - v.mean()
    up = np.flatnonzero((v[:-1] < 0) & (v[1:] >= 0)) + 1 + settle
    if up.size < 3:
        raise SignalInputError("fewer than two whole periods between zero crossings")
    return slice(int(up[0]), int(up[-1]))
