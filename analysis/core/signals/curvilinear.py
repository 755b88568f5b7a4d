"""Curvilinear bench: oscillating rotating table (docs/domain.md §8.2).

θ(t) = θ0 cos(2πft): at radius r the tangential acceleration has amplitude
r·θ0·(2πf)² at f, the radial one a 2f component of amplitude r·(2πfθ0)²/2.  The
reference comes from the ``ref`` channel (IEPE accelerometer, tangential, at
``reference_radius_m``; scaled by r/r_ref) or from the encoder angle, whose amplitude
θ0 is *fitted* (never differentiated sample by sample).  With a trusted reference
clock the fit also measures the actual excitation frequency, which then sets the MEMS
rate (fs = f / ν).  Tangential axes are read at f, radial axes at 2f.
"""

from __future__ import annotations

import numpy as np

from analysis.core.signals.budget import (
    RADIUS_TOL_M,
    REFERENCE_U_REL,
    Input,
    rect,
    sensitivity_budget,
)
from analysis.core.signals.measure import Measured, Method, measure
from analysis.core.signals.records import Record, SignalInputError
from analysis.core.signals.results import (
    NOT_EXCITED,
    AxisResult,
    SensitivityResult,
    clipped_result,
    rows,
    usable_axes,
)

DEFAULT_RADIUS_M = 0.170
DEFAULT_REFERENCE_RADIUS_M = 0.145
ANGLE_CHECK_TOLERANCE = 0.10


def encoder_reference(theta0: float, f: float, r: float) -> tuple[float, float]:
    """(tangential amplitude at f, radial 2f amplitude) in m/s² at radius r."""
    w0 = 2 * np.pi * f * theta0
    return r * theta0 * (2 * np.pi * f) ** 2, r * w0**2 / 2


def curvilinear_sensitivity(
    mems: Record, reference: Record | None, method: Method
) -> SensitivityResult:
    """Tangential (f) and radial (2f) sensitivities of one record (docs/interfaces.md §5)."""
    meta, where = mems.meta, mems.name
    if "frequency_hz" not in meta or "orientation" not in meta:
        raise SignalInputError(
            f"{where}: frequency_hz and orientation are needed on the curvilinear bench"
        )
    f0, orientation = float(meta["frequency_hz"]), meta["orientation"]
    r = float(meta.get("radius_m", DEFAULT_RADIUS_M))
    ref_rec, ref_name = _reference_channel(mems, reference)
    fs_ref, ref_trusted = ref_rec.sampling_rate()
    ref = measure(
        rows(ref_rec, [ref_name]),
        f0,
        fs_ref,
        trusted=ref_trusted,
        method=method,
        bench="curvilinear",
    )
    f = ref.frequency_hz
    axes, clipped = usable_axes(mems)
    fs, trusted = mems.sampling_rate()
    m = measure(
        rows(mems, axes),
        f,
        fs,
        trusted=trusted,
        method=method,
        bench="curvilinear",
        harmonics=(1, 2),
    )
    refs, source, notes = _reference_inputs(ref, ref_name, ref_rec, r, meta)
    results = []
    for axis in [a for a in "xyz" if a in mems.channels]:
        direction = orientation.get(axis, "axial")
        if axis in clipped:
            results.append(clipped_result(mems, axis, direction, f0))
            continue
        if direction not in refs:
            results.append(AxisResult(axis, direction, f0, f0, None, None, None, None, NOT_EXCITED))
            continue
        i, h = axes.index(axis), 0 if direction == "tangential" else 1
        a_ref, inputs = refs[direction]
        amp = float(m.amplitude[i, h])
        budget = sensitivity_budget(
            amp,
            float(m.u_amplitude[i, h]),
            m.dof,
            a_ref,
            inputs,
            m.fs_hz,
            m.u_fs_hz,
            float(m.dln_dfs[i, h]),
        )
        note = m.left_out_note(i)
        analysed = (h + 1) * f
        results.append(
            AxisResult(axis, direction, f0, analysed, amp, a_ref, budget.value, budget, note=note)
        )
    return SensitivityResult(
        "curvilinear", method, m.fs_hz, m.u_fs_hz, f0, source, results, notes, m.frequency_hz
    )


def _reference_channel(mems: Record, reference: Record | None) -> tuple[Record, str]:
    for rec in (mems, reference):
        if rec is not None:
            for name in ("ref", "encoder_rad"):
                if name in rec.channels:
                    return rec, name
    raise SignalInputError(
        f"{mems.name}: the curvilinear bench needs a ref or encoder_rad "
        "channel (in the record or in --reference)"
    )


def _reference_inputs(
    ref: Measured, name: str, rec: Record, r: float, meta: dict[str, object]
) -> tuple[dict[str, tuple[float, list[Input]]], str, list[str]]:
    """Reference amplitude and budget inputs per direction (powers give ∂ln a/∂q)."""
    f, u_f = ref.frequency_hz, ref.u_frequency_hz
    amp, u_amp = float(ref.amplitude[0, 0]), float(ref.u_amplitude[0, 0])
    u_r = rect(RADIUS_TOL_M)
    notes: list[str] = []
    if name == "encoder_rad":
        a_t, a_r = encoder_reference(amp, f, r)
        angle = meta.get("oscillation_angle_deg")
        if (
            isinstance(angle, float)
            and abs(2 * np.degrees(amp) / angle - 1) > ANGLE_CHECK_TOLERANCE
        ):
            notes.append(
                f"encoder swing {2 * np.degrees(amp):.2f}° differs from the nominal "
                f"oscillation angle {angle:g}° by more than 10 %"
            )
        p_theta, p_r_ref = (1.0, 2.0), (0.0, 0.0)
        p_f = (2.0, 2.0)
        scale = 0.0
    else:
        r_ref = float(
            rec.meta.get(
                "reference_radius_m", meta.get("reference_radius_m", DEFAULT_REFERENCE_RADIUS_M)
            )
        )
        a_t = amp * r / r_ref
        a_r = r * (amp / (r_ref * 2 * np.pi * f)) ** 2 / 2
        p_theta, p_r_ref, p_f, scale = (1.0, 2.0), (-1.0, -2.0), (0.0, -2.0), REFERENCE_U_REL
    out = {}
    for k, (direction, a) in enumerate((("tangential", a_t), ("radial", a_r))):
        inputs = [
            Input(f"{name} amplitude (fit residuals)", amp, u_amp, p_theta[k] / amp, ref.dof, "A"),
            Input("radius r (m)", r, u_r, 1.0 / r),
            Input("excitation frequency f (Hz)", f, u_f, p_f[k] / f, ref.dof, "A"),
        ]
        if name == "ref":
            inputs += [
                Input("reference amplitude scale", amp, scale * amp, p_theta[k] / amp),
                Input("reference radius r_ref (m)", r_ref, u_r, p_r_ref[k] / r_ref),
            ]
        out[direction] = (float(a), inputs)
    source = "encoder" if name == "encoder_rad" else f"ref channel at r_ref = {r_ref:g} m"
    return out, f"{source} of {rec.name}", notes
