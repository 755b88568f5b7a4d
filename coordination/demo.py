"""Demo data: the seed study (docs/domain.md §8) as comparison IMU-2024-DEMO.

Two laboratories reproduce Chiominto et al. 2024: a linear-bench lab and a
curvilinear-bench lab whose per-frequency (and per-direction) results aggregate,
with the rule of docs/domain.md §3, exactly to Table 1 of the reference data.  Ten
synthetic laboratories add plausible scatter on both benches; one of them
(``Outlier Metrology Services``) is a clear outlier on MEMS 2.  A second round,
``IMU-2025-CALL``, is in preparation with its call for participation open and one pending
application (lab03's, by its manager), so a new user sees the enrolment
(docs/lifecycles.md §7) from both sides.  An earlier round, ``IMU-2023-DEMO``, is published:
the same laboratories (with other codes) at a subset of the points, analysed by a run of the
service and published by its publication job, so every laboratory has a history across rounds
(docs/domain.md §4.1).  IMU-2024-DEMO's devices travelled in two kits, each in its own loop
with the linear-bench laboratory as pilot (docs/domain.md §15): one arrival was damaged,
and the pilot's repeats show Kit B's MEMS 1 drifting (§13).  Everything is created
idempotently: running the loader twice leaves the same rows.  A two-kit round of magnitude,
phase and angular-rate points, ``IMU-2025-KITS``, is in coordination/demo_kits.py.
"""

from __future__ import annotations

import csv
import datetime as dt
import math
import secrets
import zlib
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from django.conf import settings
from django.contrib.auth import get_user_model
from django.contrib.auth.models import Group, Permission
from django.db import transaction
from django.utils import timezone

from analysis.core.signals import synthetic
from analysis.publication import active_publication, publication_start
from analysis.services import analysis_run_execute, analysis_run_start
from labs.enrolment import enrolment_apply
from labs.kits import (
    SlotPlan,
    circulation_set,
    handover_dispatch,
    handover_receive,
    kit_create,
    kit_measurements_replace,
)
from labs.models import (
    Enrolment,
    KitSlot,
    Laboratory,
    Membership,
    Participant,
    Result,
    Submission,
)
from labs.raw_services import Upload, raw_record_upload
from labs.services import Scope, participants_invite
from proficiency import protocols
from proficiency.models import (
    AssignedValueMethod,
    Comparison,
    ComparisonStatus,
    Device,
    Kit,
    MeasurementPoint,
    SigmaPtMode,
)
from proficiency.services import comparison_apply_template, measurement_points_generate

if TYPE_CHECKING:
    from analysis.core.signals.records import Record

DEMO_CODE = "IMU-2024-DEMO"
#: the published round before it: the laboratories' history (docs/domain.md §4.1)
PREVIOUS_CODE = "IMU-2023-DEMO"
#: whether ``load_demo`` makes that round: the tests turn it off unless they ask for it
#: (tests/conftest.py; its publication renders 13 PDF reports, seconds per demo loaded)
EARLIER_ROUND = True
#: its points: two of the devices, the frequencies both benches share, tangential only
PREVIOUS_DEVICES = (1, 2)
PREVIOUS_FREQUENCIES = (5.0, 10.0)
PREVIOUS_DIRECTIONS = ("vertical", "tangential")
#: whether ``load_demo`` makes IMU-2025-KITS (coordination/demo_kits.py): the tests turn it
#: off unless they ask for it (tests/conftest.py; its run costs a second per demo loaded)
KITS_ROUND = True
#: the round whose call for participation is open in the demo
CALL_CODE = "IMU-2025-CALL"
#: its enrolment closes, and its results are due, this long after the demo is first loaded
CALL_ENROLMENT = dt.timedelta(days=60)
CALL_DEADLINE = dt.timedelta(days=120)
COORDINATORS_GROUP = "coordinators"
#: the demo coordinator's name, as the reports print it ("Elena Conti, coordinator")
DEMO_COORDINATOR_NAME = ("Elena", "Conti")
NOMINAL = 418.0
REFERENCE_DATA = Path(settings.BASE_DIR) / "docs" / "reference-data"  # published tables

