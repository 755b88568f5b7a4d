"""Demo data: IMU-2025-KITS, a two-kit round of all three quantity kinds (docs/domain.md
§12, §13, §15), analysed by a run of the service.

Two LSM6DSR IMUs, each circulated as two copies in two kits: on the linear bench the
accelerometer's sensitivity magnitude and phase (Z axis, 5/10/20 Hz), on the rotating table
the gyroscope's angular-rate sensitivity (Z axis, 5/8/10 Hz).  Eight laboratories of the
demo take part; ``Elbe Calibration Services`` is the pilot and reference laboratory, holding
the first slot, slots between, and the last slot of both loops.  Kit B's copy of IMU 1 has a
gyroscope whose sensitivity drifts (its pilot repeats show it, and so do the laboratories'
results on it), so the run corrects the reference to each laboratory's date.  Kit B is on
its way back to the pilot, its arrival not logged yet: the pilot has a hand-over to log
(which changes no laboratory's date, so no score) and the coordinator sees a late mark.

The values are plausible, not measured: magnitudes near the ±8 g range's 418 D/(m/s²),
phases from the decimation filter's delay (≈1.1 ms: −2° at 5 Hz to −8° at 20 Hz), angular
rates near the ±2000 dps range's 1/0.07 ≈ 14.29 D/(°/s), each laboratory with a bias of
its own and scatter within its uncertainty.  Made once; a demo that has the round keeps it.
"""

from __future__ import annotations

import datetime as dt
from dataclasses import dataclass
from typing import Any

import numpy as np

from analysis.services import analysis_run_execute, analysis_run_start
from common.quantities import ANGULAR_RATE, MAGNITUDE, PHASE
from coordination.demo_circulation import circulate
from coordination.demo_results import submit
from labs.kits import (
    SlotPlan,
    circulation_set,
    kit_create,
    kit_measurements_replace,
)
from labs.models import Laboratory, Participant, Submission
from labs.services import Scope, participants_invite
from proficiency import protocols
from proficiency.models import (
    AssignedValueMethod,
    Comparison,
    ComparisonStatus,
    Device,
    DriftTreatment,
    Kit,
    MeasurementPoint,
)
from proficiency.services import measurement_points_generate

KITS_ROUND_CODE = "IMU-2025-KITS"
DEVICES = (("IMU 1", 1.0, 1.004), ("IMU 2", 1.003, 0.997))  # name, magnitude, rate factor
MAGNITUDE_NOMINAL = 418.0  # D/(m/s²) at ±8 g
RATE_NOMINAL = 1 / 0.07  # D/(°/s) at ±2000 dps: 70 mdps per digit
FILTER_DELAY_S = 1.1e-3  # the accelerometer's decimation filter: phase = −360° f τ
#: how Kit B's copies differ from Kit A's, relative (magnitude, angular rate); their phases
#: agree, the delay being the digital filter's, the same in every copy at one data rate
KIT_B_OFFSET = (0.0025, -0.003)
#: Kit B's IMU 1 gyroscope: its angular-rate sensitivity changes by this per day
RATE_DRIFT_PER_DAY = 0.0005
PILOT = "Elbe Calibration Services"
LINEAR_LAB = "Linear Bench Calibration Laboratory"
CURVILINEAR_LAB = "Curvilinear Bench Calibration Laboratory"
#: each kit's loop after the pilot's first slot: laboratories, and None for the pilot
LOOPS = {
    "Kit A": (LINEAR_LAB, "Baltic Inertial Calibration", None, "Danube Accelerometry Centre"),
    "Kit B": (CURVILINEAR_LAB, None, "Alpine Vibration Metrology", None,
              "Castile Sensor Laboratory", None, "Fjord Measurement Institute"),
}  # fmt: skip
KIT_STARTS = {"Kit A": dt.date(2025, 2, 3), "Kit B": dt.date(2025, 2, 10)}
#: Kit B is sent back to the pilot for its last slot and its arrival is not logged yet
IN_TRANSIT = "Kit B"
#: when every laboratory's results were submitted
SUBMITTED = dt.datetime(2025, 9, 15, 12, 0, tzinfo=dt.UTC)


@dataclass(frozen=True)
class Turn:
    kit: str
    day: float  # days after the kit's start, the middle of the slot


