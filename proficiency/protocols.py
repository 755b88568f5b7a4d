"""The seed protocols (docs/domain.md §8) as ready-made comparison templates.

A template says which benches, frequencies, directions and axes a comparison
measures and what excitation each point gets.  Expected amplitudes are computed
from the bench physics, not typed in:

* linear bench (§8.1): a_x = |a_ref sin θ cos α|, a_y = |a_ref sin θ sin α|,
  a_z = |a_ref cos θ| for each mounting (θ, α); the point's amplitude is a_ref.
* curvilinear bench (§8.2): θ(t) = θ0 cos(2πft) with θ0 = swing/2; tangential
  amplitude r θ0 (2πf)²; radial peak r ω0² with ω0 = 2πf θ0 (its 2f component
  has half that amplitude).  The tangential point's amplitude is the tangential
  amplitude, the radial point's the radial peak.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from common.quantities import ANGULAR_RATE, MAGNITUDE, PHASE

LINEAR = "linear"
CURVILINEAR = "curvilinear"
SINE_ON_RANDOM = "sine_on_random"
CUSTOM = "custom"

AXES = ("X", "Y", "Z")
DIRECTIONS_BY_BENCH = {LINEAR: ("vertical",), CURVILINEAR: ("tangential", "radial")}
MEMS_RADIUS_M = 0.170
IEPE_RADIUS_M = 0.145


def linear_components(
    a_ref: float, tilt_deg: float, rotation_deg: float
) -> tuple[float, float, float]:
    """Expected (a_x, a_y, a_z) peak amplitudes on the tilted plate (docs/domain.md §8.1)."""
    theta, alpha = math.radians(tilt_deg), math.radians(rotation_deg)
    return (
        abs(a_ref * math.sin(theta) * math.cos(alpha)),
        abs(a_ref * math.sin(theta) * math.sin(alpha)),
        abs(a_ref * math.cos(theta)),
    )


def curvilinear_amplitudes(
    frequency_hz: float, swing_deg: float, radius_m: float = MEMS_RADIUS_M
) -> tuple[float, float]:
    """(tangential amplitude, radial peak) in m/s² for a peak-to-peak swing
    (docs/domain.md §8.2)."""
    theta0 = math.radians(swing_deg) / 2.0
    omega = 2.0 * math.pi * frequency_hz
    omega0 = omega * theta0
    return radius_m * theta0 * omega**2, radius_m * omega0**2


@dataclass(frozen=True)
class BenchPlan:
    """One bench of a template: its frequencies, directions and excitation per frequency."""

    bench: str
    frequencies_hz: tuple[float, ...]
    directions: tuple[str, ...]
    description: str
    # amplitude_m_s2[(frequency, direction)] -> expected excitation amplitude
    amplitudes: dict[tuple[float, str], float] = field(default_factory=dict)
    settings: dict[str, object] = field(default_factory=dict)
    #: the quantity kinds (``common.quantities``) the bench can measure; a comparison made
    #: from the template asks for some of them (the magnitude by default)
    quantities: tuple[str, ...] = (MAGNITUDE,)


@dataclass(frozen=True)
class ProtocolTemplate:
    key: str
    title: str
    description: str
    benches: tuple[BenchPlan, ...]
    axes: tuple[str, ...] = AXES


LINEAR_MOUNTINGS_DEG = ((0.0, 270.0), (15.0, 90.0), (75.0, 0.0), (75.0, 90.0))
LINEAR_A_REF = 10.0
LINEAR_FREQUENCIES = (5.0, 10.0, 20.0)
CURVILINEAR_PLAN = ((5.0, 34.0), (8.0, 13.0), (10.0, 8.5))


def _linear_plan() -> BenchPlan:
    return BenchPlan(
        bench=LINEAR,
        frequencies_hz=LINEAR_FREQUENCIES,
        directions=DIRECTIONS_BY_BENCH[LINEAR],
        description=(
            "Tilt plate on a vertical exciter (ISO 16063-21 comparison), a_ref = 10 m/s² peak, "
            "mountings (θ, α) = (0°, 270°), (15°, 90°), (75°, 0°), (75°, 90°), angle "
            "tolerance 0.1°. First-order band-pass (10 % bandwidth) and RMS."
        ),
        amplitudes={(f, "vertical"): LINEAR_A_REF for f in LINEAR_FREQUENCIES},
        # the exciter's reference accelerometer and the DUT share one DAQ clock: a phase
        quantities=(MAGNITUDE, PHASE),
        settings={
            "a_ref_m_s2": LINEAR_A_REF,
            "mountings_deg": [list(m) for m in LINEAR_MOUNTINGS_DEG],
            "expected_components_m_s2": [
                list(linear_components(LINEAR_A_REF, t, a)) for t, a in LINEAR_MOUNTINGS_DEG
            ],
            "angle_tolerance_deg": 0.1,
        },
    )


def _curvilinear_plan() -> BenchPlan:
    amplitudes: dict[tuple[float, str], float] = {}
    for f, swing in CURVILINEAR_PLAN:
        tangential, radial_peak = curvilinear_amplitudes(f, swing)
        amplitudes[(f, "tangential")] = tangential
        amplitudes[(f, "radial")] = radial_peak
    return BenchPlan(
        bench=CURVILINEAR,
        frequencies_hz=tuple(f for f, _ in CURVILINEAR_PLAN),
        directions=DIRECTIONS_BY_BENCH[CURVILINEAR],
        description=(
            "Oscillating rotating table, encoder at 1000 Hz, sensing element at r = 170 mm "
            "(IEPE reference at 145 mm); swings 34° at 5 Hz, 13° at 8 Hz, 8.5° at 10 Hz; "
            "each axis mounted tangential and radial; 10 repetitions of 40 s."
        ),
        amplitudes=amplitudes,
        # the encoder gives the table's angle, hence the phase and (ω = dθ/dt) the
        # gyroscope's angular-rate sensitivity (docs/domain.md §12.1)
        quantities=(MAGNITUDE, PHASE, ANGULAR_RATE),
        settings={
            "radius_m": MEMS_RADIUS_M,
            "reference_radius_m": IEPE_RADIUS_M,
            "swing_deg_by_frequency": {str(f): s for f, s in CURVILINEAR_PLAN},
            "repetitions": 10,
            "record_length_s": 40,
        },
    )


TEMPLATES: dict[str, ProtocolTemplate] = {
    LINEAR: ProtocolTemplate(
        key=LINEAR,
        title="Linear bench (tilt plate on a vertical exciter)",
        description="Chiominto et al. 2024, linear bench, 5/10/20 Hz.",
        benches=(_linear_plan(),),
    ),
    CURVILINEAR: ProtocolTemplate(
        key=CURVILINEAR,
        title="Curvilinear bench (oscillating rotating table)",
        description="Chiominto et al. 2024, curvilinear bench, 5/8/10 Hz, tangential and radial.",
        benches=(_curvilinear_plan(),),
    ),
    "linear_and_curvilinear": ProtocolTemplate(
        key="linear_and_curvilinear",
        title="Linear and curvilinear benches (Chiominto et al. 2024)",
        description="Both benches of the seed study: the bench-to-bench comparison of Table 2.",
        benches=(_linear_plan(), _curvilinear_plan()),
    ),
    SINE_ON_RANDOM: ProtocolTemplate(
        key=SINE_ON_RANDOM,
        title="Vibration robustness (sine-on-random, IEC 60068-2-80 / ISO 16750-3)",
        description=(
            "1 g peak sine at 5, 10, 15 Hz or swept 5→20 Hz on random vibration 200–2000 Hz, "
            "ASD 0.01 g²/Hz; before/test/after zones of 3/10/3 min; 5 repetitions."
        ),
        benches=(
            BenchPlan(
                bench=SINE_ON_RANDOM,
                frequencies_hz=(5.0, 10.0, 15.0),
                directions=("vertical",),
                description="Sine-on-random service conditions SC1–SC3 (SC4 is a sweep).",
                amplitudes={(f, "vertical"): 9.80665 for f in (5.0, 10.0, 15.0)},
                settings={"random_band_hz": [200, 2000], "asd_g2_per_hz": 0.01, "odr_hz": 119},
            ),
        ),
    ),
}

PROTOCOL_CHOICES = [(key, t.title) for key, t in TEMPLATES.items()] + [(CUSTOM, "Custom")]