#: The synthetic laboratory (lab03, submitting by the API) that also has a manager account
MANAGED_LAB = 3
# (lab name, country, username, benches measured)
LINEAR_LAB = ("Linear Bench Calibration Laboratory", "IT", "linear-lab")
CURVILINEAR_LAB = ("Curvilinear Bench Calibration Laboratory", "IT", "curvilinear-lab")
SYNTHETIC_LABS = [
    ("Alpine Vibration Metrology", "AT"),
    ("Baltic Inertial Calibration", "LT"),
    ("Castile Sensor Laboratory", "ES"),
    ("Danube Accelerometry Centre", "HU"),
    ("Elbe Calibration Services", "DE"),
    ("Fjord Measurement Institute", "NO"),
    ("Outlier Metrology Services", "FR"),
    ("Garonne Test House", "FR"),
    ("Hellenic Vibration Laboratory", "GR"),
    ("Iberian Motion Metrology", "PT"),
]
OUTLIER_LAB = "Outlier Metrology Services"
RAW_DATA_LAB = "Alpine Vibration Metrology"  # attaches a linear and a curvilinear record
RAW_SECONDS = 8.0  # synthetic records generated at load time: small (~80 kB + 160 kB)
RAW_BIAS = 1.002  # the record's truth differs from the reported value by +0.2 %


# Table 1 of Chiominto et al. 2024 as shipped with the specification; the copy
# here is used only when the shared folder is absent (e.g. an installed wheel).
def table1() -> dict[tuple[str, str, str], tuple[float, float]]:
    """(bench, device, axis) -> (mean sensitivity, expanded uncertainty k=2) of Table 1."""
    text = (REFERENCE_DATA / "chiominto2024_table1.csv").read_text(encoding="utf-8")
    return {
        (r["bench"], r["device"], r["axis"]): (
            float(r["sensitivity"]),
            float(r["expanded_uncertainty"]),
        )
        for r in csv.DictReader(text.splitlines())
    }


def _offsets(point: MeasurementPoint, mean: float) -> float:
    """Deterministic per-point offset from the Table 1 mean; offsets sum to zero per bench.

    Linear: −δ, 0, +δ over 5/10/20 Hz with δ = 0.3 %; curvilinear: tangential
    −a, 0, +a (a = 0.2 %) and radial +b, 0, −b (b = 0.6 %) over 5/8/10 Hz, so the
    radial results scatter more, as in the study.
    """
    rank = {5.0: 0, 10.0: 1, 20.0: 2} if point.bench == "linear" else {5.0: 0, 8.0: 1, 10.0: 2}
    sign = rank[point.frequency_hz] - 1
    rel = {"vertical": 0.003, "tangential": 0.002, "radial": -0.006}[point.direction]
    return sign * rel * mean


def reproduction_results(
    points: list[MeasurementPoint], bench: str
) -> list[tuple[MeasurementPoint, float, float]]:
    """Results of one bench lab that aggregate (docs/domain.md §3) exactly to Table 1.

    Within each (device, axis) the offsets have mean zero, so x̄ is the Table 1
    value; every result gets the same u_i = √(u_T1² − s²), so that
    √(ū² + s²) = u_T1 = U/2.
    """
    t1 = table1()
    by_cell: dict[tuple[str, str], list[MeasurementPoint]] = {}
    for p in points:
        if p.bench == bench:
            by_cell.setdefault((p.device.name, p.axis), []).append(p)
    out = []
    for (device, axis), cell in by_cell.items():
        mean, expanded = t1[(bench, device, axis)]
        values = np.array([mean + _offsets(p, mean) for p in cell])
        s = float(np.std(values, ddof=1))
        u_single = math.sqrt((expanded / 2) ** 2 - s**2)
        out += [(p, float(v), 2 * u_single) for p, v in zip(cell, values, strict=True)]
    return out


