"""IEEE 1057 sine fits and the study's scan against signals of known truth."""

import numpy as np
import pytest

from analysis.core.signals import paper
from analysis.core.signals.records import SignalInputError
from analysis.core.signals.sinefit import (
    cos_sin,
    estimate_rate,
    fft_seed,
    fit_free_frequency,
    fit_known_frequency,
)

N = 66_548  # 40 s at 1663.7 Hz
NU = 10.0 / 1663.7


def sine(a=1000.0, phase=0.4, offset=50.0, nu=NU, n=N):
    m = np.arange(n) - (n - 1) / 2
    return a * np.cos(2 * np.pi * nu * m + phase) + offset


def test_block_angle_addition_equals_cos_and_sin():
    c, s = cos_sin(np.array([NU, 0.3]), 1000)
    m = np.arange(1000) - 499.5
    np.testing.assert_allclose(c[1], np.cos(2 * np.pi * 0.3 * m), atol=1e-12)
    np.testing.assert_allclose(s[0], np.sin(2 * np.pi * NU * m), atol=1e-12)


def test_three_parameter_fit_is_exact_on_a_clean_sine():
    fit = fit_known_frequency(np.stack([sine(), sine(3.0, -1.0, -7.0)]), NU)
    np.testing.assert_allclose(fit.amplitude[:, 0], [1000.0, 3.0], rtol=1e-12)
    np.testing.assert_allclose(fit.phase[:, 0], [0.4, -1.0], atol=1e-12)
    np.testing.assert_allclose(fit.offset, [50.0, -7.0], rtol=1e-12)


def test_residual_uncertainty_matches_white_noise_theory():
    """u(A) = σ·√(2/N) and u(offset) = σ/√N for a sine in white noise (IEEE 1057 §8.5)."""
    rng = np.random.default_rng(7)
    sigma = 20.0
    fit = fit_known_frequency(sine() + rng.normal(0, sigma, N), NU)
    assert fit.u_amplitude[0, 0] == pytest.approx(sigma * np.sqrt(2 / N), rel=0.02)
    assert fit.u_offset[0] == pytest.approx(sigma / np.sqrt(N), rel=0.02)
    assert fit.u_phase[0, 0] == pytest.approx(sigma * np.sqrt(2 / N) / 1000.0, rel=0.02)
    assert abs(fit.amplitude[0, 0] - 1000.0) < 4 * fit.u_amplitude[0, 0]


def test_four_parameter_fit_recovers_frequency_from_the_fft_seed():
    rng = np.random.default_rng(3)
    y = np.stack([sine(), sine(500.0, 2.0)]) + rng.normal(0, 5.0, (2, N))
    seed, peak = fft_seed(y, 10 / 1830, 10 / 1490)
    assert np.all(np.abs(seed - NU) * N < 0.05)  # within 1/20 of an FFT bin
    assert peak[0] == pytest.approx(1000.0, rel=0.02)
    fit = fit_free_frequency(y, seed)
    assert np.all(np.abs(fit.nu - NU) < 4 * fit.u_nu)
    # CRB for frequency: u(ν) ≈ σ·√(24/N³)/(2π A) (IEEE 1057 Annex)
    assert fit.u_nu[0] == pytest.approx(5.0 * np.sqrt(24 / N**3) / (2 * np.pi * 1000), rel=0.05)


def test_rate_estimate_within_001_hz_on_a_clean_record():
    rate = estimate_rate(sine()[None, :], 10.0, 1660.0)
    assert rate.fs_hz == pytest.approx(1663.7, abs=0.01)
    assert abs(rate.fs_hz - 1663.7) < 1e-6


def test_scan_finds_the_nearest_hertz_and_only_that():
    fs, rates, amp = paper.scan_rate(sine(n=66_548), 10.0)
    assert fs == 1664.0 and rates[0] == 1560 and rates[-1] == 1760 and amp.size == 201
    assert paper.dft_amplitude(sine(), 10.0, 1663.7)[0, 0] == pytest.approx(1000.0, rel=1e-4)


def test_zero_crossing_trim_keeps_whole_periods_and_the_lowpass_passes_10_hz():
    fs, f = 1663.7, 10.0
    x = np.cos(2 * np.pi * f * np.arange(20_000) / fs + 1.0) + 3.0
    sl = paper.whole_periods(x)
    periods = (sl.stop - sl.start) * f / fs
    assert abs(periods - round(periods)) < fs / f / 1e3 + 1 / (fs / f)  # within one sample
    assert round(periods) == 119
    low = paper.lowpass(x - 3.0, fs)[0, 2000:]
    assert np.ptp(low) / 2 == pytest.approx(1.0, rel=1e-4)  # 6-pole at 40 Hz: |H(10 Hz)| ≈ 1
    with pytest.raises(SignalInputError, match="fewer than two whole periods"):
        paper.whole_periods(x[:200])
