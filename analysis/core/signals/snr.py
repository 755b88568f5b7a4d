"""Signal-to-noise ratio equivalent to MATLAB ``snr(x, fs, n)`` (Signal Processing Toolbox).

The procedure (docs/domain.md §8.3): remove the mean; Kaiser window β = 38; one-sided
periodogram (PSD, nfft = N); resolution bandwidth rbw = ENBW of the window.  The DC
lobe is removed, the fundamental is the largest remaining peak and its power the
integral of its main lobe (rolled down to the first local minima on both sides, at
least rbw × peak density); harmonics 2..n are located near h·f1 and removed the same
way; the removed bins are filled with the median of the remaining PSD bins (never
above the original density) and the noise power is the integral of that PSD.
SNR = 10·log10(P_fundamental / P_noise).  Integrals are MATLAB's ``bandpower``
rectangles, width ΔF per bin except the last bin of a range.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike
from scipy import signal

from analysis.core.groups import FloatArray
from analysis.core.signals.records import SignalInputError

KAISER_BETA = 38.0


def snr_db(x: ArrayLike, fs_hz: float, n_harmonics: int = 6) -> FloatArray:
    """SNR in dB of each row of ``x`` (C, N) or of a 1-D signal (then 0-d)."""
    arr = np.asarray(x, dtype=np.float64)
    rows = np.atleast_2d(arr)
    if rows.shape[1] < 64:
        raise SignalInputError(f"snr needs at least 64 samples, got {rows.shape[1]}")
    n = rows.shape[1]
    w = signal.windows.kaiser(n, KAISER_BETA, sym=True)
    rbw = fs_hz * float(np.sum(w**2) / np.sum(w) ** 2)
    freq, psd = signal.periodogram(
        rows - rows.mean(axis=1, keepdims=True),
        fs_hz,
        window=w,
        nfft=n,
        detrend=False,
        scaling="density",
        axis=1,
    )
    out = np.array([_snr_row(p, freq, rbw, n_harmonics) for p in psd])
    return out if arr.ndim > 1 else out[0]


def _snr_row(psd: FloatArray, freq: FloatArray, rbw: float, n_harmonics: int) -> float:
    orig, p = psd, psd.copy()
    _, _, left, right = _tone(p, freq, rbw, 0.0)
    p[left : right + 1] = 0.0
    p_fund, f_fund, left, right = _tone(p, freq, rbw, None)
    p[left : right + 1] = 0.0
    for h in range(2, n_harmonics + 1):
        if h * f_fund <= freq[-1]:
            _, _, left, right = _tone(p, freq, rbw, h * f_fund)
            p[left : right + 1] = 0.0
    if not (p > 0).any():
        raise SignalInputError("snr: no noise bins are left after removing the tones")
    p[p == 0] = np.median(p[p > 0])
    noise = _bandpower(np.minimum(p, orig), freq)
    return float(10.0 * np.log10(p_fund / noise))


def _bandpower(p: FloatArray, freq: FloatArray) -> float:
    width = np.append(np.diff(freq), 0.0)
    return float(np.dot(width, p))


def _tone(
    p: FloatArray, freq: FloatArray, rbw: float, f: float | None
) -> tuple[float, float, int, int]:
    """(power, centroid frequency, first bin, last bin) of the lobe of a tone: the
    largest peak (``f`` None) or the local maximum within ±1 bin of ``f``."""
    if f is None:
        idx = int(np.argmax(p))
    else:
        near = int(np.argmin(np.abs(freq - f)))
        lo = max(near - 1, 0)
        idx = lo + int(np.argmax(p[lo : near + 2]))
    falls_left = np.flatnonzero(p[:idx] > p[1 : idx + 1])  # i with p[i] > p[i+1], i < idx
    left = int(falls_left[-1]) + 1 if falls_left.size else 0
    rises_right = np.flatnonzero(p[idx:-1] < p[idx + 1 :])  # j-1 with p[j-1] < p[j], j > idx
    right = idx + int(rises_right[0]) if rises_right.size else p.size - 1
    band, fb = p[left : right + 1], freq[left : right + 1]
    centroid = float(np.dot(fb, band) / band.sum()) if band.sum() > 0 else float(freq[idx])
    if left < right:
        power = _bandpower(band, fb)
    elif 0 < right < p.size - 1:
        power = float(p[right] * (freq[right + 1] - freq[right - 1]) / 2)
    else:
        power = float(p[right] * np.mean(np.diff(freq)))
    if power < rbw * p[idx]:
        power, centroid = float(rbw * p[idx]), float(freq[idx])
    return power, centroid, left, right
