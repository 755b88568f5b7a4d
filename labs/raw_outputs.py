"""What a raw record's recomputation stores (docs/lifecycles.md §5): every axis of the
record as ``pt_sensitivity`` gives it (each accelerometer axis's sensitivity and phase, the
gyroscope axes' angular-rate sensitivity; docs/domain.md §12.1), the figures of the
measurement point — chosen by the point's quantity kind — and En against the reported
result (on the wrapped difference for a phase)."""

from __future__ import annotations

import math
from typing import Any

from analysis.core.groups import CoreInputError
from analysis.core.phase import difference
from analysis.core.signals.sensitivity import record_analysis
from common import quantities
from labs.models import RawRecomputation
from labs.raw_figures import PHASE_K
from labs.raw_selectors import raw_record_read
from proficiency.models import MeasurementPoint

#: the figures of one point: the stored columns of docs/interfaces.md §2/§5
Figures = dict[str, Any]


def recomputed_outputs(row: RawRecomputation) -> dict[str, Any]:
    """The stored outputs of a recomputation: every axis of the record (docs/interfaces.md
    §5 ``axes``, with the phases and the gyroscope axes), the point's figures, and En."""
    record = row.record
    point = record.measurement_point
    mems, reference = raw_record_read(record)
    result = record_analysis(mems, reference, row.method)  # type: ignore[arg-type]
    axes = result.to_dict()["axes"]  # with each axis's phase and the gyroscope axes
    chosen = point_figures(axes, point)
    s, big_u = chosen["sensitivity"], chosen["expanded_uncertainty"]
    en = en_number(row.reported_value, row.reported_expanded_uncertainty, s, big_u, point.quantity)
    return {
        "fs_hz": result.fs_hz,
        "u_fs_hz": result.u_fs_hz,
        "axes": axes,
        "sensitivity": s,
        "standard_uncertainty": chosen["standard_uncertainty"],
        "expanded_uncertainty": big_u,
        "coverage_factor": chosen["coverage_factor"],
        "budget": chosen["budget"],
        "en": en,
    }


def point_figures(axes: list[dict[str, Any]], point: MeasurementPoint) -> Figures:
    """The record's figures compared with the point's reported result, by the point's
    quantity kind (docs/lifecycles.md §5):

    * ``magnitude``: the point's accelerometer axis (and direction on the curvilinear
      bench), its sensitivity, U and budget;
    * ``phase``: the same axis's ``phase_deg`` with U = 2·``u_phase_deg`` (k = 2, as the
      page shows it); where the axis has no phase its note ("phase not determinable: no
      common time base") is the error, never a number;
    * ``angular_rate``: gyroscope axis ``G<axis>`` (the point's axis names the gyroscope
      axis, docs/domain.md §8; its direction is not matched: the table turns about the
      axial direction, which no bench direction names), its sensitivity, U and budget in
      the point's unit.
    """
    if point.quantity == quantities.PHASE:
        return _phase_figures(_axis_of_point(axes, point, need_value=False), point)
    if point.quantity == quantities.ANGULAR_RATE:
        return _rate_figures(_gyro_axis(axes, point), point)
    return _axis_of_point(axes, point)


def _axis_of_point(
    axes: list[dict[str, Any]], point: MeasurementPoint, *, need_value: bool = True
) -> dict[str, Any]:
    """The record's result for the point's axis (and direction on the curvilinear bench)."""
    want_direction = point.bench == "curvilinear"
    for a in axes:
        if a.get("sensor", "accelerometer") != "accelerometer":
            continue
        if a["axis"] == point.axis and (not want_direction or a["direction"] == point.direction):
            if a["sensitivity"] is None and need_value:
                raise CoreInputError(f"axis {point.axis}: {a['status']}. {a['note']}".strip())
            return a
    given = ", ".join(f"{a['axis']} {a['direction']}" for a in axes) or "no axis"
    raise CoreInputError(
        f"the record gives no sensitivity for axis {point.axis} {point.direction} "
        f"(it gives {given}); check 'orientation' in the metadata"
    )


def _phase_figures(axis: dict[str, Any], point: MeasurementPoint) -> Figures:
    """A phase point's figures from its accelerometer axis (docs/domain.md §12.1)."""
    if axis.get("phase_deg") is None:
        note = axis.get("phase_note") or f"phase not determined: {axis['status']}"
        raise CoreInputError(f"axis {point.axis}: {note}")
    u = float(axis["u_phase_deg"])
    return {"sensitivity": float(axis["phase_deg"]), "standard_uncertainty": u,
            "expanded_uncertainty": PHASE_K * u, "coverage_factor": PHASE_K,
            "budget": []}  # fmt: skip


def _gyro_axis(axes: list[dict[str, Any]], point: MeasurementPoint) -> dict[str, Any]:
    """The gyroscope axis ``G<axis>`` of an angular-rate point, with a value."""
    name = f"G{point.axis}"
    found = next((a for a in axes if a.get("sensor") == "gyroscope" and a["axis"] == name), None)
    if found is None:
        given = ", ".join(a["axis"] for a in axes if a.get("sensor") == "gyroscope") or "none"
        raise CoreInputError(
            f"the record has no gyroscope channel g{point.axis.lower()} for the angular-rate "
            f"point of axis {point.axis} (its gyroscope axes: {given}); check 'channels'"
        )
    if found["sensitivity"] is None:
        raise CoreInputError(f"axis {name}: {found['status']}. {found['note']}".strip())
    return found


def _rate_figures(axis: dict[str, Any], point: MeasurementPoint) -> Figures:
    """An angular-rate point's figures in the point's unit: the gyroscope gives digits
    per °/s; a point in digits per rad/s takes them × 180/π (``common.quantities``)."""
    if not axis["sensitivity_unit"].startswith("digits"):
        shown = quantities.unit_text
        raise CoreInputError(
            f"axis {axis['axis']}: the gyroscope output is in °/s (gyro_unit 'deg/s'), so "
            f"its sensitivity is in {shown(axis['sensitivity_unit'])}, not the point's "
            f"{shown(point.value_unit)}; upload the digits (gyro_unit 'digits')"
        )
    own = quantities.own_unit(point.quantity, point.value_unit)
    factor = own[1] if own else 1.0  # a value in the point's unit × factor = per °/s
    budget = [c | {"sensitivity_coefficient": c["sensitivity_coefficient"] / factor,
                   "contribution": c["contribution"] / factor} for c in axis["budget"]]  # fmt: skip
    return {"sensitivity": axis["sensitivity"] / factor,
            "standard_uncertainty": axis["standard_uncertainty"] / factor,
            "expanded_uncertainty": axis["expanded_uncertainty"] / factor,
            "coverage_factor": axis["coverage_factor"], "budget": budget}  # fmt: skip


def en_number(
    s_rep: float, big_u_rep: float, s_rec: float, big_u_rec: float, quantity: str | None = None
) -> float:
    """En = (S_reported − S_recomputed) / √(U_rep² + U_rec²) (ISO 13528:2022 §9.7 form);
    for a circular kind (a phase) the difference is wrapped into (−180°, 180°]
    (docs/domain.md §12): 179.9° against −179.9° is −0.2°, not 359.8°."""
    d = float(difference(s_rep, s_rec)) if quantities.is_circular(quantity) else s_rep - s_rec
    return d / math.hypot(big_u_rep, big_u_rec)