def synthetic_results(
    points: list[MeasurementPoint], lab_index: int, outlier: bool, seed: int = 20240
) -> list[tuple[MeasurementPoint, float, float]]:
    """Plausible results: the two benches' mean as truth, lab bias ~0.4 %, noise ~0.25 %
    (``seed``: one per round, so each round draws its own)."""
    t1 = table1()
    rng = np.random.default_rng(seed + lab_index)
    bias = rng.normal(0.0, 0.004)
    rel_u = rng.uniform(0.006, 0.012)  # standard uncertainty 0.6–1.2 %
    out = []
    for p in points:
        truth = 0.5 * (
            t1[("linear", p.device.name, p.axis)][0] + t1[("curvilinear", p.device.name, p.axis)][0]
        )
        value = truth * (1 + bias + rng.normal(0.0, 0.0025))
        if outlier and p.device.name == "MEMS 2":
            value *= 1.06
        out.append((p, round(value, 2), round(2 * rel_u * value, 2)))
    return out


@dataclass
class DemoSummary:
    comparison: Comparison
    call: Comparison | None = None
    previous: Comparison | None = None
    kits_round: Comparison | None = None
    created_users: dict[str, str] = field(default_factory=dict)  # username -> password
    existing_users: list[str] = field(default_factory=list)


@transaction.atomic
def load_demo(*, password: str | None = None) -> DemoSummary:
    """Create the demo comparison, labs, users and results; idempotent."""
    comparison = _comparison()
    devices = _devices(comparison, (1, 2, 3))
    if not comparison.measurement_points.exists():
        comparison_apply_template(
            comparison=comparison, template_key="linear_and_curvilinear", devices=devices
        )
    points = list(comparison.measurement_points.select_related("device"))
    summary = DemoSummary(comparison=comparison)
    coordinator = _user(summary, "coordinator", password)
    if coordinator.is_staff:  # demo databases made before the admin was closed to them
        coordinator.is_staff = False
        coordinator.save(update_fields=["is_staff"])
    if not coordinator.get_full_name():  # the reports name coordinators by full name
        coordinator.first_name, coordinator.last_name = DEMO_COORDINATOR_NAME
        coordinator.save(update_fields=["first_name", "last_name"])
    coordinator.groups.add(_coordinators_group())
    comparison.coordinators.add(coordinator)
    admin = _user(summary, "admin", password, staff=True)
    if not admin.is_superuser:
        admin.is_superuser = True
        admin.save(update_fields=["is_superuser"])
    labs: list[tuple[Laboratory, Scope | None, bool]] = []  # (lab, scope, outlier)
    for name, country, username in (LINEAR_LAB, CURVILINEAR_LAB):
        bench = "linear" if username == "linear-lab" else "curvilinear"
        # each bench laboratory measures its own bench only (docs/domain.md §10)
        scope = Scope(benches=[bench])
        participant = _lab(summary, comparison, name, country, username, password, scope)
        labs.append((participant.laboratory, scope, False))
        _submit(participant, reproduction_results(points, bench), Submission.Source.FILE)
        if bench == "curvilinear":  # its software applies to the open call (below)
            curvilinear_lab = participant.laboratory
    for i, (name, country) in enumerate(SYNTHETIC_LABS, start=3):
        participant = _lab(summary, comparison, name, country, f"lab{i:02d}", password)
        labs.append((participant.laboratory, None, name == OUTLIER_LAB))
        if i == MANAGED_LAB:  # its manager creates the API keys its software submits with
            manager = _user(summary, f"lab{i:02d}-manager", password)
            Membership.objects.get_or_create(
                user=manager, laboratory=participant.laboratory,
                defaults={"role": Membership.Role.MANAGER},
            )  # fmt: skip
            # ... and applies to the round whose call is open (below)
            applicant = (participant.laboratory, manager)
        rows = synthetic_results(points, i, outlier=name == OUTLIER_LAB)
        _submit(participant, rows, Submission.Source.API if i % 2 else Submission.Source.WEB)
        if name == RAW_DATA_LAB:
            _raw_records(participant)
    summary.call = _call(coordinator, *applicant, curvilinear_lab)
    _kits(comparison)
    if EARLIER_ROUND:
        summary.previous = _previous(coordinator, labs)
    if KITS_ROUND:  # imported here: demo_kits reads this module's laboratories
        from coordination.demo_kits import kits_round

        summary.kits_round = kits_round(coordinator)
    return summary


#: the demo's two kits: (name, serial prefix, drift of the pilot's MEMS 1 repeats per day)
DEMO_KITS = (("Kit A", "A", 0.0), ("Kit B", "B", 0.012))
KITS = DEMO_KITS  # the tests' demo keeps its kits still (tests/conftest.py)


