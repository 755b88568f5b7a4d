"""A stored recomputation's phases and gyroscope axes as the rows a page shows
(docs/domain.md §12.1, numbers written by docs/domain.md §3.1 in the templates)."""

from __future__ import annotations

import math
from typing import Any

PHASE_K = 2.0
"""The phase's U = 2·u (docs/domain.md §3: k defaults to 2); its fits have ν in the
thousands, where the Student factor is 1.96."""


def record_figures(axes: list[dict[str, Any]]) -> dict[str, list[dict[str, Any]]]:
    """A stored ``axes`` list as the rows a page shows (docs/domain.md §12.1): ``phases``
    of the accelerometer axes that have a sensitivity, and the gyroscope axes' ``rates``,
    each with its U (k = 2 for a phase) or the note in words.  Rows written before the
    phase was computed carry neither and are left out."""
    phases = [
        {"axis": a["axis"], "direction": a["direction"], "phase": a["phase_deg"],
         "U": _times(a.get("u_phase_deg"), PHASE_K), "note": a.get("phase_note", "")}
        for a in axes
        if a.get("sensor", "accelerometer") == "accelerometer" and "phase_note" in a
        and a["sensitivity"] is not None
    ]  # fmt: skip
    rates = [_rate_row(a) for a in axes if a.get("sensor") == "gyroscope"]
    return {"phases": phases, "rates": rates}


def _rate_row(a: dict[str, Any]) -> dict[str, Any]:
    per_rad = 180.0 / math.pi
    big_u = a["expanded_uncertainty"]
    return {
        "axis": a["axis"], "direction": a["direction"], "unit": a["sensitivity_unit"],
        "omega": a["omega_deg_s"], "S": a["sensitivity"], "U": big_u, "k": a["coverage_factor"],
        "S_rad": a["sensitivity_per_rad_s"], "U_rad": _times(big_u, per_rad),
        "phase": a["phase_deg"], "U_phase": _times(a["u_phase_deg"], PHASE_K),
        "note": a["note"] or (a["phase_note"] if a["sensitivity"] is not None else a["status"]),
        "phase_note": a["phase_note"],
    }  # fmt: skip


def _times(value: float | None, factor: float) -> float | None:
    return None if value is None else value * factor