def kits_round(coordinator: Any) -> Comparison:
    """The round (module docstring), made once, closed, and analysed by a run executed here
    as a worker would; a round already made is left as it is."""
    comparison, created = Comparison.objects.get_or_create(
        code=KITS_ROUND_CODE,
        defaults={
            "title": "IMU sensitivity: magnitude, phase and angular rate in two kits (demo)",
            "description": (
                "Two LSM6DSR IMUs in two kits, each circulated in its own loop with the pilot "
                "laboratory before, between and after: accelerometer sensitivity magnitude and "
                "phase on the linear bench (Z, 5/10/20 Hz), gyroscope angular-rate sensitivity "
                "on the rotating table (Z, 5/8/10 Hz)."
            ),
            "protocol": protocols.CUSTOM,
            "status": ComparisonStatus.CLOSED,
            "submission_deadline": dt.datetime(2025, 9, 30, 23, 59, tzinfo=dt.UTC),
            "assigned_value_method": AssignedValueMethod.REFERENCE,
            "drift_treatment": DriftTreatment.CORRECT,
            "authorised_by_name": "Demo Quality Manager",
            "authorised_by_role": "Quality manager of the PT provider (demonstration)",
        },
    )
    comparison.coordinators.add(coordinator)
    if not created:
        return comparison
    points = _points(comparison)
    participants = _participants(comparison)
    turns = _kits(comparison, participants)
    for name, participant in participants.items():
        submit(participant, _results(points, name, turns[name]), Submission.Source.FILE,
               SUBMITTED, decided_after=dt.timedelta(days=5))  # fmt: skip
    run = analysis_run_start(comparison=comparison, user=coordinator)
    analysis_run_execute(run_id=run.pk)
    comparison.refresh_from_db()
    return comparison


def _points(comparison: Comparison) -> list[MeasurementPoint]:
    devices = [
        Device.objects.create(comparison=comparison, name=name, model="LSM6DSR",
                              serial=f"LSM6DSR-KITS-{i:03d}",
                              nominal_sensitivity=MAGNITUDE_NOMINAL)
        for i, (name, _, _) in enumerate(DEVICES, 1)
    ]  # fmt: skip
    linear = protocols.TEMPLATES[protocols.LINEAR].benches[0]
    curvilinear = protocols.TEMPLATES[protocols.CURVILINEAR].benches[0]
    measurement_points_generate(
        comparison=comparison, devices=devices, axes=["Z"], frequencies_hz=linear.frequencies_hz,
        benches=[protocols.LINEAR], amplitudes=linear.amplitudes, quantities=[MAGNITUDE, PHASE],
    )  # fmt: skip
    measurement_points_generate(
        comparison=comparison, devices=devices, axes=["Z"],
        frequencies_hz=curvilinear.frequencies_hz, benches=[protocols.CURVILINEAR],
        directions=["tangential"], amplitudes=curvilinear.amplitudes, quantities=[ANGULAR_RATE],
    )  # fmt: skip
    return list(comparison.measurement_points.select_related("device").order_by("pk"))


def _participants(comparison: Comparison) -> dict[str, Participant]:
    """Every laboratory of the loops invited (the bench laboratories to their own bench),
    the pilot marked as the reference laboratory."""
    names = [PILOT, *dict.fromkeys(n for loop in LOOPS.values() for n in loop if n)]
    out = {}
    for name in names:
        bench = {LINEAR_LAB: protocols.LINEAR, CURVILINEAR_LAB: protocols.CURVILINEAR}.get(name)
        (out[name],) = participants_invite(
            comparison=comparison, laboratories=[Laboratory.objects.get(name=name)],
            scope=Scope(benches=[bench]) if bench else None, notify=False,
        )  # fmt: skip
    out[PILOT].is_reference = True
    out[PILOT].save(update_fields=["is_reference"])
    return out


def _kits(comparison: Comparison, participants: dict[str, Participant]) -> dict[str, list[Turn]]:
    """Both kits planned, circulated and measured by the pilot; each laboratory's turns."""
    devices = list(comparison.devices.order_by("name"))
    turns: dict[str, list[Turn]] = {name: [] for name in participants}
    for prefix, (kit_name, loop) in zip("AB", LOOPS.items(), strict=True):
        serials = {d: f"{prefix}-{i:03d}" for i, d in enumerate(devices, 1)}
        kit = kit_create(comparison_id=comparison.pk, name=kit_name, serials=serials)
        start = day = KIT_STARTS[kit_name]
        plan, names = [SlotPlan(participants[PILOT], day, day + dt.timedelta(days=4))], [PILOT]
        for name in (*loop, None):
            day += dt.timedelta(days=14)
            long = dt.timedelta(days=10 if name else 4)
            plan.append(SlotPlan(participants[name or PILOT], day, day + long))
            names.append(name or PILOT)
        slots = circulation_set(kit=kit, plan=plan)
        for name, slot in zip(names, slots, strict=True):
            middle = (slot.starts_on - start).days + (slot.ends_on - slot.starts_on).days / 2
            turns[name].append(Turn(kit_name, middle))
        circulate(kit, slots, pending=len(slots) if kit_name == IN_TRANSIT else None)
        _pilot_repeats(kit, turns[PILOT], start)
    return turns