def _kits(comparison: Comparison) -> None:
    """Two kits circulated in two loops in the first half of 2024, the linear-bench
    laboratory as pilot before, between and after (docs/domain.md §15): every hand-over
    logged, one arrival damaged, and the pilot's repeats of MEMS 1 on the linear bench
    showing Kit B drifting (§13). Made once; a demo that has kits keeps them."""
    if comparison.kits.exists():
        return
    participants = list(comparison.participants.select_related("laboratory").order_by("code"))
    pilot = next(p for p in participants if p.laboratory.name == LINEAR_LAB[0])
    others = [p for p in participants if p != pilot]
    devices = list(comparison.devices.order_by("name"))
    points = list(comparison.measurement_points.filter(bench="linear")
                  .select_related("device").order_by("pk"))  # fmt: skip
    for index, (name, prefix, drift) in enumerate(KITS):
        serials = {d: f"{prefix}-{i:03d}" for i, d in enumerate(devices, 1)}
        kit = kit_create(comparison_id=comparison.pk, name=name, serials=serials)
        day = dt.date(2024, 1, 8)
        plan = [SlotPlan(pilot, day, day + dt.timedelta(days=4))]
        loop = others[index::2]
        for i, p in enumerate(loop):
            day += dt.timedelta(days=14)
            plan.append(SlotPlan(p, day, day + dt.timedelta(days=10)))
            if i % 2 == 1 and i < len(loop) - 1:  # the pilot again, every two laboratories
                day += dt.timedelta(days=14)
                plan.append(SlotPlan(pilot, day, day + dt.timedelta(days=4)))
        day += dt.timedelta(days=14)
        plan.append(SlotPlan(pilot, day, day + dt.timedelta(days=4)))
        slots = circulation_set(kit=kit, plan=plan)
        _circulate(kit, slots, damaged=index == 1)
        _pilot_repeats(kit, points, [s for s in slots if s.participant_id == pilot.pk], drift,
                       _own_values(pilot))  # fmt: skip


def _circulate(kit: Kit, slots: list[KitSlot], *, damaged: bool) -> None:
    """Every hand-over of a finished loop: each holder received the kit two days into its
    slot and sent it on at its end; in a damaged loop the fourth holder found MEMS 2's
    connector bent."""

    def noon(day: dt.date) -> dt.datetime:
        return dt.datetime.combine(day, dt.time(12), tzinfo=dt.UTC)

    sent = handover_dispatch(kit=kit, from_slot=None, user=None, carrier_note="courier",
                             at=noon(slots[0].starts_on - dt.timedelta(days=2)))  # fmt: skip
    for i, slot in enumerate(slots):
        broken = damaged and i == 3
        handover_receive(handover=sent, user=None, condition="damaged" if broken else "good",
                         note="MEMS 2: connector bent in transport" if broken else "",
                         at=noon(slot.starts_on))  # fmt: skip
        sent = handover_dispatch(kit=kit, from_slot=slot, user=None, carrier_note="courier",
                                 at=noon(slot.ends_on))  # fmt: skip
    handover_receive(handover=sent, user=None, condition="good",
                     at=noon(slots[-1].ends_on + dt.timedelta(days=2)))  # fmt: skip


def _own_values(participant: Participant) -> dict[int, float]:
    """The participant's accepted results by point id."""
    rows = Result.objects.filter(submission__participant=participant,
                                 submission__status=Submission.Status.ACCEPTED)  # fmt: skip
    return dict(rows.values_list("measurement_point_id", "value"))


