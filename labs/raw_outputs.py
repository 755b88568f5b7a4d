"""What a raw record's recomputation stores (docs/lifecycles.md §5): every axis of the
record as ``pt_sensitivity`` gives it (each accelerometer axis's sensitivity and phase, the
gyroscope axes' angular-rate sensitivity; docs/domain.md §12.1), the figures of the
measurement point's axis, and En against the reported result."""

from __future__ import annotations

import math
from typing import Any

from analysis.core.groups import CoreInputError
from analysis.core.signals.sensitivity import record_analysis
from labs.models import RawRecomputation
from labs.raw_selectors import raw_record_read
from proficiency.models import MeasurementPoint


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
    return {
        "fs_hz": result.fs_hz,
        "u_fs_hz": result.u_fs_hz,
        "axes": axes,
        "sensitivity": s,
        "standard_uncertainty": chosen["standard_uncertainty"],
        "expanded_uncertainty": big_u,
        "coverage_factor": chosen["coverage_factor"],
        "budget": chosen["budget"],
        "en": en_number(row.reported_value, row.reported_expanded_uncertainty, s, big_u),
    }


def point_figures(axes: list[dict[str, Any]], point: MeasurementPoint) -> dict[str, Any]:
    """The record's figures that are compared with the point's reported result.

    Today every measurement point is a sensitivity magnitude, so this is the point's
    accelerometer axis (:func:`_axis_of_point`); the axis's ``phase_deg`` and the
    gyroscope axes (``sensor`` = ``gyroscope``) are stored beside it in ``axes``.  Once
    ``MeasurementPoint`` carries its ``quantity`` (``magnitude`` | ``phase`` |
    ``angular_rate``, issue 20 Deliver 1) this will map by it: a phase point to the same
    axis's ``phase_deg`` / ``u_phase_deg`` (a "not determinable" note being the error),
    an angular-rate point to gyroscope axis ``G<axis>``'s sensitivity and budget."""
    return _axis_of_point(axes, point)


def _axis_of_point(axes: list[dict[str, Any]], point: MeasurementPoint) -> dict[str, Any]:
    """The record's result for the point's axis (and direction on the curvilinear bench)."""
    want_direction = point.bench == "curvilinear"
    for a in axes:
        if a.get("sensor", "accelerometer") != "accelerometer":
            continue
        if a["axis"] == point.axis and (not want_direction or a["direction"] == point.direction):
            if a["sensitivity"] is None:
                raise CoreInputError(f"axis {point.axis}: {a['status']}. {a['note']}".strip())
            return a
    given = ", ".join(f"{a['axis']} {a['direction']}" for a in axes)
    raise CoreInputError(
        f"the record gives no sensitivity for axis {point.axis} {point.direction} "
        f"(it gives {given}); check 'orientation' in the metadata"
    )


def en_number(s_rep: float, big_u_rep: float, s_rec: float, big_u_rec: float) -> float:
    """En = (S_reported − S_recomputed) / √(U_rep² + U_rec²) (ISO 13528:2022 §9.7 form)."""
    return (s_rep - s_rec) / math.hypot(big_u_rep, big_u_rec)
