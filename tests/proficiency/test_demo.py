"""The demo loader: idempotent, and its two bench labs reproduce Table 1 exactly."""

import csv
import datetime as dt
from io import StringIO
from pathlib import Path

import numpy as np
import pytest
from django.contrib.auth import get_user_model
from django.core.management import call_command
from django.db.models import Model

from coordination.demo import CALL_CODE, DEMO_CODE, LINEAR_LAB, OUTLIER_LAB, PREVIOUS_CODE
from labs.models import Enrolment, Laboratory, Membership, Notice, Participant, Result, Submission
from labs.selectors import scope_text
from proficiency.models import Comparison, Device, MeasurementPoint
from proficiency.selectors import open_calls

pytestmark = pytest.mark.django_db
REFERENCE = Path(__file__).resolve().parents[2] / "docs" / "reference-data"


def counts() -> dict[str, int]:
    models: list[type[Model]] = [
        Comparison,
        Device,
        MeasurementPoint,
        Laboratory,
        Membership,
        Participant,
        Submission,
        Result,
        get_user_model(),
        Enrolment,
    ]
    return {m.__name__: m._default_manager.count() for m in models}


FIRST = {
    # the demo round, and IMU-2025-CALL with its call open (1 device on both benches:
    # 9 linear and 18 curvilinear points)
    "Comparison": 2,
    "Device": 3 + 1,
    "MeasurementPoint": 81 + 27,
    "Laboratory": 12,
    "Membership": 13,
    "Participant": 12,
    "Submission": 12,
    # 2 bench labs (27 + 54 points) and 10 labs measuring all 81 points
    "Result": 27 + 54 + 10 * 81,
    "User": 15,
    "Enrolment": 2,
}


def test_load_demo_twice_gives_the_same_rows():
    out = StringIO()
    call_command("load_demo", password="demo-password-1", stdout=out)
    first = counts()
    assert first == FIRST
    assert "coordinator" in out.getvalue() and "demo-password-1" in out.getvalue()
    out2 = StringIO()
    call_command("load_demo", stdout=out2)
    assert counts() == first
    assert "demo-password-1" not in out2.getvalue()
    assert "kept their passwords" in out2.getvalue()


def test_demo_accounts_and_roles():
    call_command("load_demo", password="demo-password-1", stdout=StringIO())
    users = get_user_model().objects
    assert users.get(username="admin").is_superuser
    coordinator = users.get(username="coordinator")
    assert coordinator.check_password("demo-password-1")
    assert coordinator.get_full_name() == "Elena Conti"  # as the reports name coordinators
    assert coordinator.groups.filter(name="coordinators").exists()
    # least privilege: no staff flag, and the one model permission coordinators use
    assert not coordinator.is_staff
    assert sorted(coordinator.get_all_permissions()) == ["proficiency.add_comparison"]
    assert Comparison.objects.get(code=DEMO_CODE).coordinators.filter(pk=coordinator.pk).exists()
    assert Membership.objects.filter(user__username="lab07").get().laboratory.name
    staff = Membership.objects.get(user__username="lab03")
    manager = Membership.objects.get(user__username="lab03-manager")
    assert (staff.role, manager.role) == ("staff", "manager")
    assert manager.laboratory == staff.laboratory


def test_demo_has_an_open_call_with_two_pending_applications():
    out = StringIO()
    call_command("load_demo", password="demo-password-1", stdout=out)
    assert [c.code for c in open_calls()] == [CALL_CODE]
    call = Comparison.objects.get(code=CALL_CODE)
    assert call.status == "draft"
    assert call.coordinators.filter(username="coordinator").exists()
    application = Enrolment.objects.get(laboratory__members__user__username="lab03")
    assert application.comparison == call
    assert application.status == Enrolment.Status.PENDING
    assert application.applied_by is not None
    assert application.applied_by.username == "lab03-manager"
    assert scope_text(application) == "bench linear"
    by_key = Enrolment.objects.get(laboratory__members__user__username="curvilinear-lab")
    assert (by_key.status, by_key.applied_by, scope_text(by_key)) == (
        Enrolment.Status.PENDING,
        None,
        "bench curvilinear",
    )
    assert not call.participants.exists()
    assert not Notice.objects.filter(comparison=call).exists()  # the demo e-mails nobody
    assert f"Open call {CALL_CODE}: 27 measurement points, 2 pending applications" in (
        out.getvalue()
    )


