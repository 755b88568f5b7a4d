"""Phase and angular-rate sensitivity from synthetic records of known truth
(docs/domain.md §12.1): the phase to 0.1°, the angular-rate sensitivity to 0.05 %,
and "phase not determinable" where the records share no time base."""

from __future__ import annotations

import numpy as np
import pytest

from analysis.core.phase import difference
from analysis.core.signals.phase import (
    NO_TIME_BASE,
    angular_rate_sensitivity,
    fit_channel,
    relative_phase,
)
from analysis.core.signals.records import Record, SignalInputError
from analysis.core.signals.synthetic import gyro_record, phase_records


@pytest.mark.parametrize("truth", [-12.5, 0.0, 45.0, 179.6, -179.7])
def test_the_phase_of_two_records_with_a_trigger_offset_is_recovered_to_a_tenth_degree(truth):
    dut, ref = phase_records(phase_deg=truth, seed=int(abs(truth) * 10))
    got = relative_phase(dut, "z", ref, "ref", 80.0)
    assert got.phase_deg is not None and got.u_phase_deg is not None
    assert abs(float(difference(got.phase_deg, truth))) < 0.1
    assert got.u_phase_deg < 0.05  # residual-based, white noise of 2 digits on 4200


def test_ignoring_the_trigger_offset_would_be_wrong_by_360_f_offset():
    """The offset matters: 12.3 ms at 80 Hz is 354.24°, i.e. −5.76° wrapped."""
    dut, ref = phase_records(phase_deg=-12.5)
    got = relative_phase(dut, "z", ref, "ref", 80.0)
    no_offset = Record(dut.name, dut.channels, dut.data, {**dut.meta, "trigger_offset_s": 0.0})
    naive = relative_phase(no_offset, "z", ref, "ref", 80.0)
    assert got.phase_deg is not None and naive.phase_deg is not None
    assert float(difference(naive.phase_deg, got.phase_deg)) == pytest.approx(
        float(difference(360 * 80 * 0.0123, 0.0)), abs=0.05
    )


def test_start_times_on_one_clock_are_a_common_time_base_too():
    dut, ref = phase_records(phase_deg=30.0, offset_s=None)
    dut2 = Record(dut.name, dut.channels, dut.data, {**dut.meta, "start_time_s": 100.0123})
    ref2 = Record(ref.name, ref.channels, ref.data, {**ref.meta, "start_time_s": 100.0})
    got = relative_phase(dut2, "z", ref2, "ref", 80.0)
    assert got.phase_deg is not None and abs(float(difference(got.phase_deg, 30.0))) < 0.1


def test_without_a_common_time_base_there_is_no_number():
    dut, ref = phase_records(offset_s=None)
    got = relative_phase(dut, "z", ref, "ref", 80.0)
    assert (got.phase_deg, got.u_phase_deg, got.note) == (None, None, NO_TIME_BASE)
    assert NO_TIME_BASE == "phase not determinable: no common time base"


def test_the_offset_uncertainty_enters_the_phase_uncertainty():
    dut, ref = phase_records()
    dut2 = Record(dut.name, dut.channels, dut.data, {**dut.meta, "u_trigger_offset_s": 1e-5})
    base = relative_phase(dut, "z", ref, "ref", 80.0).u_phase_deg
    more = relative_phase(dut2, "z", ref, "ref", 80.0).u_phase_deg
    assert base is not None and more is not None
    assert more == pytest.approx(np.hypot(base, 360 * 80 * 1e-5), rel=1e-9)


@pytest.mark.parametrize(("truth", "lag"), [(114.3, -3.2), (70.0, 0.0), (262.4, -25.0)])
def test_the_gyroscope_sensitivity_from_the_encoder_to_005_percent(truth, lag):
    rec = gyro_record(sensitivity_dps=truth, phase_deg=lag, seed=int(truth))
    got = angular_rate_sensitivity(rec, "gz", None, 2.0)
    assert abs(got.sensitivity / truth - 1) < 5e-4
    assert got.omega_deg_s == pytest.approx(2 * np.pi * 2.0 * 15.0, rel=1e-5)
    assert got.phase.phase_deg is not None and abs(got.phase.phase_deg - lag) < 0.1
    assert got.per_rad_s == pytest.approx(got.sensitivity * 180 / np.pi)
    assert 0 < got.u_sensitivity < 5e-4 * truth


def test_the_encoder_and_frequency_scale_uncertainties_add_in_quadrature():
    rec = gyro_record()
    plain = angular_rate_sensitivity(rec, "gz", None, 2.0)
    more = angular_rate_sensitivity(rec, "gz", None, 2.0, u_f_rel=1e-4, u_encoder_rel=5e-3)
    rel0 = plain.u_sensitivity / plain.sensitivity
    assert more.u_sensitivity / more.sensitivity == pytest.approx(
        np.sqrt(rel0**2 + 1e-8 + 2.5e-5), rel=1e-9
    )


def test_a_fit_at_or_above_nyquist_is_refused():
    with pytest.raises(SignalInputError, match="fs/2"):
        fit_channel(np.zeros(100), 600.0, 1000.0)


def test_a_trigger_offset_that_is_not_a_number_says_where():
    dut, ref = phase_records()
    bad = Record(dut.name, dut.channels, dut.data, {**dut.meta, "trigger_offset_s": "soon"})
    with pytest.raises(SignalInputError, match="synthetic-phase-dut: trigger_offset_s"):
        relative_phase(bad, "z", ref, "ref", 80.0)
