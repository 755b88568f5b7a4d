"""Linear and curvilinear benches on synthetic records of known truth (docs/domain.md §8.1–8.2)."""

import numpy as np
import pytest
from scipy import signal, stats

from analysis.core.signals import paper
from analysis.core.signals.curvilinear import encoder_reference
from analysis.core.signals.linear import expected_components
from analysis.core.signals.measure import Method
from analysis.core.signals.records import Record, SignalInputError
from analysis.core.signals.sensitivity import record_sensitivity
from analysis.core.signals.synthetic import Imperfections, curvilinear_records, linear_record

FIT_AND_PAPER: tuple[Method, Method] = ("sine-fit", "paper")

TRUTH = (420.0, 418.0, 425.0)
CASES = {
    "clean": Imperfections(),
    "noise": Imperfections(noise_digits=5, seed=2),
    "distortion": Imperfections(harmonic=0.02),
    "quantised": Imperfections(quantise=True, seed=3),
    "dropped": Imperfections(dropped=3, seed=4),
    "everything": Imperfections(noise_digits=5, harmonic=0.02, quantise=True, dropped=3, seed=5),
}


def errors(result, fs_true):
    """Relative sensitivity errors of every axis with a sensitivity, then |fs error| in Hz."""
    rel = [
        abs(a.sensitivity / TRUTH["xyz".index(a.axis)] - 1)
        for a in result.accelerometer_axes
        if a.sensitivity
    ]
    return np.array([*rel, abs(result.fs_hz - fs_true)])


def test_expected_components_of_the_test_plan():
    comps = expected_components(10.0, [0, 15, 75, 75], [270, 90, 0, 90])
    np.testing.assert_allclose(
        comps[1],
        [
            10 * np.sin(np.radians(15)) * np.cos(np.pi / 2),
            10 * np.sin(np.radians(15)),
            10 * np.cos(np.radians(15)),
        ],
        atol=1e-12,
    )
    np.testing.assert_allclose(comps[2], [9.659258, 0.0, 2.588190], atol=1e-6)


@pytest.mark.parametrize(
    ("tilt", "rotation", "axes_ok"), [(0, 270, "z"), (15, 90, "yz"), (75, 0, "xz"), (75, 90, "yz")]
)
def test_clean_40_s_record_recovers_truth(tilt, rotation, axes_ok):
    result = record_sensitivity(linear_record(TRUTH, tilt=tilt, rotation=rotation))
    assert result.fs_hz == pytest.approx(1663.7, abs=0.01)
    for a in result.accelerometer_axes:
        if a.axis in axes_ok:
            assert a.status == "ok"
            assert a.sensitivity == pytest.approx(TRUTH["xyz".index(a.axis)], rel=5e-4)
        else:
            assert a.status == "component too small" and a.sensitivity is None


@pytest.mark.parametrize("fs", [1563.4, 1663.7, 1756.6])
@pytest.mark.parametrize("case", CASES)
def test_sine_fit_beats_paper_on_the_linear_bench(case, fs):
    rec = linear_record(TRUTH, fs=fs, f=10.0, imp=CASES[case])
    fit, study = (errors(record_sensitivity(rec, None, m), fs) for m in FIT_AND_PAPER)
    assert np.all(fit < study), (fit, study)
    assert np.all(fit[:-1] < 1e-4)


@pytest.mark.parametrize("case", CASES)
def test_sine_fit_beats_paper_on_the_curvilinear_bench(case):
    mems, encoder = curvilinear_records(TRUTH, imp=CASES[case])
    fit, study = (errors(record_sensitivity(mems, encoder, m), 1663.7) for m in FIT_AND_PAPER)
    assert np.all(fit < study), (fit, study)
    assert np.all(fit[:-1] < 5e-4)


