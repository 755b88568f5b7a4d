"""Sensitivity of one raw record on its bench (docs/interfaces.md §5, ``pt_sensitivity``)."""

from __future__ import annotations

from dataclasses import replace

from analysis.core.signals.axis_phase import with_phases
from analysis.core.signals.curvilinear import curvilinear_sensitivity
from analysis.core.signals.gyro import gyro_axes
from analysis.core.signals.linear import linear_sensitivity
from analysis.core.signals.measure import Method
from analysis.core.signals.records import MEMS_AXES, Record, SignalInputError
from analysis.core.signals.results import SensitivityResult

METHODS = ("sine-fit", "paper")


def record_sensitivity(
    mems: Record, reference: Record | None = None, method: Method = "sine-fit"
) -> SensitivityResult:
    """Dispatch on ``bench`` of the record's metadata (docs/domain.md §8.1 / §8.2)."""
    if method not in METHODS:
        raise SignalInputError(f"method must be one of {', '.join(METHODS)}, got {method!r}")
    bench = mems.meta.get("bench")
    if bench == "linear":
        return linear_sensitivity(mems, reference, method)
    if bench == "curvilinear":
        return curvilinear_sensitivity(mems, reference, method)
    raise SignalInputError(f"{mems.name}: bench must be linear or curvilinear (got {bench!r})")


def record_analysis(
    mems: Record, reference: Record | None = None, method: Method = "sine-fit"
) -> SensitivityResult:
    """Everything ``pt_sensitivity`` and the recomputation report for one record
    (docs/interfaces.md §5): each accelerometer axis's sensitivity with its phase, then
    each gyroscope axis's angular-rate sensitivity (docs/domain.md §12.1).  A record
    with gyroscope channels only, on the rotating table, gives the gyroscope's alone."""
    gyro = gyro_axes(mems, reference)
    accelerometer = any(a in mems.channels for a in MEMS_AXES)
    if gyro.axes and not accelerometer and mems.meta.get("bench") == "curvilinear":
        f0 = float(mems.meta["frequency_hz"])
        return SensitivityResult("curvilinear", method, gyro.fs_hz, gyro.u_fs_hz, f0,
                                 gyro.source, gyro.axes)  # fmt: skip
    result = with_phases(record_sensitivity(mems, reference, method), mems, reference)
    return replace(result, axes=[*result.axes, *gyro.axes])
