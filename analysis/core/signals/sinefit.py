"""Least-squares sine fits (IEEE Std 1057-2017 §8.5–8.6, ISO 16063-11 method 3).

Samples y[c, n] of C channels are fitted with

    y = Σ_h [a_h cos(2π h ν m) + b_h sin(2π h ν m)] + c,   m = n − (N − 1)/2,

where ν is the normalised frequency in cycles per sample and h runs over the
requested harmonics (1 alone is the classic fit).  The time origin is the middle
sample, where phase and frequency estimates are uncorrelated; phases are given
there.  Three-parameter fit: ν known, linear least squares.  Four-parameter fit:
ν estimated too, by the Gauss–Newton iteration of IEEE 1057 seeded with a
Hann-windowed, zero-padded FFT peak refined by Gaussian (log-parabolic)
interpolation.  Uncertainties come from the residuals, σ² = RSS / (N − P),
cov = σ² (DᵀD)⁻¹: they assume white residual noise (no drift, no correlated
background vibration) and are a lower bound otherwise.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike
from scipy import fft as sfft

from analysis.core.groups import FloatArray
from analysis.core.signals.records import SignalInputError

TWO_PI = 2.0 * np.pi
MAX_ITER = 12
TOL_CYCLES = 1e-7
"""Stop when ν changes by less than this many cycles over the whole record."""


@dataclass(frozen=True)
class SineFit:
    """Fit of C channels; ``amplitude``/``phase`` are (C, H) for harmonics ``harmonics``."""

    harmonics: tuple[int, ...]
    amplitude: FloatArray
    phase: FloatArray
    offset: FloatArray
    nu: FloatArray
    u_amplitude: FloatArray
    u_phase: FloatArray
    u_offset: FloatArray
    u_nu: FloatArray
    residual_rms: FloatArray
    n_samples: int
    n_params: int

    @property
    def dof(self) -> int:
        return self.n_samples - self.n_params


def centred_index(n: int) -> FloatArray:
    return np.arange(n, dtype=np.float64) - (n - 1) / 2.0


def fft_seed(
    y: FloatArray, nu_lo: float, nu_hi: float, pad: int = 4
) -> tuple[FloatArray, FloatArray]:
    """Normalised frequency and amplitude of the largest spectral peak in [nu_lo, nu_hi]
    of each row: Hann window, zero padding to ``pad``·N, Gaussian (log-parabolic)
    interpolation of the peak.  Rows are first averaged over blocks of L samples with
    ν_hi·L ≤ 1/4 (at most 16): the band of interest stays far below the new Nyquist
    frequency, the resolution (record length) is unchanged, the FFT is L times shorter."""
    y2 = np.atleast_2d(y)
    dec = block_length(nu_hi)
    n_dec = y2.shape[1] // dec
    yd = y2[:, : n_dec * dec].reshape(y2.shape[0], n_dec, dec).mean(axis=2)
    w = np.hanning(n_dec)
    nfft = sfft.next_fast_len(pad * n_dec, real=True)
    mag = np.abs(sfft.rfft((yd - yd.mean(axis=1, keepdims=True)) * w, n=nfft, axis=1))
    lo = max(int(np.floor(nu_lo * dec * nfft)), 1)
    hi = min(int(np.ceil(nu_hi * dec * nfft)) + 1, mag.shape[1] - 1)
    if hi - lo < 1:
        raise SignalInputError(f"frequency band [{nu_lo:g}, {nu_hi:g}] cycles/sample is empty")
    k = lo + np.argmax(mag[:, lo:hi], axis=1)
    rows = np.arange(mag.shape[0])
    lm, l0, lp = (np.log(mag[rows, k + d] + 1e-300) for d in (-1, 0, 1))
    denom = lm - 2 * l0 + lp
    delta = np.where(denom < 0, 0.5 * (lm - lp) / np.where(denom < 0, denom, -1.0), 0.0)
    return (k + delta) / (nfft * dec), 2.0 * mag[rows, k] / float(w.sum())


BLOCK = 256


def cos_sin(
    nu: FloatArray, n: int, out: tuple[FloatArray, FloatArray] | None = None
) -> tuple[FloatArray, FloatArray]:
    """cos and sin of 2π·ν_c·m for m = centred_index(n), one row per ν_c, by the
    angle-addition rule on blocks of ``BLOCK`` samples: two products per sample
    instead of a cosine and a sine (same accuracy, several times faster).  ``out``:
    two (C, n) arrays to write into."""
    nu = np.atleast_1d(nu)
    n_blocks = -(-n // BLOCK)
    start = -(n - 1) / 2.0 + BLOCK * np.arange(n_blocks)
    p_in = TWO_PI * nu[:, None, None] * np.arange(BLOCK)[None, None, :]
    p_out = TWO_PI * nu[:, None, None] * start[None, :, None]
    ci, si, co, so = np.cos(p_in), np.sin(p_in), np.cos(p_out), np.sin(p_out)
    c, s = out if out is not None else (np.empty((nu.size, n)), np.empty((nu.size, n)))
    c[...] = (co * ci - so * si).reshape(nu.size, -1)[:, :n]
    s[...] = (so * ci + co * si).reshape(nu.size, -1)[:, :n]
    return c, s


def _design(
    nu: FloatArray, n: int, harmonics: Sequence[int], coef: FloatArray | None = None
) -> FloatArray:
    """Design (C, P, N): cos and sin of every harmonic, the offset, and with ``coef``
    the IEEE 1057 four-parameter column, the derivative of the current model with
    respect to ν·N (scaled by 1/N to stay O(1))."""
    n_h = len(harmonics)
    d = np.empty((nu.size, 2 * n_h + 1 + (coef is not None), n))
    for j, h in enumerate(harmonics):
        cos_sin(h * nu, n, (d[:, 2 * j], d[:, 2 * j + 1]))
    d[:, 2 * n_h] = 1.0
    if coef is not None:
        deriv = d[:, -1]
        deriv[...] = 0.0
        for j, h in enumerate(harmonics):
            a, b = coef[:, 2 * j, None], coef[:, 2 * j + 1, None]
            deriv += h * (b * d[:, 2 * j] - a * d[:, 2 * j + 1])
        deriv *= TWO_PI * (centred_index(n) / n)[None, :]
    return d


def _normal(d: FloatArray, y2: FloatArray) -> tuple[FloatArray, FloatArray]:
    """DᵀD (C, P, P) and Dᵀy (C, P) for designs laid out (C, P, N); one BLAS call per
    channel (numpy's stacked matmul does not use BLAS for these strides)."""
    g = np.stack([dc @ dc.T for dc in d])
    return g, np.stack([dc @ yc for dc, yc in zip(d, y2, strict=True)])


def fit_known_frequency(y: ArrayLike, nu: float, harmonics: Sequence[int] = (1,)) -> SineFit:
    """Three-parameter fit (IEEE 1057 §8.5) at a known ν shared by all rows, extended
    to several harmonics; one linear solve for every channel."""
    y2 = np.atleast_2d(np.asarray(y, dtype=np.float64))
    n = y2.shape[1]
    d = _design(np.array([nu]), n, harmonics)[0]
    g = d @ d.T
    coef = np.linalg.solve(g, d @ y2.T).T  # (C, P)
    resid = y2 - coef @ d
    cov = _scaled_cov(resid, np.linalg.inv(g)[None, :, :], d.shape[0])
    u_nu = np.zeros(y2.shape[0])
    return _result(harmonics, coef, cov, np.full(y2.shape[0], nu), u_nu, resid, d.shape[0])


def fit_free_frequency(
    y: ArrayLike, nu0: ArrayLike, harmonics: Sequence[int] = (1,), max_iter: int = MAX_ITER
) -> SineFit:
    """Four-parameter fit (IEEE 1057 §8.6): each row gets its own ν, refined from
    ``nu0`` by Gauss–Newton on [a_h, b_h, c, Δν]; all rows iterate together."""
    y2 = np.atleast_2d(np.asarray(y, dtype=np.float64))
    n_ch, n = y2.shape
    nu = np.broadcast_to(np.asarray(nu0, dtype=np.float64), (n_ch,)).copy()
    coef = _solve(*_normal(_design(nu, n, harmonics), y2))
    step = np.zeros(n_ch)
    for _ in range(max_iter):
        d = _design(nu, n, harmonics, coef)
        g, rhs = _normal(d, y2)
        sol = _solve(g, rhs)
        coef, step = sol[:, :-1], sol[:, -1] / n
        nu = nu + step
        if np.all(np.abs(step) * n < TOL_CYCLES):
            break
    else:
        bad = int(np.argmax(np.abs(step)))
        raise SignalInputError(
            f"the four-parameter sine fit did not converge (row {bad}: last step "
            f"{step[bad] * n:.3g} cycles over the record): is there a sine in the record?"
        )
    # The last step was below TOL_CYCLES: its design serves for residuals and covariance.
    resid = y2 - np.matmul(coef[:, None, :], d[:, :-1, :])[:, 0, :]
    cov = _scaled_cov(resid, np.asarray(np.linalg.inv(g), dtype=np.float64), d.shape[1])
    u_nu = np.sqrt(cov[:, -1, -1]) / n
    return _result(harmonics, coef, cov[:, :-1, :-1], nu, u_nu, resid, d.shape[1])


def _solve(g: FloatArray, rhs: FloatArray) -> FloatArray:
    """Batched solve of (C, P, P) systems with (C, P) right-hand sides."""
    return np.asarray(np.linalg.solve(g, rhs[:, :, None])[:, :, 0], dtype=np.float64)


def _scaled_cov(resid: FloatArray, ginv: FloatArray, n_params: int) -> FloatArray:
    dof = resid.shape[1] - n_params
    if dof < 1:
        raise SignalInputError(f"{resid.shape[1]} samples cannot fit {n_params} parameters")
    s2 = np.einsum("cn,cn->c", resid, resid) / dof
    return np.asarray(s2[:, None, None] * ginv, dtype=np.float64)


def _result(
    harmonics: Sequence[int],
    coef: FloatArray,
    cov: FloatArray,
    nu: FloatArray,
    u_nu: FloatArray,
    resid: FloatArray,
    n_params: int,
) -> SineFit:
    n_h = len(harmonics)
    a, b = coef[:, 0 : 2 * n_h : 2], coef[:, 1 : 2 * n_h : 2]
    ia, ib = np.arange(0, 2 * n_h, 2), np.arange(1, 2 * n_h, 2)
    va, vb, cab = cov[:, ia, ia], cov[:, ib, ib], cov[:, ia, ib]
    amp = np.hypot(a, b)
    safe = np.where(amp > 0, amp, 1.0)
    u_amp = np.sqrt(np.maximum(a * a * va + b * b * vb + 2 * a * b * cab, 0.0)) / safe
    u_ph = np.sqrt(np.maximum(b * b * va + a * a * vb - 2 * a * b * cab, 0.0)) / safe**2
    return SineFit(
        harmonics=tuple(harmonics),
        amplitude=amp,
        phase=np.arctan2(-b, a),
        offset=coef[:, -1],
        nu=nu,
        u_amplitude=u_amp,
        u_phase=u_ph,
        u_offset=np.sqrt(cov[:, -1, -1]),
        u_nu=u_nu,
        residual_rms=np.sqrt(np.mean(resid**2, axis=1)),
        n_samples=resid.shape[1],
        n_params=n_params,
    )


@dataclass(frozen=True)
class RateEstimate:
    """Actual sampling rate from the fitted normalised frequency: fs = f / ν."""

    fs_hz: float
    u_fs_hz: float
    nu: float
    u_nu: float
    rows_used: tuple[int, ...]


def estimate_rate(
    y: ArrayLike,
    frequency_hz: float,
    fs_nominal_hz: float,
    fs_bounds: tuple[float, float] | None = None,
    min_relative_peak: float = 0.5,
) -> RateEstimate:
    """fs = f / ν with ν from four-parameter fits of the rows that carry a clear
    component at f (peak ≥ ``min_relative_peak`` × the strongest row), combined by
    inverse-variance weighting (one clock for all channels of a record).  The seed
    is searched in f / fs_bounds (default nominal ± 10 %).  Fits run on block means of
    L samples (ν·L ≤ 1/4, L ≤ 16): a sine stays a sine of normalised frequency ν·L, and
    for white noise the Cramér–Rao bound on ν is the same as with every sample."""
    y2 = np.atleast_2d(np.asarray(y, dtype=np.float64))
    lo, hi = fs_bounds or (0.9 * fs_nominal_hz, 1.1 * fs_nominal_hz)
    dec = block_length(frequency_hz / lo)
    n_dec = y2.shape[1] // dec
    yd = y2[:, : n_dec * dec].reshape(y2.shape[0], n_dec, dec).mean(axis=2)
    nu_seed, peak = fft_seed(yd, dec * frequency_hz / hi, dec * frequency_hz / lo)
    rows = np.flatnonzero(peak >= min_relative_peak * peak.max())
    fit = fit_free_frequency(yd[rows], nu_seed[rows])
    nu_rows, u_rows = fit.nu / dec, fit.u_nu / dec
    if np.any((nu_rows < frequency_hz / hi) | (nu_rows > frequency_hz / lo)):
        raise SignalInputError(
            f"the fitted rate leaves {lo:g}–{hi:g} Hz: no clear sine at {frequency_hz:g} Hz?"
        )
    w = 1.0 / np.maximum(u_rows, 1e-300) ** 2
    nu = float(np.sum(w * nu_rows) / np.sum(w))
    u_nu = float(1.0 / np.sqrt(np.sum(w)))
    fs = frequency_hz / nu
    return RateEstimate(fs, fs * u_nu / nu, nu, u_nu, tuple(int(r) for r in rows))


def block_length(nu_hi: float) -> int:
    """L with ν_hi·L ≤ 1/4, 1 ≤ L ≤ 16."""
    return int(max(1, min(16, np.floor(0.25 / nu_hi))))