def aggregate(values, u):
    """docs/domain.md §3, written out: mean, sqrt(mean(u)^2 + s^2) with s of ddof = 1."""
    values, u = np.asarray(values), np.asarray(u)
    return values.mean(), np.sqrt(u.mean() ** 2 + values.std(ddof=1) ** 2)


def test_bench_labs_reproduce_table1():
    call_command("load_demo", password="demo-password-1", stdout=StringIO())
    rows = list(csv.DictReader((REFERENCE / "chiominto2024_table1.csv").open()))
    assert len(rows) == 18
    lab_of = {
        "linear": "Linear Bench Calibration Laboratory",
        "curvilinear": "Curvilinear Bench Calibration Laboratory",
    }
    for row in rows:
        results = Result.objects.filter(
            submission__participant__laboratory__name=lab_of[row["bench"]],
            measurement_point__device__name=row["device"],
            measurement_point__axis=row["axis"],
        )
        n_expected = 3 if row["bench"] == "linear" else 6
        assert results.count() == n_expected
        assert {r.measurement_point.bench for r in results} == {row["bench"]}
        mean, u = aggregate([r.value for r in results], [r.standard_uncertainty for r in results])
        assert mean == pytest.approx(float(row["sensitivity"]), abs=1e-9), row
        assert 2 * u == pytest.approx(float(row["expanded_uncertainty"]), abs=1e-9), row


def test_outlier_is_clear_and_the_rest_plausible():
    call_command("load_demo", password="demo-password-1", stdout=StringIO())
    results = Result.objects.select_related(
        "measurement_point__device", "submission__participant__laboratory"
    )
    for r in results:
        lab = r.submission.participant.laboratory.name
        dev = r.measurement_point.device.name
        deviation = abs(r.value / 418.0 - 1)
        if lab == OUTLIER_LAB and dev == "MEMS 2":
            assert deviation > 0.05
        else:
            assert deviation < 0.04, (lab, dev, r.value)
        assert 0 < r.expanded_uncertainty / r.value < 0.06


def test_the_two_bench_labs_have_their_bench_as_scope():
    """Each bench laboratory reports its own bench's points: its submission is complete for
    its scope (docs/domain.md §10); the synthetic laboratories report every point."""
    from coordination.demo import CURVILINEAR_LAB, LINEAR_LAB
    from labs.selectors import participant_points, scope_text

    call_command("load_demo", password="demo-password-1", stdout=StringIO())
    comparison = Comparison.objects.get(code=DEMO_CODE)
    n_points = comparison.measurement_points.count()
    for (name, _, _), bench in ((LINEAR_LAB, "linear"), (CURVILINEAR_LAB, "curvilinear")):
        participant = Participant.objects.get(comparison=comparison, laboratory__name=name)
        assert scope_text(participant) == f"bench {bench}"
        points = set(participant_points(participant).values_list("pk", flat=True))
        assert points == set(
            comparison.measurement_points.filter(bench=bench).values_list("pk", flat=True)
        )
        assert len(points) < n_points
        reported = Result.objects.filter(submission__participant=participant)
        assert set(reported.values_list("measurement_point_id", flat=True)) == points
    synthetic = Participant.objects.get(comparison=comparison, laboratory__name=OUTLIER_LAB)
    assert participant_points(synthetic).count() == n_points