def _pilot_repeats(kit: Kit, points: list[MeasurementPoint], slots: list[KitSlot],
                   drift: float, own: dict[int, float]) -> None:  # fmt: skip
    """The pilot's measurement of each linear-bench point in each of its slots: its own
    result there (the nominal value where it has none) with a small scatter, plus, on MEMS
    1, ``drift`` per day since the first slot (Kit B's MEMS 1 ages)."""
    rng = np.random.default_rng(zlib.crc32(kit.name.encode()))
    first = slots[0].starts_on
    lines = ["device,axis,frequency_hz,bench,direction,amplitude_m_s2,measured_on,"
             "sensitivity,expanded_uncertainty"]  # fmt: skip
    for p in points:
        amplitude = "" if p.amplitude_m_s2 is None else repr(p.amplitude_m_s2)
        rate = drift if p.device.name == "MEMS 1" else 0.0
        for slot in slots:
            base = own.get(p.pk, NOMINAL + 1.5)
            value = base + rate * (slot.starts_on - first).days + rng.normal(0, 0.03)
            lines.append(f"{p.device.name},{p.axis},{p.frequency_hz!r},{p.bench},{p.direction},"
                         f"{amplitude},{slot.starts_on},{value:.4f},0.08")  # fmt: skip
    kit_measurements_replace(kit=kit, text="\n".join(lines))


def _previous(coordinator: Any, labs: list[tuple[Laboratory, Scope | None, bool]]) -> Comparison:
    """The round a year before: created closed with every laboratory's accepted results,
    analysed by a run of the service (executed here, as a worker would: the task sent after
    commit finds it done), then its publication asked for as the Publish button asks: the
    job's task, sent after commit, renders the final reports and publishes (at once with
    the quick start's eager Celery, in the background with a worker; a test's transaction
    never commits, so there the round stays analysed with its publication pending until a
    test executes it).  A round published, or being published, is left as it is."""
    previous, created = Comparison.objects.get_or_create(
        code=PREVIOUS_CODE,
        defaults={
            "title": "MEMS accelerometer sensitivity, first round (demo, published)",
            "description": (
                "The round before IMU-2024-DEMO: two LSM6DSR accelerometers on the linear bench "
                "and on the curvilinear bench (tangential) at 5 and 10 Hz."
            ),
            "protocol": "linear_and_curvilinear",
            "status": ComparisonStatus.CLOSED,
            "submission_deadline": dt.datetime(2023, 6, 30, 23, 59, tzinfo=dt.UTC),
            "assigned_value_method": AssignedValueMethod.NOMINAL,
            "sigma_pt_mode": SigmaPtMode.RELATIVE,
            "sigma_pt_value": 1.0,
            "authorised_by_name": "Demo Quality Manager",
            "authorised_by_role": "Quality manager of the PT provider (demonstration)",
        },
    )
    previous.coordinators.add(coordinator)
    if created:
        _previous_results(previous, labs)
    if previous.status == ComparisonStatus.CLOSED:
        run = analysis_run_start(comparison=previous, user=coordinator)
        analysis_run_execute(run_id=run.pk)
        previous.refresh_from_db()
    if previous.status == ComparisonStatus.ANALYSED and active_publication(previous) is None:
        publication_start(comparison=previous, user=coordinator)
    return previous


def _previous_results(
    previous: Comparison, labs: list[tuple[Laboratory, Scope | None, bool]]
) -> None:
    devices = _devices(previous, PREVIOUS_DEVICES, serial="LSM6DSR-2023")
    for plan in protocols.TEMPLATES["linear_and_curvilinear"].benches:
        measurement_points_generate(
            comparison=previous, devices=devices, axes=protocols.AXES,
            frequencies_hz=[f for f in plan.frequencies_hz if f in PREVIOUS_FREQUENCIES],
            benches=[plan.bench],
            directions=[d for d in plan.directions if d in PREVIOUS_DIRECTIONS],
            amplitudes=plan.amplitudes,
        )  # fmt: skip
    points = list(previous.measurement_points.select_related("device"))
    submitted = dt.datetime(2023, 6, 15, 12, 0, tzinfo=dt.UTC)
    for i, (lab, scope, outlier) in enumerate(labs, start=1):
        (participant,) = participants_invite(
            comparison=previous, laboratories=[lab], scope=scope, notify=False
        )
        benches = scope.benches if scope is not None else None
        mine = [p for p in points if not benches or p.bench in benches]
        rows = synthetic_results(mine, i, outlier, seed=20230)
        _submit(participant, rows, Submission.Source.FILE, submitted)


