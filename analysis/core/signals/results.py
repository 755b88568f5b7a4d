"""Result containers of the benches and the helpers both benches share."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from analysis.core.groups import FloatArray
from analysis.core.signals.budget import Budget
from analysis.core.signals.phase import AngularRate, PhaseResult
from analysis.core.signals.records import MEMS_AXES, Record, SignalInputError

OK = "ok"
TOO_SMALL = "component too small"
CLIPPED = "clipped"
NOT_EXCITED = "not excited"


def _budget_fields(b: Budget | None) -> dict[str, Any]:
    """An ``axes`` entry's ``expanded_uncertainty``, ``coverage_factor``, ``dof_eff`` and
    ``budget`` (docs/interfaces.md §5): its budget's, or none where it has no budget."""
    if b is None:
        return {"expanded_uncertainty": None, "coverage_factor": None, "dof_eff": None,
                "budget": []}  # fmt: skip
    d = b.to_dict()
    return {"expanded_uncertainty": b.expanded, "coverage_factor": b.k, "dof_eff": d["dof_eff"],
            "budget": d["components"]}  # fmt: skip


@dataclass(frozen=True)
class AxisResult:
    """Sensitivity of one MEMS axis at one mounting (docs/interfaces.md §5 ``axes`` entry)."""

    axis: str
    direction: str
    frequency_hz: float
    analysis_frequency_hz: float
    output_amplitude: float | None
    reference_amplitude_m_s2: float | None
    sensitivity: float | None
    budget: Budget | None
    status: str = OK
    note: str = ""
    phase: PhaseResult | None = None
    """The phase of the sensitivity (docs/domain.md §12.1), once ``axis_phase`` added it."""

    @property
    def standard_uncertainty(self) -> float | None:
        return self.budget.combined if self.budget else None

    def phase_dict(self) -> dict[str, Any]:
        """``phase_deg``, ``u_phase_deg`` and ``phase_note`` (docs/interfaces.md §5)."""
        p = self.phase
        if p is None:
            return {}
        return {"phase_deg": p.phase_deg, "u_phase_deg": p.u_phase_deg, "phase_note": p.note}

    def to_dict(self) -> dict[str, Any]:
        b = self.budget
        return {
            "axis": self.axis.upper(),
            "sensor": "accelerometer",
            "direction": self.direction,
            "frequency_hz": self.frequency_hz,
            "analysis_frequency_hz": self.analysis_frequency_hz,
            "output_amplitude": self.output_amplitude,
            "reference_amplitude_m_s2": self.reference_amplitude_m_s2,
            "sensitivity": self.sensitivity,
            "standard_uncertainty": self.standard_uncertainty,
            **_budget_fields(b),
            "status": self.status,
            "note": self.note,
        } | self.phase_dict()


@dataclass(frozen=True)
class RateAxisResult:
    """Angular-rate sensitivity of one gyroscope axis on the rotating table (docs/domain.md
    §12.1; docs/interfaces.md §5 ``axes`` entry with ``sensor`` = ``gyroscope``)."""

    axis: str
    direction: str
    frequency_hz: float
    analysis_frequency_hz: float
    unit: str
    rate: AngularRate | None
    status: str = OK
    note: str = ""

    def to_dict(self) -> dict[str, Any]:
        r = self.rate
        b = r.budget if r else None
        per_rad = 180.0 / np.pi
        phase = r.phase if r else PhaseResult(None, None, f"phase not determined: {self.status}")
        return {
            "axis": self.axis.upper(),
            "sensor": "gyroscope",
            "direction": self.direction,
            "frequency_hz": self.frequency_hz,
            "analysis_frequency_hz": self.analysis_frequency_hz,
            "output_amplitude": b.components[0].value if b else None,
            "reference_amplitude_m_s2": None,
            "omega_deg_s": r.omega_deg_s if r else None,
            "sensitivity": r.sensitivity if r else None,
            "sensitivity_unit": f"{'digits' if self.unit == 'digits' else '(°/s)'}/(°/s)",
            "sensitivity_per_rad_s": r.per_rad_s if r else None,
            "standard_uncertainty_per_rad_s": r.u_sensitivity * per_rad if r else None,
            "standard_uncertainty": r.u_sensitivity if r else None,
            **_budget_fields(b),
            "status": self.status,
            "note": self.note,
            "phase_deg": phase.phase_deg,
            "u_phase_deg": phase.u_phase_deg,
            "phase_note": phase.note,
        }


@dataclass(frozen=True)
class SensitivityResult:
    """Everything ``pt_sensitivity`` reports for one record."""

    bench: str
    method: str
    fs_hz: float
    u_fs_hz: float
    frequency_hz: float
    reference_source: str
    axes: Sequence[AxisResult | RateAxisResult]
    notes: list[str] = field(default_factory=list)
    fit_frequency_hz: float | None = None
    """The excitation frequency the DUT's sine fits used (measured with a trusted clock),
    which the phase fits reuse; not in the JSON (``frequency_hz`` is the nominal f)."""

    @property
    def accelerometer_axes(self) -> list[AxisResult]:
        """The accelerometer's axes (the gyroscope's, where the record has them, left out)."""
        return [a for a in self.axes if isinstance(a, AxisResult)]

    def to_dict(self) -> dict[str, Any]:
        return {
            "fs_hz": self.fs_hz,
            "u_fs_hz": self.u_fs_hz,
            "method": self.method,
            "bench": self.bench,
            "frequency_hz": self.frequency_hz,
            "reference_source": self.reference_source,
            "axes": [a.to_dict() for a in self.axes],
            "notes": self.notes,
        }


def need(meta: dict[str, Any], key: str, where: str, why: str) -> Any:
    if key not in meta:
        raise SignalInputError(f"{where}: {key} is needed ({why})")
    return meta[key]


def usable_axes(record: Record) -> tuple[list[str], list[str]]:
    """(MEMS axes present and not clipped, clipped ones)."""
    present = [a for a in MEMS_AXES if a in record.channels]
    if not present:
        raise SignalInputError(f"{record.name}: no MEMS axis channel (x, y or z)")
    clipped = [a for a in present if a in record.clipped]
    return [a for a in present if a not in clipped], clipped


def clipped_result(record: Record, axis: str, direction: str, f: float) -> AxisResult:
    count, first = record.clipped[axis]
    return AxisResult(
        axis,
        direction,
        f,
        f,
        None,
        None,
        None,
        None,
        CLIPPED,
        f"{count} samples at the int16 rail, the first at sample {first}: saturated, not used",
    )


def rows(record: Record, names: list[str]) -> FloatArray:
    return np.asarray(record.data[[record.channels.index(n) for n in names]], dtype=np.float64)
