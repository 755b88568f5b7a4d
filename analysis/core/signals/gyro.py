"""The gyroscope channels of a record on the oscillating rotating table (docs/domain.md
§12.1): the angular-rate sensitivity of each axis from the encoder's angle, ω = dθ/dt.

The encoder channel (``encoder_rad``, in the record or in the reference record) is
measured as the curvilinear bench measures it (``analysis.core.signals.measure``): with
a trusted clock (``fs_hz``) its fit gives the actual excitation frequency f and u(f).
The gyroscope's rate is then its record's trusted ``fs_hz``, the encoder's (one record,
one clock) or the rate its own sine fit finds.  Each axis is fitted by
:func:`analysis.core.signals.phase.angular_rate_sensitivity` (S = A/(2πf·θ₀) with its
budget, and its phase against ω).  The axis of the table is the ``axial`` direction
of the record's ``orientation``; a gyroscope axis pointing elsewhere is not excited.
Without an orientation every gyroscope channel is taken as given.
"""

from __future__ import annotations

from dataclasses import dataclass

from analysis.core.signals.measure import Measured, measure
from analysis.core.signals.phase import angular_rate_sensitivity
from analysis.core.signals.records import GYRO_AXES, Record
from analysis.core.signals.results import (
    CLIPPED,
    NOT_EXCITED,
    RateAxisResult,
    need,
    rows,
)

NO_ENCODER = "no encoder"


@dataclass(frozen=True)
class GyroAxes:
    """The gyroscope axes of one record, with the rate and the reference they used."""

    axes: list[RateAxisResult]
    fs_hz: float = 0.0
    u_fs_hz: float = 0.0
    source: str = ""


def gyro_axes(mems: Record, reference: Record | None) -> GyroAxes:
    """Angular-rate sensitivity of every gyroscope channel of ``mems`` (none: empty)."""
    present = [g for g in GYRO_AXES if g in mems.channels]
    if not present:
        return GyroAxes([])
    f0 = float(need(mems.meta, "frequency_hz", mems.name, "the excitation frequency"))
    unit = str(mems.meta.get("gyro_unit", "digits"))
    enc = next((r for r in (mems, reference) if r is not None and "encoder_rad" in r.channels),
               None)  # fmt: skip
    if mems.meta.get("bench") != "curvilinear" or enc is None:
        status, note = (
            (NOT_EXCITED, "the linear bench excites no angular rate")
            if mems.meta.get("bench") != "curvilinear"
            else (NO_ENCODER, "no encoder_rad channel (record or reference): ω is not known")
        )
        return GyroAxes([RateAxisResult(g, "", f0, f0, unit, None, status, note) for g in present])
    fs_e, trusted = enc.sampling_rate()
    em = measure(rows(enc, ["encoder_rad"]), f0, fs_e, trusted=trusted, method="sine-fit",
                 bench="curvilinear")  # fmt: skip
    fs_g, u_fs_g = _gyro_rate(mems, enc, em, present)
    axes = [_axis(mems, enc, g, em, fs_g, f0, unit) for g in present]
    return GyroAxes(axes, fs_g, u_fs_g, f"encoder of {enc.name}")


def _gyro_rate(mems: Record, enc: Record, em: Measured, present: list[str]) -> tuple[float, float]:
    """(rate, u) of the gyroscope's samples: the encoder's when they share the record,
    the trusted ``fs_hz``, or found by the four-parameter fit at the encoder's f."""
    if enc is mems:
        return em.fs_hz, em.u_fs_hz
    fs, trusted = mems.sampling_rate()
    if trusted:
        return fs, 0.0
    usable = [g for g in present if g not in mems.clipped and _direction(mems, g) == "axial"]
    if not usable:  # no axis will be computed: a fit of noise would not converge
        return fs, 0.0
    gm = measure(rows(mems, usable), em.frequency_hz, fs, trusted=False, method="sine-fit",
                 bench="curvilinear")  # fmt: skip
    return gm.fs_hz, gm.u_fs_hz


def _direction(mems: Record, g: str) -> str:
    """The direction of gyroscope axis ``g`` (``gz``: that of ``z``), axial without one."""
    orientation = mems.meta.get("orientation")
    return str(orientation.get(g[1], "axial")) if orientation else "axial"


def _axis(
    mems: Record, enc: Record, g: str, em: Measured, fs_g: float, f0: float, unit: str
) -> RateAxisResult:
    direction = _direction(mems, g)
    f = em.frequency_hz
    if g in mems.clipped:
        count, first = mems.clipped[g]
        note = f"{count} samples at the int16 rail, the first at sample {first}: not used"
        return RateAxisResult(g, direction, f0, f, unit, None, CLIPPED, note)
    if direction != "axial":
        note = f"points {direction}: the table turns about the axial direction"
        return RateAxisResult(g, direction, f0, f, unit, None, NOT_EXCITED, note)
    u_enc = float(mems.meta.get("u_encoder_scale_rel", enc.meta.get("u_encoder_scale_rel", 0.0)))
    rate = angular_rate_sensitivity(
        mems, g, None if enc is mems else enc, f, u_f_rel=em.u_frequency_hz / f,
        u_encoder_rel=u_enc, fs_hz=fs_g, fs_encoder_hz=em.fs_hz,
    )  # fmt: skip
    return RateAxisResult(g, direction, f0, f, unit, rate)
