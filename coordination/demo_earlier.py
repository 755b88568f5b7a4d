"""Demo data: IMU-2023-DEMO, the published round before the demo round (docs/domain.md §4.1).

The same laboratories (with other codes) at a subset of the points, analysed by a run of
the service and published by its publication job, so every laboratory has a history
across rounds.  ``coordination.demo.load_demo`` makes it where ``EARLIER_ROUND`` says so.
"""

from __future__ import annotations

import datetime as dt
from typing import Any

from analysis.publication import active_publication, publication_start
from analysis.services import analysis_run_execute, analysis_run_start
from coordination.demo_results import demo_devices, submit, synthetic_results
from labs.models import Laboratory, Submission
from labs.services import Scope, participants_invite
from proficiency import protocols
from proficiency.models import AssignedValueMethod, Comparison, ComparisonStatus, SigmaPtMode
from proficiency.services import measurement_points_generate

PREVIOUS_CODE = "IMU-2023-DEMO"
#: its points: two of the devices, the frequencies both benches share, tangential only
PREVIOUS_DEVICES = (1, 2)
PREVIOUS_FREQUENCIES = (5.0, 10.0)
PREVIOUS_DIRECTIONS = ("vertical", "tangential")
#: a laboratory of the demo round: (laboratory, its scope there, whether it is the outlier)
DemoLab = tuple[Laboratory, Scope | None, bool]


def earlier_round(coordinator: Any, labs: list[DemoLab]) -> Comparison:
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
        _earlier_results(previous, labs)
    if previous.status == ComparisonStatus.CLOSED:
        run = analysis_run_start(comparison=previous, user=coordinator)
        analysis_run_execute(run_id=run.pk)
        previous.refresh_from_db()
    if previous.status == ComparisonStatus.ANALYSED and active_publication(previous) is None:
        publication_start(comparison=previous, user=coordinator)
    return previous


def _earlier_results(previous: Comparison, labs: list[DemoLab]) -> None:
    devices = demo_devices(previous, PREVIOUS_DEVICES, serial="LSM6DSR-2023")
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
        submit(participant, rows, Submission.Source.FILE, submitted)