def _call(
    coordinator: Any, laboratory: Laboratory, manager: Any, curvilinear_lab: Laboratory
) -> Comparison:
    """The two-bench round in preparation with its call open, ``laboratory``'s pending
    application for the linear bench (by its manager) and ``curvilinear_lab``'s for the
    curvilinear bench (by its software's API key); each made once, with no e-mail, as the
    demo's invitations."""
    now = timezone.now()
    call, _ = Comparison.objects.get_or_create(
        code=CALL_CODE,
        defaults={
            "title": "MEMS accelerometer sensitivity on two benches (demo, open call)",
            "description": (
                "A round in preparation: one LSM6DSR accelerometer measured on the linear bench "
                "(tilt plate on a vertical exciter, 5/10/20 Hz) and on the curvilinear bench "
                "(oscillating rotating table, 5/8/10 Hz, tangential and radial); a laboratory "
                "may run either bench or both. Laboratories apply from Open calls with the "
                "benches they run."
            ),
            "protocol": "linear_and_curvilinear",
            "status": ComparisonStatus.DRAFT,
            "submission_deadline": now + CALL_DEADLINE,
            "enrolment_open": True,
            "enrolment_closes": now + CALL_ENROLMENT,
            "assigned_value_method": AssignedValueMethod.WEIGHTED_MEAN,
        },
    )
    call.coordinators.add(coordinator)
    devices = _devices(call, (1,), serial="LSM6DSR-CALL")
    if not call.measurement_points.exists():
        comparison_apply_template(
            comparison=call, template_key="linear_and_curvilinear", devices=devices
        )
    if not Enrolment.objects.filter(comparison=call, laboratory=laboratory).exists():
        enrolment_apply(
            comparison=call, laboratory=laboratory, scope=Scope(benches=[protocols.LINEAR]),
            note="We calibrate on a linear bench up to 20 Hz; no rotating table.",
            user=manager, notify=False,
        )  # fmt: skip
    if not Enrolment.objects.filter(comparison=call, laboratory=curvilinear_lab).exists():
        enrolment_apply(
            comparison=call, laboratory=curvilinear_lab,
            scope=Scope(benches=[protocols.CURVILINEAR]),
            note="Oscillating rotating table only, tangential and radial.", notify=False,
        )  # fmt: skip
    return call


def _comparison() -> Comparison:
    comparison, _ = Comparison.objects.get_or_create(
        code=DEMO_CODE,
        defaults={
            "title": "MEMS accelerometer sensitivity on linear and curvilinear benches (demo)",
            "description": (
                "Demonstration round reproducing Chiominto et al., Micromachines 15:727 (2024): "
                "three LSM6DSR accelerometers measured on a linear bench (tilt plate on a "
                "vertical exciter, 5/10/20 Hz) and on a curvilinear bench (oscillating "
                "rotating table, 5/8/10 Hz, tangential and radial)."
            ),
            "protocol": "linear_and_curvilinear",
            "status": ComparisonStatus.CLOSED,
            "submission_deadline": dt.datetime(2024, 6, 30, 23, 59, tzinfo=dt.UTC),
            "assigned_value_method": AssignedValueMethod.NOMINAL,
            "sigma_pt_mode": SigmaPtMode.RELATIVE,
            "sigma_pt_value": 1.0,
            "authorised_by_name": "Demo Quality Manager",
            "authorised_by_role": "Quality manager of the PT provider (demonstration)",
        },
    )
    return comparison


def _devices(
    comparison: Comparison, numbers: tuple[int, ...], serial: str = "LSM6DSR-DEMO"
) -> list[Device]:
    return [
        Device.objects.get_or_create(
            comparison=comparison,
            name=f"MEMS {i}",
            defaults={
                "model": "LSM6DSR",
                "serial": f"{serial}-{i:03d}",
                "nominal_sensitivity": NOMINAL,
                "tolerance": 1.0,
                "tolerance_relative": True,
                "tolerance_distribution": "rectangular",
            },
        )[0]
        for i in numbers
    ]


def _coordinators_group() -> Group:
    """Coordinators may create comparisons; everything else they may do follows from the
    comparisons they coordinate (never a model permission: the admin is for superusers)."""
    group, _ = Group.objects.get_or_create(name=COORDINATORS_GROUP)
    group.permissions.set(
        Permission.objects.filter(content_type__app_label="proficiency", codename="add_comparison")
    )
    return group


