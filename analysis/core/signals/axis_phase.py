"""The phase of each accelerometer axis's sensitivity, added to a bench's result
(docs/domain.md §12.1).

The phase is taken against the reference signal the magnitude used, from the same
three-parameter sine fits (IEEE 1057 §8.5) at the excitation frequency the bench's fits
found, with the DUT rate they found (``SensitivityResult.fit_frequency_hz``, ``fs_hz``):

* linear bench: the ``ref`` channel (of the record or of the reference record); the
  axis's projection of the plate's motion (sin θ cos α, sin θ sin α, cos θ) may be
  negative, which turns the output by 180°, and is taken out;
* curvilinear bench, tangential axes: the ``ref`` channel (tangential acceleration), or
  the encoder's angle, against which the tangential acceleration r·θ̈ is at 180°;
* a radial axis is read at 2f, a harmonic of the motion: no phase is given for it.

Without a reference channel (``a_ref_m_s2`` only), a common time base, or a trusted
clock (``fs_hz``) of a separate reference record, the axis says why and carries no
number.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from analysis.core.phase import wrap
from analysis.core.signals.phase import PhaseResult, relative_phase
from analysis.core.signals.records import Record
from analysis.core.signals.results import AxisResult, RateAxisResult, SensitivityResult

NO_REFERENCE = "phase not determinable: no reference channel"
RADIAL = "phase not determined: a radial axis is read at 2f"
NOMINAL_REFERENCE_CLOCK = (
    "phase not determinable: the reference record's rate is only nominal (give its fs_hz)"
)

Reference = tuple[Record | None, str, float]
"""(the reference record, None for the DUT's own; its channel; the phase of the axis's
acceleration against that channel, degrees)."""


def with_phases(
    result: SensitivityResult, mems: Record, reference: Record | None
) -> SensitivityResult:
    """``result`` with every accelerometer axis's phase (docs/domain.md §12.1)."""
    ref = reference_signal(result.bench, mems, reference)
    f = result.fit_frequency_hz or result.frequency_hz
    axes = [
        replace(a, phase=axis_phase(a, mems, ref, f, result.fs_hz))
        if isinstance(a, AxisResult) else a
        for a in result.axes
    ]  # fmt: skip
    return replace(result, axes=axes)


def reference_signal(bench: str, mems: Record, reference: Record | None) -> Reference | None:
    """The signal the bench took its reference amplitude from (the record's own first)."""
    names = ("ref", "encoder_rad") if bench == "curvilinear" else ("ref",)
    for rec in (mems, reference):
        for name in names:
            if rec is not None and name in rec.channels:
                shift = 180.0 if name == "encoder_rad" else 0.0
                return (None if rec is mems else rec), name, shift
    return None


def axis_phase(
    axis: AxisResult | RateAxisResult,
    mems: Record,
    ref: Reference | None,
    f_hz: float,
    fs_hz: float,
) -> PhaseResult:
    """The phase of one axis's sensitivity, or the reason there is none."""
    if not isinstance(axis, AxisResult) or axis.sensitivity is None:
        return PhaseResult(None, None, f"phase not determined: {axis.status}")
    if ref is None:
        return PhaseResult(None, None, NO_REFERENCE)
    if axis.direction == "radial":
        return PhaseResult(None, None, RADIAL)
    rec, channel, shift = ref
    if rec is not None and not rec.sampling_rate()[1]:  # its fit at a nominal rate drifts
        return PhaseResult(None, None, NOMINAL_REFERENCE_CLOCK)
    fs_ref = fs_hz if rec is None else None
    got = relative_phase(mems, axis.axis, rec, channel, f_hz, fs_hz=fs_hz, fs_reference_hz=fs_ref)
    if got.phase_deg is None:
        return got
    shift += _projection_turn(mems, axis.axis)
    return PhaseResult(float(wrap(got.phase_deg - shift)), got.u_phase_deg)


def _projection_turn(mems: Record, axis: str) -> float:
    """180° where the linear bench's projection of the motion on ``axis`` is negative."""
    if mems.meta.get("bench") != "linear":
        return 0.0
    t, r = np.radians(float(mems.meta["tilt_deg"])), np.radians(float(mems.meta["rotation_deg"]))
    factor = {"x": np.sin(t) * np.cos(r), "y": np.sin(t) * np.sin(r), "z": np.cos(t)}[axis]
    return 180.0 if factor < 0 else 0.0
