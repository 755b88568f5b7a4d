"""Result containers shared by the statistics of the core."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from analysis.core.groups import BoolArray, FloatArray

DEFAULT_K = 2.0
"""Coverage factor of the expanded uncertainties the service computes (ISO 13528:2022 §7.7)."""


@dataclass(frozen=True)
class AssignedValues:
    """Assigned value x_pt and its standard uncertainty u(x_pt) for every group.

    ``value`` and ``standard_uncertainty`` have one entry per group.  ``included``
    (one entry per result) says which results entered the estimate (e.g. the
    largest consistent subset, or the reference laboratory); it drives the
    correlation correction of ISO 13528 / Cox 2002 in the scores.  ``diagnostics``
    holds per-group arrays named by the method (``chi2_obs``, ``birge_ratio``,
    ``consistent``, ``s_star``, ``tau``, ``iterations`` ...).  ``coverage_factor`` (one
    per group, default 2) gives U(x_pt) = k·u(x_pt): 2 for every estimate the service
    makes, the reference laboratory's own k where x_pt is its result.
    """

    value: FloatArray
    standard_uncertainty: FloatArray
    method: str
    included: BoolArray
    diagnostics: dict[str, np.ndarray] = field(default_factory=dict)
    coverage_factor: FloatArray | None = None

    @property
    def coverage_factors(self) -> FloatArray:
        """k of U(x_pt) per group (2 unless the source reported another)."""
        if self.coverage_factor is None:
            return np.full(self.value.shape, DEFAULT_K)
        return self.coverage_factor

    @property
    def expanded_uncertainty(self) -> FloatArray:
        """U(x_pt) = k·u(x_pt) per group."""
        return self.coverage_factors * self.standard_uncertainty

    @property
    def n_groups(self) -> int:
        return int(self.value.size)