def _user(summary: DemoSummary, username: str, password: str | None, *, staff: bool = False):
    user_model = get_user_model()
    user, created = user_model.objects.get_or_create(
        username=username, defaults={"email": f"{username}@example.org", "is_staff": staff}
    )
    if created:
        pw = password or secrets.token_urlsafe(12)
        user.set_password(pw)
        user.save(update_fields=["password"])
        summary.created_users[username] = pw
    else:
        summary.existing_users.append(username)
    return user


def _lab(
    summary: DemoSummary,
    comparison: Comparison,
    name: str,
    country: str,
    username: str,
    password: str | None,
    scope: Scope | None = None,
) -> Participant:
    lab, _ = Laboratory.objects.get_or_create(
        name=name,
        defaults={
            "country": country,
            "accreditation_body": "Demo accreditation body",
            "accreditation_number": f"DEMO-{zlib.crc32(name.encode()) % 10000:04d}",
            "contact_name": f"Quality manager, {name}",
            "contact_email": f"{username}@example.org",
        },
    )
    user = _user(summary, username, password)
    Membership.objects.get_or_create(
        user=user, laboratory=lab, defaults={"role": Membership.Role.STAFF}
    )
    # a new participant gets ``scope``; one from an earlier run of the demo keeps its own
    (participant,) = participants_invite(
        comparison=comparison, laboratories=[lab], scope=scope, notify=False
    )
    return participant


def _submit(
    participant: Participant,
    rows: list[tuple[MeasurementPoint, float, float]],
    source: str,
    submitted: dt.datetime = dt.datetime(2024, 6, 15, 12, 0, tzinfo=dt.UTC),
) -> None:
    if participant.submissions.exists():
        return
    submission = Submission.objects.create(
        participant=participant,
        version=1,
        status=Submission.Status.ACCEPTED,
        source=source,
        submitted_at=submitted,
        decided_at=submitted + dt.timedelta(days=16, hours=-3),
    )
    Result.objects.bulk_create(
        Result(
            submission=submission,
            measurement_point=point,
            value=value,
            unit=point.device.unit,
            expanded_uncertainty=expanded,
            coverage_factor=2.0,
        )
        for point, value, expanded in rows
    )


def _raw_records(participant: Participant) -> None:
    """A synthetic linear (int16 + sidecar) and curvilinear (int16 + encoder CSV) record
    behind MEMS 1, X, 10 Hz, whose truth is the reported value × ``RAW_BIAS``; recomputed
    by the Celery task after the loader's transaction commits."""
    if participant.raw_records.exists():
        return
    submission = participant.submissions.get(version=1)
    for bench, direction in (("linear", "vertical"), ("curvilinear", "tangential")):
        result = submission.results.select_related("measurement_point__device").get(
            measurement_point__device__name="MEMS 1", measurement_point__axis="X",
            measurement_point__frequency_hz=10.0, measurement_point__bench=bench,
            measurement_point__direction=direction,
        )  # fmt: skip
        p = result.measurement_point
        truth = (result.value * RAW_BIAS, 419.0, 424.0)
        imp = synthetic.Imperfections(noise_digits=1.5, quantise=True, seed=11)
        point = p.key._asdict()
        if bench == "linear":
            mems = synthetic.linear_record(truth, duration=RAW_SECONDS, imp=imp)
            reference = None
        else:
            mems, enc = synthetic.curvilinear_records(truth, duration=RAW_SECONDS, imp=imp)
            reference = Upload(_csv(enc), "demo-encoder.csv", {"fs_hz": enc.meta["fs_hz"]})
        data = Upload(_int16(mems), f"demo-{bench}.bin", _plain(mems.meta))
        raw_record_upload(participant=participant, point_fields=point, data=data,
                          reference=reference)  # fmt: skip


def _int16(record: Record) -> bytes:
    return np.ascontiguousarray(record.data.T).astype("<i2").tobytes()


def _csv(record: Record) -> bytes:
    rows = [",".join(record.channels)] + [f"{v:.9g}" for v in record.data[0]]
    return ("\n".join(rows) + "\n").encode()


def _plain(meta: dict) -> dict:
    return {k: list(v) if isinstance(v, tuple) else v for k, v in meta.items()}