def test_curvilinear_reference_from_the_test_plan():
    """docs/domain.md §8.2: 8.5° peak to peak at 10 Hz, r = 170 mm → 49.78 and 3.69/2."""
    a_t, a_r = encoder_reference(np.radians(8.5) / 2, 10.0, 0.170)
    assert a_t == pytest.approx(49.78, abs=0.005) and 2 * a_r == pytest.approx(3.69, abs=0.005)
    mems, encoder = curvilinear_records(TRUTH)
    result = record_sensitivity(mems, encoder)
    by_axis = {a.axis: a for a in result.accelerometer_axes}
    assert by_axis["x"].reference_amplitude_m_s2 == pytest.approx(a_t, rel=1e-9)
    assert by_axis["y"].reference_amplitude_m_s2 == pytest.approx(a_r, rel=1e-9)
    assert by_axis["y"].analysis_frequency_hz == pytest.approx(20.0, rel=1e-9)
    assert by_axis["z"].status == "not excited"


def test_iepe_reference_scaled_by_radius():
    mems, encoder = curvilinear_records(TRUTH)
    theta = encoder.data[0]
    fs = 1000.0
    a_ref = -0.145 * np.gradient(np.gradient(theta, 1 / fs), 1 / fs)  # tangential at r_ref
    ref = Record("iepe", ("ref",), a_ref[None, 2:-2], {"fs_hz": fs, "reference_radius_m": 0.145})
    result = record_sensitivity(mems, ref)
    x = next(a for a in result.accelerometer_axes if a.axis == "x")
    assert "r_ref = 0.145" in result.reference_source
    assert x.sensitivity == pytest.approx(420.0, rel=2e-3)  # finite differences bias ~(πf/fs)²


def test_paper_mode_loses_amplitude_when_the_filter_is_designed_at_the_nominal_rate():
    """The study's weakness (docs/domain.md §8.1): at 1756.6 Hz actual, a band-pass designed
    at 1660 Hz sees 10 Hz as 10·1660/1756.6 Hz and passes |H| of that, ≈ 0.66."""
    rec = linear_record(TRUTH, fs=1756.6, tilt=0, rotation=270, imp=Imperfections(gravity=False))
    z = rec.data[2]
    wrong = paper.bandpass_rms_amplitude(z, 10.0, 1660.0, 1756.6)[0] / (425.0 * 10)
    _, h = signal.sosfreqz(paper.bandpass(10.0, 1660.0), worN=[10.0 * 1660 / 1756.6], fs=1660.0)
    assert wrong == pytest.approx(abs(h[0]), rel=2e-3)
    assert wrong < 0.7
    right = paper.bandpass_rms_amplitude(z, 10.0, 1757.0, 1756.6)[0] / (425.0 * 10)
    assert right == pytest.approx(1.0, abs=1e-3)


def test_budget_combines_components_with_welch_satterthwaite():
    rec = linear_record(TRUTH, tilt=75, rotation=0, imp=Imperfections(noise_digits=5, seed=9))
    x = next(a for a in record_sensitivity(rec).accelerometer_axes if a.axis == "x")
    assert x.budget is not None and x.sensitivity is not None
    assert x.standard_uncertainty is not None
    comps = x.budget.components
    names = [c.name for c in comps]
    assert names == [
        "output amplitude (fit residuals)",
        "reference amplitude scale",
        "tilt θ (rad)",
        "rotation α (rad)",
        "sampling rate fs",
    ]
    contrib = np.array([abs(c.sensitivity_coefficient) * c.standard_uncertainty for c in comps])
    assert x.standard_uncertainty == pytest.approx(np.sqrt(np.sum(contrib**2)), rel=1e-12)
    s = x.sensitivity
    assert comps[1].sensitivity_coefficient == pytest.approx(-s / 10.0, rel=1e-12)
    assert comps[1].standard_uncertainty == pytest.approx(0.05, rel=1e-12)
    # a_x = a sinθ cosα: ∂S/∂θ = −S cotθ, ∂S/∂α = S tanα = 0 at α = 0
    assert comps[2].sensitivity_coefficient == pytest.approx(-s / np.tan(np.radians(75)), rel=1e-9)
    assert comps[3].sensitivity_coefficient == pytest.approx(0.0, abs=1e-9)
    nu = contrib**4 / np.array([c.dof for c in comps])
    dof = np.sum(contrib**2) ** 2 / np.sum(nu[np.isfinite(nu)])
    assert x.budget.dof_eff == pytest.approx(dof, rel=1e-9)
    assert x.budget.k == pytest.approx(stats.t.ppf(0.975, dof), rel=1e-9)
    assert x.standard_uncertainty / s == pytest.approx(0.005, rel=0.1)  # the 0.5 % reference


