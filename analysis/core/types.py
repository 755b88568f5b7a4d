"""Result containers shared by the statistics of the core."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from analysis.core.groups import BoolArray, FloatArray


@dataclass(frozen=True)
class AssignedValues:
    """Assigned value x_pt and its standard uncertainty u(x_pt) for every group.

    ``value`` and ``standard_uncertainty`` have one entry per group.  ``included``
    (one entry per result) says which results entered the estimate (e.g. the
    largest consistent subset, or the reference laboratory); it drives the
    correlation correction of ISO 13528 / Cox 2002 in the scores.  ``diagnostics``
    holds per-group arrays named by the method (``chi2_obs``, ``birge_ratio``,
    ``consistent``, ``s_star``, ``tau``, ``iterations`` ...).
    """

    value: FloatArray
    standard_uncertainty: FloatArray
    method: str
    included: BoolArray
    diagnostics: dict[str, np.ndarray] = field(default_factory=dict)

    @property
    def n_groups(self) -> int:
        return int(self.value.size)
