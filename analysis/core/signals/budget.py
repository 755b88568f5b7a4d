"""Uncertainty budget of a sensitivity S = A_out / a_ref (JCGM 100:2008, GUM §5.1, G.4).

Each input quantity q_i has a standard uncertainty u(q_i), degrees of freedom ν_i
(∞ for Type B) and a sensitivity coefficient c_i = ∂S/∂q_i; u_c(S)² = Σ (c_i u_i)²
(inputs uncorrelated), ν_eff by Welch–Satterthwaite and k the Student t quantile
for 95 % (``analysis.core.uncertainty``).  Plain numpy rather than GTC: the model is
a product of powers and trigonometric factors whose coefficients are written out in
closed form, so every coefficient is visible in the budget table.  The Type B
assumptions are the module constants below.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from analysis.core.uncertainty import coverage_factor, welch_satterthwaite

REFERENCE_U_REL = 0.005
"""Relative standard uncertainty of the reference amplitude scale (reference transducer
calibration, or a stated a_ref): 0.5 %, as the study's reference (docs/domain.md §8.2)."""
ANGLE_TOL_DEG = 0.1
"""Mounting angle tolerance ±0.1° (docs/domain.md §8.1), rectangular."""
RADIUS_TOL_M = 0.5e-3
"""Radius tolerance ±0.5 mm, rectangular (an assumption: the study gives none)."""


@dataclass(frozen=True)
class Component:
    """One input quantity of the budget."""

    name: str
    value: float
    standard_uncertainty: float
    sensitivity_coefficient: float
    dof: float = float("inf")
    kind: str = "B"

    @property
    def contribution(self) -> float:
        return abs(self.sensitivity_coefficient) * self.standard_uncertainty


@dataclass(frozen=True)
class Budget:
    """A sensitivity with its combined standard uncertainty, ν_eff and k (95 %)."""

    value: float
    components: tuple[Component, ...]
    combined: float
    dof_eff: float
    k: float

    @property
    def expanded(self) -> float:
        return self.k * self.combined

    def to_dict(self) -> dict[str, Any]:
        return {
            "value": self.value,
            "standard_uncertainty": self.combined,
            "dof_eff": _json_float(self.dof_eff),
            "coverage_factor": self.k,
            "expanded_uncertainty": self.expanded,
            "components": [
                {
                    "name": c.name,
                    "type": c.kind,
                    "value": c.value,
                    "standard_uncertainty": c.standard_uncertainty,
                    "sensitivity_coefficient": c.sensitivity_coefficient,
                    "contribution": c.contribution,
                    "dof": _json_float(c.dof),
                }
                for c in self.components
            ],
        }


def _json_float(v: float) -> float | None:
    """JSON has no infinity: ν = ∞ is written as null."""
    return None if not np.isfinite(v) else float(v)


@dataclass(frozen=True)
class Input:
    """An input of the reference amplitude a: its value, u, ν, and ∂ln a/∂q."""

    name: str
    value: float
    standard_uncertainty: float
    dln_a: float
    dof: float = float("inf")
    kind: str = "B"


def sensitivity_budget(
    output_amplitude: float,
    u_output: float,
    dof_output: float,
    reference_amplitude: float,
    inputs: Sequence[Input],
    fs_hz: float = 0.0,
    u_fs_hz: float = 0.0,
    dln_output_dfs: float = 0.0,
) -> Budget:
    """Budget of S = A_out / a: c = S/A_out for the output amplitude, c = −S·∂ln a/∂q
    for each reference input, c = S·∂ln A_out/∂fs for the sampling rate."""
    s = output_amplitude / reference_amplitude
    comps = [
        Component(
            "output amplitude (fit residuals)",
            output_amplitude,
            u_output,
            s / output_amplitude,
            dof_output,
            "A",
        ),
        *(
            Component(i.name, i.value, i.standard_uncertainty, -s * i.dln_a, i.dof, i.kind)
            for i in inputs
        ),
        Component("sampling rate fs", fs_hz, u_fs_hz, s * dln_output_dfs, float("inf"), "A"),
    ]
    u = np.array([c.contribution for c in comps])
    nu = np.array([c.dof for c in comps])
    keep = u > 0
    combined = float(np.sqrt(np.sum(u**2)))
    if combined == 0:
        return Budget(s, tuple(comps), 0.0, float("inf"), float(coverage_factor(np.inf)))
    dof = float(welch_satterthwaite(u[keep], nu[keep]))
    return Budget(s, tuple(comps), combined, dof, float(coverage_factor(dof)))


def rect(half_width: float) -> float:
    """u of a rectangular tolerance ±a: a/√3 (JCGM 100:2008 4.3.7)."""
    return half_width / float(np.sqrt(3.0))