def test_clipped_axis_is_flagged_and_not_used():
    rec = linear_record(TRUTH, tilt=75, rotation=0, imp=Imperfections(quantise=True))
    data = rec.data.copy()
    data[0, 500:503] = 32767
    clipped = Record(rec.name, rec.channels, data, rec.meta, None, {"x": (3, 500)})
    by_axis = {a.axis: a for a in record_sensitivity(clipped).accelerometer_axes}
    assert by_axis["x"].status == "clipped" and by_axis["x"].sensitivity is None
    assert "first at sample 500" in by_axis["x"].note
    assert by_axis["z"].sensitivity == pytest.approx(425.0, rel=5e-4)


def test_missing_metadata_is_named():
    rec = linear_record(TRUTH)
    meta = {k: v for k, v in rec.meta.items() if k != "tilt_deg"}
    with pytest.raises(SignalInputError, match="tilt_deg is needed"):
        record_sensitivity(Record(rec.name, rec.channels, rec.data, meta))
    mems, _ = curvilinear_records(TRUTH)
    with pytest.raises(SignalInputError, match="needs a ref or encoder_rad channel"):
        record_sensitivity(mems)


def test_reference_record_with_trusted_clock_measures_the_actual_frequency():
    """Generator at 10.003 Hz for a nominal 10 Hz: the reference (10 kHz, trusted clock)
    gives f, so the MEMS rate is f / ν and neither amplitude is biased."""
    rec = linear_record(TRUTH, f=10.003, tilt=0, rotation=270, imp=Imperfections(noise_digits=2))
    meta = {k: v for k, v in rec.meta.items() if k != "a_ref_m_s2"} | {"frequency_hz": 10.0}
    mems = Record(rec.name, rec.channels, rec.data, meta)
    t = np.arange(400_000) / 10_000.0
    ref = Record(
        "daq", ("ref",), 10.0 * np.cos(2 * np.pi * 10.003 * t + 0.3)[None, :], {"fs_hz": 10_000.0}
    )
    result = record_sensitivity(mems, ref)
    z = next(a for a in result.accelerometer_axes if a.axis == "z")
    assert result.fs_hz == pytest.approx(1663.7, abs=0.01)
    assert z.reference_amplitude_m_s2 == pytest.approx(10.0, rel=1e-9)
    assert z.sensitivity == pytest.approx(425.0, rel=5e-4)
    assert result.reference_source == "ref channel of daq"
    assert z.budget is not None
    assert [c.name for c in z.budget.components][:3] == [
        "output amplitude (fit residuals)",
        "reference amplitude (fit residuals)",
        "reference amplitude scale",
    ]


def test_dropped_samples_are_reported_and_do_not_bias_the_rate():
    """3 lost samples make the record 3 samples short: a whole-record fit would put fs
    3/N low (≈ 0.075 Hz); the phase advance between segments is immune."""
    rec = linear_record(TRUTH, tilt=75, rotation=0, imp=Imperfections(dropped=3, seed=4))
    result = record_sensitivity(rec)
    assert result.fs_hz == pytest.approx(1663.7, abs=0.01)
    x = next(a for a in result.accelerometer_axes if a.axis == "x")
    assert "segments left out" in x.note
    assert x.sensitivity == pytest.approx(420.0, rel=1e-4)
    clean = next(
        a for a in record_sensitivity(linear_record(TRUTH, tilt=75, rotation=0)).accelerometer_axes
    )
    assert clean.note == ""
