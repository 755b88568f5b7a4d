"""Small rounds with kits for the run tests (docs/domain.md §13–§15): a pilot (the
reference laboratory) and six laboratories at two points of one device, in one kit or two,
the pilot's repeats of every kit on four dates, each lab at the midpoint of its slot."""

from __future__ import annotations

import datetime as dt

import numpy as np

from analysis.models import AnalysisRun
from analysis.services import analysis_run_start
from labs.kits import SlotPlan, circulation_set, kit_create
from labs.models import KitMeasurement, Submission
from proficiency.models import ComparisonStatus, Kit, MeasurementPoint
from tests.factories import (
    ComparisonFactory,
    DeviceFactory,
    MeasurementPointFactory,
    ParticipantFactory,
    ResultFactory,
    SubmissionFactory,
)

START = dt.date(2025, 1, 6)
#: the pilot's repeat dates (days after START) and their U (k = 2)
PILOT_DAYS = (0, 40, 80, 120)
PILOT_U = 0.08


def make_round(*, method: str = "reference", seed: int = 1) -> dict:
    """The round, closed, with accepted results (no kits yet)."""
    c = ComparisonFactory.create(status=ComparisonStatus.CLOSED, assigned_value_method=method)
    device = DeviceFactory.create(comparison=c, name="MEMS 1")
    points = [MeasurementPointFactory.create(device=device, frequency_hz=f) for f in (5.0, 10.0)]
    rng = np.random.default_rng(seed)
    parts = [ParticipantFactory.create(comparison=c, code=f"L{i}", is_reference=i == 0)
             for i in range(7)]  # fmt: skip
    for p in parts:
        sub = SubmissionFactory.create(participant=p, status=Submission.Status.ACCEPTED)
        for point in points:
            ResultFactory.create(submission=sub, measurement_point=point,
                                 value=round(418 + rng.normal(0, 1.5), 3),
                                 expanded_uncertainty=round(rng.uniform(2, 6), 3))  # fmt: skip
    return {"comparison": c, "device": device, "points": points, "pilot": parts[0],
            "labs": parts[1:]}  # fmt: skip


def add_kit(r: dict, name: str, labs: list, *, drift: float = 0.0, offset: float = 0.0,
            repeats: bool = True) -> Kit:  # fmt: skip
    """A kit whose loop is the pilot, ``labs`` (ten days each, a day apart), the pilot
    again; the pilot's repeats at :data:`PILOT_DAYS` drift by ``drift`` per day (none
    without ``repeats``)."""
    kit = kit_create(comparison_id=r["comparison"].pk, name=name, serials={r["device"]: name})
    plan = [SlotPlan(r["pilot"], START, START)]
    day = START + dt.timedelta(days=2)
    for lab in labs:
        plan.append(SlotPlan(lab, day, day + dt.timedelta(days=10)))
        day += dt.timedelta(days=11)
    plan.append(SlotPlan(r["pilot"], START + dt.timedelta(days=120),
                         START + dt.timedelta(days=120)))  # fmt: skip
    circulation_set(kit=kit, plan=plan)
    if not repeats:
        return kit
    wobble = (0.01, -0.012, 0.008, -0.006)
    KitMeasurement.objects.bulk_create(
        KitMeasurement(kit=kit, measurement_point=p, measured_on=START + dt.timedelta(days=d),
                       value=419.0 + offset + drift * d + w + 0.1 * i, expanded_uncertainty=PILOT_U)
        for i, p in enumerate(r["points"]) for d, w in zip(PILOT_DAYS, wobble, strict=True)
    )  # fmt: skip
    return kit


def started(comparison, capture) -> AnalysisRun:
    """A run of ``comparison``, executed on commit (``capture``: pytest-django's
    ``django_capture_on_commit_callbacks``; eager Celery runs it inline)."""
    with capture(execute=True):
        run = analysis_run_start(comparison=comparison, user=None)
    run.refresh_from_db()
    assert run.status == "succeeded", run.error
    return run


def analysed_with_coordinators(r: dict, capture, name: str, other_round: str) -> dict:
    """``r`` with its coordinator (``<name>-coordinator``) and another round's
    (``<name>-other-coordinator``, of ``other_round``), analysed by a run (:func:`started`);
    the reports' run contexts cleared."""
    from analysis.reports.assemble import clear_run_contexts
    from tests.factories import ComparisonFactory, UserFactory

    r["coordinator"] = UserFactory.create(username=f"{name}-coordinator")
    r["comparison"].coordinators.add(r["coordinator"])
    r["other"] = UserFactory.create(username=f"{name}-other-coordinator")
    ComparisonFactory.create(code=other_round).coordinators.add(r["other"])
    r["run"] = started(r["comparison"], capture)
    clear_run_contexts()
    return r


def day_of(slot_start: dt.date, slot_end: dt.date) -> float:
    """A slot's date as the run takes it (no hand-over logged): the mean of the noons."""
    return (slot_start.toordinal() + slot_end.toordinal()) / 2 + 0.5


def u_day_of(slot_start: dt.date, slot_end: dt.date) -> float:
    """That date's standard uncertainty: uniform from the first noon to the last, the
    width over √12 (docs/domain.md §13)."""
    return (slot_end - slot_start).days / np.sqrt(12.0)


def pilot_series(kit: Kit, point: MeasurementPoint) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    rows = KitMeasurement.objects.filter(kit=kit, measurement_point=point).order_by("measured_on")
    t = np.array([m.measured_on.toordinal() + 0.5 for m in rows])
    y = np.array([m.value for m in rows])
    u = np.array([m.expanded_uncertainty / m.coverage_factor for m in rows])
    return t, y, u