def _truth(point: MeasurementPoint, kit: str, day: float) -> float:
    """The kit's copy of the point's device on ``day`` (days after the kit's start)."""
    magnitude, rate = next((m, r) for n, m, r in DEVICES if n == point.device.name)
    b = kit == "Kit B"
    if point.quantity == PHASE:
        return -360.0 * point.frequency_hz * FILTER_DELAY_S
    if point.quantity == ANGULAR_RATE:
        value = RATE_NOMINAL * rate * (1 + (KIT_B_OFFSET[1] if b else 0.0))
        return value + (RATE_DRIFT_PER_DAY * day if b and point.device.name == "IMU 1" else 0.0)
    return MAGNITUDE_NOMINAL * magnitude * (1 + (KIT_B_OFFSET[0] if b else 0.0))


def _lab_rng(name: str) -> np.random.Generator:
    return np.random.default_rng(sum(name.encode()) + 20250)


def _biases(rng: np.random.Generator) -> dict[str, float]:
    """A laboratory's bias per kind: relative for a magnitude or rate, degrees for a phase."""
    return {MAGNITUDE: rng.normal(0, 0.003), PHASE: rng.normal(0, 0.15),
            ANGULAR_RATE: rng.normal(0, 0.002)}  # fmt: skip


def _results(points: list[MeasurementPoint], name: str,
             turns: list[Turn]) -> list[tuple[MeasurementPoint, float, float]]:  # fmt: skip
    """One laboratory's results, on the kit of its first turn: its own bias per kind
    (0.3 % in magnitude, 0.15° in phase, 0.2 % in angular rate) and scatter within its U."""
    rng = _lab_rng(name)
    turn = min(turns, key=lambda t: (KIT_STARTS[t.kit] + dt.timedelta(days=t.day), t.kit))
    bias = _biases(rng)
    rel_u = {MAGNITUDE: rng.uniform(0.006, 0.010), ANGULAR_RATE: rng.uniform(0.004, 0.007)}
    phase_u = rng.uniform(0.3, 0.6)
    scope = {LINEAR_LAB: protocols.LINEAR, CURVILINEAR_LAB: protocols.CURVILINEAR}.get(name)
    out = []
    for p in points:
        if scope and p.bench != scope:
            continue
        truth = _truth(p, turn.kit, turn.day)
        if p.quantity == PHASE:
            value = truth + bias[PHASE] + rng.normal(0, 0.08)
            out.append((p, round(value, 3), round(phase_u, 2)))
            continue
        value = truth * (1 + bias[p.quantity] + rng.normal(0, 0.001))
        digits = 2 if p.quantity == MAGNITUDE else 4
        out.append((p, round(value, digits), round(rel_u[p.quantity] * value, digits)))
    return out


def _pilot_repeats(kit: Kit, turns: list[Turn], start: dt.date) -> None:
    """The pilot's measurements of the kit in each of its slots but a last one the kit has
    not reached: the copy's truth with the pilot's bias and a small scatter; its phases
    (U 0.05°, drawn from a stream of their own) link the phase points' loops (docs/domain.md
    §14)."""
    rng, phase_rng = _lab_rng(kit.name), _lab_rng(f"{kit.name} phase")
    rel = _biases(_lab_rng(PILOT))
    mine = [t for t in turns if t.kit == kit.name]
    if kit.name == IN_TRANSIT:
        mine = mine[:-1]
    points = kit.comparison.measurement_points.select_related("device")
    lines = ["device,axis,frequency_hz,bench,direction,amplitude_m_s2,quantity,measured_on,"
             "sensitivity,expanded_uncertainty"]  # fmt: skip
    for p in points.order_by("pk"):
        amplitude = "" if p.amplitude_m_s2 is None else repr(p.amplitude_m_s2)
        u = {MAGNITUDE: 0.08, PHASE: 0.05}.get(p.quantity, 0.004)
        for t in mine:
            if p.quantity == PHASE:
                value = _truth(p, kit.name, t.day) + rel[PHASE] + phase_rng.normal(0, u / 4)
            else:
                value = _truth(p, kit.name, t.day) * (1 + rel[p.quantity]) + rng.normal(0, u / 4)
            day = start + dt.timedelta(days=int(t.day))
            lines.append(f"{p.device.name},{p.axis},{p.frequency_hz!r},{p.bench},{p.direction},"
                         f"{amplitude},{p.quantity},{day},{value:.4f},{u}")  # fmt: skip
    kit_measurements_replace(kit=kit, text="\n".join(lines))
