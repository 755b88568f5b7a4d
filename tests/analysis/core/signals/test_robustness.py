"""RR, SR, SNR and before/after compatibility against closed forms (docs/domain.md §8.3)."""

import numpy as np
import pytest

from analysis.core.signals.records import Record, SignalInputError
from analysis.core.signals.robustness import repetition, summary, zone_slices
from analysis.core.signals.snr import snr_db

FS = 119.0


def tone(n, f=5.0, a=1.0, phase=0.0):
    return a * np.cos(2 * np.pi * f * np.arange(n) / FS + phase)


def zones(
    leak_db: float = -26.0, n: int = 21_420, seed: int = 0, sr_gain: float = 1.0
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Excited X; Y carries the same sine attenuated by leak_db; Z only its noise floor."""
    rng = np.random.default_rng(seed)
    floor = rng.normal(0, 1e-3, (3, 3 * n))
    before, test, after = np.split(floor, 3, axis=1)
    leak = 10 ** (leak_db / 20)
    test = test * sr_gain
    test[0] += tone(n, a=9.8)
    test[1] = leak * test[0]
    return before, test, after


def test_rr_of_a_minus_26_db_cross_axis_leak_is_26_db():
    rep = repetition(*zones(), axes="xyz", excited="X", fs_hz=FS)
    assert rep.rr_db[1] == pytest.approx(26.0, abs=0.1)
    assert rep.rr_db[1] == pytest.approx(26.0, abs=1e-9)  # exact: Y is X scaled
    assert np.isnan(rep.rr_db[0]) and np.isnan(rep.sr_db[0])


def test_sr_is_the_rms_ratio_of_test_to_before_in_db():
    before, test, after = zones(sr_gain=2.0)
    rep = repetition(before, test, after, axes="xyz", excited="x", fs_hz=FS)
    expected = 20 * np.log10(test[2].std() / before[2].std())
    assert rep.sr_db[2] == pytest.approx(expected, rel=1e-12)
    assert rep.sr_db[2] == pytest.approx(20 * np.log10(2.0), abs=0.1)


@pytest.mark.parametrize(("sigma", "seed"), [(0.01, 1), (0.1, 2), (0.3, 3)])
def test_snr_within_01_db_of_theory_for_sine_plus_white_noise(sigma, seed):
    n = 2**20
    x = tone(n, a=1.0, phase=0.3) + np.random.default_rng(seed).normal(0, sigma, n)
    theory = 10 * np.log10(0.5 / sigma**2)
    assert snr_db(x, FS) == pytest.approx(theory, abs=0.1)


def test_snr_ignores_harmonics_2_to_6_and_the_offset():
    n = 2**18
    rng = np.random.default_rng(4)
    clean = tone(n) + 0.05 * tone(n, 10.0) + 0.02 * tone(n, 25.0) + 3.0
    noisy = clean + rng.normal(0, 0.05, n)
    assert snr_db(noisy, FS) == pytest.approx(10 * np.log10(0.5 / 0.05**2), abs=0.1)
    assert snr_db(np.stack([noisy, noisy]), FS).shape == (2,)


def test_before_after_compatibility():
    before, test, after = zones()
    rep = repetition(before, test, after, axes="xyz", excited="x", fs_hz=FS)
    assert np.all(rep.en_mean < 1) and np.all(rep.sd_compatible)
    shifted = after.copy()
    shifted[1] += 3 * 2 * np.sqrt(2) * 1e-3  # 3 × the k = 2 combined spread
    rep = repetition(before, test, shifted, axes="xyz", excited="x", fs_hz=FS)
    assert rep.en_mean[1] == pytest.approx(3.0, rel=0.02)
    assert rep.to_dict()["before_after"]["Y"]["mean_compatible"] is False
    noisier = after * 1.2
    rep = repetition(before, test, noisier, axes="xyz", excited="x", fs_hz=FS)
    assert not rep.sd_compatible.any() and rep.f_ratio == pytest.approx(1.44, rel=0.05)


def test_summary_is_mean_and_sample_sd_over_repetitions():
    reps = [
        repetition(*zones(leak_db=-d, seed=i), axes="xyz", excited="x", fs_hz=FS)
        for i, d in enumerate((24.0, 26.0, 28.0))
    ]
    table = summary(reps)
    assert table["rr_db"]["Y"]["mean"] == pytest.approx(26.0, abs=1e-9)
    assert table["rr_db"]["Y"]["sd"] == pytest.approx(2.0, abs=1e-9)
    assert table["rr_db"]["X"] == {"mean": None, "sd": None, "n": 0}
    assert table["snr_db"]["X"]["n"] == 3


def test_zones_from_seconds_and_errors():
    rec = Record("r", ("x",), np.zeros((1, 1190)), {"fs_hz": FS})
    sl = zone_slices(rec, {"before": (0.0, 3.0), "test": (3.0, 7.0)}, FS)
    assert sl["before"] == slice(0, 357) and sl["test"] == slice(357, 833)
    with pytest.raises(SignalInputError, match="zone 'after' \\[20, 30\\] s holds 0 samples"):
        zone_slices(rec, {"after": (20.0, 30.0)}, FS)
    with pytest.raises(SignalInputError, match="excited axis 'w'"):
        repetition(*zones(n=200), axes="xyz", excited="w", fs_hz=FS)


def test_a_constant_zone_is_an_error_not_a_nan():
    before, test, after = zones(n=500)
    before[2] = 0.0
    with pytest.raises(SignalInputError, match="zone before, axis z: constant signal"):
        repetition(before, test, after, axes="xyz", excited="x", fs_hz=FS)