def test_the_previous_round_is_published_by_its_job_and_makes_a_history(
    demo_earlier_round, django_capture_on_commit_callbacks
):
    """IMU-2023-DEMO: analysed by a run of the service, published by its publication job (here
    run at commit, as the quick start's eager Celery runs it), with its final reports and
    notices; then every laboratory has a history, joined through it across its codes."""
    from analysis.history import lab_history
    from analysis.models import Publication, Report
    from analysis.services import analysis_run_execute, analysis_run_start

    with django_capture_on_commit_callbacks(execute=True):
        call_command("load_demo", password="demo-password-1", stdout=StringIO())
    previous = Comparison.objects.get(code=PREVIOUS_CODE)
    job = Publication.objects.get(comparison=previous)
    assert (previous.status, job.status) == ("published", "succeeded"), job.error
    assert Report.objects.filter(comparison=previous, status="final").count() == 1 + 12
    assert Notice.objects.filter(comparison=previous, kind="published").count() == 12
    assert not Notice.objects.filter(comparison__code=DEMO_CODE).exists()
    demo = Comparison.objects.get(code=DEMO_CODE)
    run = analysis_run_start(comparison=demo, user=None)
    assert analysis_run_execute(run_id=run.pk) == "succeeded"
    Comparison.objects.filter(pk=demo.pk).update(status="published")
    lab = Laboratory.objects.get(name=LINEAR_LAB[0])
    codes = {c: Participant.objects.get(comparison__code=c, laboratory=lab).code
             for c in (PREVIOUS_CODE, DEMO_CODE)}  # fmt: skip
    history = lab_history(lab)
    assert [(r.code, r.own_code) for r in history.rounds] == list(codes.items())
    assert [(r.en_scored, r.z_scored) for r in history.rounds] == [(12, 12), (27, 27)]
    (point,) = [
        p for p in history.points if p.key.label == "LSM6DSR, X, 5 Hz, linear vertical, 10 m/s²"
    ]
    assert [(e.round_code, e.device, e.own_code) for e in point.entries] == [
        (PREVIOUS_CODE, "MEMS 1", codes[PREVIOUS_CODE]),
        (PREVIOUS_CODE, "MEMS 2", codes[PREVIOUS_CODE]),
        (DEMO_CODE, "MEMS 1", codes[DEMO_CODE]),
        (DEMO_CODE, "MEMS 2", codes[DEMO_CODE]),
        (DEMO_CODE, "MEMS 3", codes[DEMO_CODE]),
    ]
    assert point.combined is not None and point.combined.n == 5
    assert {p.key.bench for p in history.points} == {"linear"}  # its scope, in both rounds
    assert counts() == {
        **FIRST,  # the demo round and the open call, as without it, and IMU-2023-DEMO: 2
        # devices × 3 axes × 5 and 10 Hz, linear vertical and curvilinear tangential; the
        # bench labs 12 points each, the others all 24
        "Comparison": 3, "Device": 4 + 2, "MeasurementPoint": 108 + 24, "Participant": 24,
        "Submission": 24, "Result": 891 + 2 * 12 + 10 * 24,
    }  # fmt: skip
    call_command("load_demo", stdout=StringIO())
    assert (
        counts()["Result"] == 1155 and Publication.objects.filter(comparison=previous).count() == 1
    )


def test_the_demo_round_circulated_two_kits_and_one_drifts(demo_kit_drift):
    from labs.kits import circulation_status, kit_drift
    from labs.models import Handover

    call_command("load_demo", password="demo-password-1", stdout=StringIO())
    call_command("load_demo", stdout=StringIO())  # the kits are made once
    demo = Comparison.objects.get(code=DEMO_CODE)
    kits = list(demo.kits.order_by("name"))
    assert [k.name for k in kits] == ["Kit A", "Kit B"]
    for kit in kits:
        slots = circulation_status(kit, today=dt.date(2024, 12, 1))
        # the pilot first, between and last; every hand-over received, none late or overdue
        assert slots[0].slot.participant == slots[-1].slot.participant
        assert Handover.objects.filter(kit=kit, received_at__isnull=True).count() == 0
        assert not any(s.late or s.overdue for s in slots)
    assert [s.damaged for s in circulation_status(kits[1])].count(True) == 1
    stable, drifting = (kit_drift(k)[0] for k in kits)
    assert {r.model for r in stable} == {"constant"}
    # the pilot repeats every linear-bench point on both kits; on Kit B only MEMS 1 ages
    assert len(stable) == len(drifting) == 27
    mems1 = [r for r in drifting if r.label.startswith("MEMS 1,")]
    assert len(mems1) == 9 and {r.model for r in mems1} == {"linear"}
    assert all(abs(r.slope_per_day - 0.012) < 0.002 for r in mems1)
    assert {r.model for r in drifting if r not in mems1} == {"constant"}


