"""Linear bench: tilt plate on a vertical exciter (docs/domain.md §8.1, ISO 16063-21 comparison).

Expected component amplitudes for a plate tilted by θ and rotated by α:

    a_x = |a_ref sin θ cos α|,  a_y = |a_ref sin θ sin α|,  a_z = |a_ref cos θ|

Sensitivity of an axis = output amplitude (digits) / expected component (m/s²).
An axis whose expected component is below ``MIN_COMPONENT_FRACTION`` · a_ref gives no
sensitivity: the angle tolerance alone would make its relative uncertainty large.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from analysis.core.groups import FloatArray
from analysis.core.signals.budget import (
    ANGLE_TOL_DEG,
    REFERENCE_U_REL,
    Input,
    rect,
    sensitivity_budget,
)
from analysis.core.signals.measure import Measured, Method, measure
from analysis.core.signals.records import Record
from analysis.core.signals.results import (
    TOO_SMALL,
    AxisResult,
    SensitivityResult,
    clipped_result,
    need,
    rows,
    usable_axes,
)

MIN_COMPONENT_FRACTION = 0.1


def expected_components(
    a_ref: ArrayLike, tilt_deg: ArrayLike, rotation_deg: ArrayLike
) -> FloatArray:
    """(..., 3) amplitudes a_x, a_y, a_z; broadcasts over mountings."""
    a = np.asarray(a_ref, dtype=np.float64)[..., None]
    t, r = np.radians(tilt_deg), np.radians(rotation_deg)
    f = np.stack(np.broadcast_arrays(np.sin(t) * np.cos(r), np.sin(t) * np.sin(r), np.cos(t)), -1)
    return np.asarray(np.abs(a * f), dtype=np.float64)


def log_derivatives(tilt_deg: float, rotation_deg: float) -> FloatArray:
    """(3, 2): ∂ln a_i/∂θ and ∂ln a_i/∂α (per radian) for i = x, y, z."""
    t, r = np.radians(tilt_deg), np.radians(rotation_deg)
    with np.errstate(divide="ignore"):
        cot_t, tan_t, tan_r = np.cos(t) / np.sin(t), np.tan(t), np.tan(r)
        cot_r = np.cos(r) / np.sin(r)
    return np.array([[cot_t, -tan_r], [cot_t, cot_r], [-tan_t, 0.0]])


def linear_sensitivity(mems: Record, reference: Record | None, method: Method) -> SensitivityResult:
    """Per-axis sensitivity of one linear-bench record (docs/interfaces.md §5)."""
    meta, where = mems.meta, mems.name
    f = float(need(meta, "frequency_hz", where, "the excitation frequency"))
    tilt = float(need(meta, "tilt_deg", where, "linear bench mounting angle θ"))
    rot = float(need(meta, "rotation_deg", where, "linear bench mounting angle α"))
    axes, clipped = usable_axes(mems)
    fs, trusted = mems.sampling_rate()
    names = axes + (["ref"] if "ref" in mems.channels else [])
    ref_m = None
    if "ref" not in names and reference is not None:  # its clock is trusted: f is measured
        fs_r, trusted_r = reference.sampling_rate()
        ref_rows = rows(reference, ["ref"])
        ref_m = measure(ref_rows, f, fs_r, trusted=trusted_r, method=method, bench="linear")
    f_fit = ref_m.frequency_hz if ref_m else f
    m = measure(rows(mems, names), f_fit, fs, trusted=trusted, method=method, bench="linear")
    a_ref, ref_inputs, source = _reference(mems, reference, m, ref_m, names)
    expected = dict(zip("xyz", expected_components(a_ref, tilt, rot), strict=True))
    dln = dict(zip("xyz", log_derivatives(tilt, rot), strict=True))
    u_angle = np.radians(rect(ANGLE_TOL_DEG))
    results = []
    for axis in [a for a in "xyz" if a in mems.channels]:
        if axis in clipped:
            results.append(clipped_result(mems, axis, "vertical", f))
            continue
        i = names.index(axis)
        amp, comp = float(m.amplitude[i, 0]), float(expected[axis])
        if comp < MIN_COMPONENT_FRACTION * a_ref:
            results.append(
                AxisResult(
                    axis,
                    "vertical",
                    f,
                    f,
                    amp,
                    comp,
                    None,
                    None,
                    TOO_SMALL,
                    f"expected component {comp:.3g} m/s² is below {MIN_COMPONENT_FRACTION:.0%} "
                    f"of a_ref at θ = {tilt:g}°, α = {rot:g}°",
                )
            )
            continue
        inputs = [
            *ref_inputs,
            Input("tilt θ (rad)", np.radians(tilt), u_angle, float(dln[axis][0])),
            Input("rotation α (rad)", np.radians(rot), u_angle, float(dln[axis][1])),
        ]
        budget = sensitivity_budget(
            amp,
            float(m.u_amplitude[i, 0]),
            m.dof,
            comp,
            inputs,
            m.fs_hz,
            m.u_fs_hz,
            float(m.dln_dfs[i, 0]),
        )
        note = m.left_out_note(i)
        results.append(
            AxisResult(axis, "vertical", f, f, amp, comp, budget.value, budget, note=note)
        )
    return SensitivityResult(
        "linear", method, m.fs_hz, m.u_fs_hz, f, source, results, fit_frequency_hz=m.frequency_hz
    )


def _reference(
    mems: Record, reference: Record | None, m: Measured, ref_m: Measured | None, names: list[str]
) -> tuple[float, list[Input], str]:
    """a_ref and its inputs: the ``ref`` channel of the record, of the reference record,
    or ``a_ref_m_s2`` of the metadata (with the reference scale uncertainty)."""
    if "ref" in names:
        i = names.index("ref")
        a, u, dof = float(m.amplitude[i, 0]), float(m.u_amplitude[i, 0]), m.dof
        source = "ref channel"
    elif ref_m is not None and reference is not None:
        a, u, dof = float(ref_m.amplitude[0, 0]), float(ref_m.u_amplitude[0, 0]), ref_m.dof
        source = f"ref channel of {reference.name}"
    else:
        a = float(need(mems.meta, "a_ref_m_s2", mems.name, "no ref channel was given"))
        scale = Input("reference amplitude scale", a, REFERENCE_U_REL * a, 1.0 / a)
        return a, [scale], "a_ref_m_s2"
    fit = Input("reference amplitude (fit residuals)", a, u, 1.0 / a, dof, "A")
    return a, [fit, Input("reference amplitude scale", a, REFERENCE_U_REL * a, 1.0 / a)], source
