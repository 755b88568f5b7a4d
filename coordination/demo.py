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
phase and angular-rate points, ``IMU-2025-KITS``, is in coordination/demo_kits.py; the
earlier round in coordination/demo_earlier.py, the kits in coordination/demo_circulation.py
and the laboratories' results (and raw records) in coordination/demo_results.py.
"""

from __future__ import annotations

import datetime as dt
import secrets
import zlib
from dataclasses import dataclass, field
from typing import Any

from django.contrib.auth import get_user_model
from django.contrib.auth.models import Group, Permission
from django.db import transaction
from django.utils import timezone

from coordination.demo_circulation import round_kits
from coordination.demo_earlier import PREVIOUS_CODE as PREVIOUS_CODE
from coordination.demo_earlier import DemoLab, earlier_round
from coordination.demo_kits import kits_round
from coordination.demo_results import RAW_BIAS as RAW_BIAS
from coordination.demo_results import (
    demo_devices,
    raw_records,
    reproduction_results,
    submit,
    synthetic_results,
)
from labs.enrolment import enrolment_apply
from labs.models import Enrolment, Laboratory, Membership, Participant, Submission
from labs.services import Scope, participants_invite
from proficiency import protocols
from proficiency.models import AssignedValueMethod, Comparison, ComparisonStatus, SigmaPtMode
from proficiency.services import comparison_apply_template

DEMO_CODE = "IMU-2024-DEMO"
#: whether ``load_demo`` makes the published round before it, ``PREVIOUS_CODE``
#: (coordination/demo_earlier.py, the laboratories' history, docs/domain.md §4.1): the tests
#: turn it off unless they ask for it (tests/conftest.py; its publication renders 13 PDF
#: reports, seconds per demo loaded)
EARLIER_ROUND = True
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
#: attaches a linear and a curvilinear record whose truth is its result × ``RAW_BIAS``
RAW_DATA_LAB = "Alpine Vibration Metrology"
#: the demo round's two kits: (name, serial prefix, drift of the pilot's MEMS 1 repeats per day)
DEMO_KITS = (("Kit A", "A", 0.0), ("Kit B", "B", 0.012))
KITS = DEMO_KITS  # the tests' demo keeps its kits still (tests/conftest.py)


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
    devices = demo_devices(comparison, (1, 2, 3))
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
    labs: list[DemoLab] = []
    for name, country, username in (LINEAR_LAB, CURVILINEAR_LAB):
        bench = "linear" if username == "linear-lab" else "curvilinear"
        # each bench laboratory measures its own bench only (docs/domain.md §10)
        scope = Scope(benches=[bench])
        participant = _lab(summary, comparison, name, country, username, password, scope)
        labs.append((participant.laboratory, scope, False))
        submit(participant, reproduction_results(points, bench), Submission.Source.FILE)
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
        submit(participant, rows, Submission.Source.API if i % 2 else Submission.Source.WEB)
        if name == RAW_DATA_LAB:
            raw_records(participant)
    summary.call = _call(coordinator, *applicant, curvilinear_lab)
    round_kits(comparison, KITS, pilot_lab=LINEAR_LAB[0])
    if EARLIER_ROUND:
        summary.previous = earlier_round(coordinator, labs)
    if KITS_ROUND:
        summary.kits_round = kits_round(coordinator)
    return summary


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
    devices = demo_devices(call, (1,), serial="LSM6DSR-CALL")
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