def test_the_kits_round_has_three_kinds_two_kits_and_a_drifting_gyroscope(demo_kits_round):
    """IMU-2025-KITS (coordination/demo_kits.py): 18 points of three kinds, eight
    laboratories with plausible results, Kit B's IMU 1 angular rate drifting, analysed; made
    once (a second load adds no row)."""
    from analysis.models import KitPointFit, KitScore
    from coordination.demo_kits import KITS_ROUND_CODE, RATE_NOMINAL
    from labs.models import Handover

    out = StringIO()
    call_command("load_demo", password="demo-password-1", stdout=out)
    assert f"Kit round {KITS_ROUND_CODE}: 18 measurement points" in out.getvalue()
    before = counts()
    call_command("load_demo", stdout=StringIO())
    assert counts() == before
    c = Comparison.objects.get(code=KITS_ROUND_CODE)
    assert c.status == "analysed" and c.participants.count() == 8
    names = Laboratory.objects.filter(participations__comparison=c).values_list("name", flat=True)
    assert [n for n in names if n in c.title + c.description] == []  # codes only to the labs
    kinds = {q: c.measurement_points.filter(quantity=q).count()
             for q in ("magnitude", "phase", "angular_rate")}  # fmt: skip
    assert kinds == {"magnitude": 6, "phase": 6, "angular_rate": 6}
    results = Result.objects.filter(submission__participant__comparison=c)
    # 6 labs at all 18 points, the linear lab at 12, the curvilinear lab at 6
    assert results.count() == 6 * 18 + 12 + 6
    for r in results.select_related("measurement_point"):
        p, u = r.measurement_point, r.expanded_uncertainty
        if p.quantity == "phase":  # the filter's delay: −360° · f · 1.1 ms, lab scatter
            assert r.unit == "deg" and abs(r.value + 0.396 * p.frequency_hz) < 1.0 and u < 1
        elif p.quantity == "angular_rate":  # 1/0.07 D/(°/s) at ±2000 dps, U about 0.5 %
            assert r.unit == "D/(deg/s)" and abs(r.value / RATE_NOMINAL - 1) < 0.02
            assert 0.003 < u / r.value < 0.008
        else:
            assert r.unit == "D/(m/s^2)" and abs(r.value / 418 - 1) < 0.02
    run = c.analysis_runs.get()
    assert run.status == "succeeded"
    fits = KitPointFit.objects.filter(run=run).select_related("measurement_point__device")
    drifting = sorted((f.measurement_point.device.name, f.measurement_point.quantity, d["kit"])
                      for f in fits for d in f.drift if d["model"] == "linear")  # fmt: skip
    assert drifting == [("IMU 1", "angular_rate", "Kit B")] * 3
    # every result is linked, the phases too (docs/domain.md §14): a phase's d within 1°
    linked = KitScore.objects.filter(run=run, linked_d__isnull=False)
    assert linked.count() == results.count()
    phase_d = linked.filter(result__measurement_point__quantity="phase")
    assert phase_d.count() == 6 * 6 + 6  # the curvilinear lab measures no phase
    assert max(abs(d or 0.0) for d in phase_d.values_list("linked_d", flat=True)) < 1.0
    # Kit B is on its way back to the pilot: one hand-over not received
    assert Handover.objects.filter(kit__comparison=c, received_at__isnull=True).count() == 1
