"""A phase through the whole service (docs/domain.md §12, docs/interfaces.md §1, §3): each
laboratory uploads one CSV with a ``quantity`` column holding a magnitude and a phase of one
point (phases straddling ±180°), the coordinator accepts, the analysis runs; the stored
assigned value, D and En are those computed here by hand on the wrapped differences.  The
API and the downloads carry the kind."""

import csv
import io
import math

import pytest
from django.test import Client

from analysis.models import AssignedValue, CompatibilityMatrix, Score
from analysis.services import analysis_run_start
from labs.models import Result
from labs.services import submission_from_file, submission_transition
from proficiency.models import ComparisonStatus
from tests.factories import (
    ComparisonFactory,
    DeviceFactory,
    MeasurementPointFactory,
    MembershipFactory,
    ParticipantFactory,
    UserFactory,
)

pytestmark = pytest.mark.django_db(transaction=True)

# (code, magnitude, U, phase as written, U of the phase): the phases are 179°, −179° (written
# 181°, stored wrapped) and 178°
LABS = [("L01", 418.0, 4.0, "179", 3.0), ("L02", 420.0, 4.0, "181", 3.0),
        ("L03", 419.0, 8.0, "178", 6.0)]  # fmt: skip
HEADER = "device,axis,frequency_hz,bench,direction,quantity,sensitivity,unit,expanded_uncertainty"


def wrap(a: float) -> float:
    """The test's own wrap into (−180°, 180°], exact (no shift by 180° before the fmod)."""
    r = math.fmod(a, 360.0)
    if r > 180.0:
        r -= 360.0
    elif r <= -180.0:
        r += 360.0
    return r + 0.0


@pytest.fixture
def round_():
    comparison = ComparisonFactory.create(
        status=ComparisonStatus.OPEN, assigned_value_method="weighted_mean"
    )
    device = DeviceFactory.create(comparison=comparison, name="MEMS 1")
    points = {
        q: MeasurementPointFactory.create(
            comparison=comparison, device=device, frequency_hz=80.0, bench="curvilinear",
            direction="tangential", quantity=q,
        )
        for q in ("magnitude", "phase")
    }  # fmt: skip
    participants = {}
    for code, magnitude, u_mag, phase, u_phase in LABS:
        p = ParticipantFactory.create(comparison=comparison, code=code)
        participants[code] = p
        text = "\n".join([
            HEADER,
            f"MEMS 1,X,80,curvilinear,tangential,,{magnitude},,{u_mag}",  # blank: magnitude
            f"MEMS 1,X,80,curvilinear,tangential,phase,{phase},deg,{u_phase}",
        ])  # fmt: skip
        sub = submission_from_file(participant=p, data=text.encode(), filename="r.csv",
                                   user=None, submit=True)  # fmt: skip
        submission_transition(submission=sub, to="accepted")
    comparison.status = ComparisonStatus.CLOSED
    comparison.save(update_fields=["status"])
    return comparison, points, participants


def analysed_by_its_coordinator(comparison) -> tuple:
    """The round's succeeded run and a client signed in as its coordinator."""
    run = analysis_run_start(comparison=comparison, user=None)
    run.refresh_from_db()
    assert run.status == "succeeded", run.error
    coordinator = UserFactory.create()
    comparison.coordinators.add(coordinator)
    client = Client()
    client.force_login(coordinator)
    return run, client


def test_phase_round_assigned_value_d_and_en_by_hand(round_):
    comparison, points, _ = round_
    stored = dict(
        Result.objects.filter(measurement_point=points["phase"]).values_list(
            "submission__participant__code", "value"
        )
    )
    assert stored == {"L01": 179.0, "L02": -179.0, "L03": 178.0}  # 181° stored wrapped
    run = analysis_run_start(comparison=comparison, user=None)
    run.refresh_from_db()
    assert run.status == "succeeded", run.error

    # by hand: 179, 181, 178 on a line, u = 1.5, 1.5, 3 → weights 4/9, 4/9, 1/9
    w = [4 / 9, 4 / 9, 1 / 9]
    mean = (4 * 179 + 4 * 181 + 178) / 9
    u_pt = 1 / math.sqrt(sum(w))
    av = AssignedValue.objects.get(run=run, measurement_point=points["phase"])
    assert av.value == pytest.approx(wrap(mean), abs=1e-12)  # 179.78°, not ≈ 59°
    assert av.standard_uncertainty == pytest.approx(u_pt, rel=1e-12)
    scores = {
        s.result.submission.participant.code: s
        for s in Score.objects.filter(
            run=run, result__measurement_point=points["phase"]
        ).select_related("result__submission__participant")
    }
    for (code, _, _, _, big_u), x in zip(LABS, (179.0, -179.0, 178.0), strict=True):
        d = wrap(x - mean)
        s = scores[code]
        assert s.d == pytest.approx(d, abs=1e-12)
        u = big_u / 2
        assert s.en == pytest.approx(d / (2 * math.sqrt(u * u - u_pt * u_pt)), rel=1e-12)
        assert s.d_percent is None
    assert scores["L02"].d == pytest.approx(1.2222222222222, abs=1e-9)  # not −358.8°

    magnitude = AssignedValue.objects.get(run=run, measurement_point=points["magnitude"])
    weights = [1 / 4, 1 / 4, 1 / 16]
    expected = (418 / 4 + 420 / 4 + 419 / 16) / sum(weights)
    assert magnitude.value == pytest.approx(expected, rel=1e-13)
    # the matrices never pool a magnitude with a phase
    groups = {m.group.get("quantity") for m in CompatibilityMatrix.objects.filter(run=run)}
    assert groups == {"magnitude", "phase"}


def test_api_and_downloads_carry_the_quantity(round_):
    comparison, _, participants = round_
    user = UserFactory.create()
    lab = participants["L01"].laboratory
    MembershipFactory.create(user=user, laboratory=lab)
    client = Client()
    client.force_login(user)
    answer = client.get(f"/api/v1/comparisons/{comparison.code}/measurands/")
    assert answer.status_code == 200
    rows = answer.json()
    rows = rows["results"] if isinstance(rows, dict) else rows
    got = sorted((r["quantity"], r["unit"]) for r in rows)
    assert got == [("magnitude", "D/(m/s^2)"), ("phase", "deg")]
    template = client.get(f"/api/v1/comparisons/{comparison.code}/template.csv")
    assert template.status_code == 200
    reader = csv.DictReader(io.StringIO(template.content.decode("utf-8-sig")))
    assert sorted((r["quantity"], r["unit"]) for r in reader) == got


def test_scores_api_filters_by_quantity_and_the_scores_page_names_the_kind(round_):
    comparison, _, _ = round_
    _, client = analysed_by_its_coordinator(comparison)
    answer = client.get(f"/api/v1/comparisons/{comparison.code}/scores/?quantity=phase")
    assert answer.status_code == 200
    rows = answer.json()["results"]
    assert [(r["lab"], r["quantity"], r["d_percent"]) for r in rows] == [
        ("L01", "phase", None), ("L02", "phase", None), ("L03", "phase", None)
    ]  # fmt: skip
    assert len(client.get(f"/api/v1/comparisons/{comparison.code}/scores/").json()["results"]) == 6
    download = client.get(f"/coordinator/{comparison.code}/scores.csv")
    assert download.status_code == 200
    lines = download.content.decode("utf-8-sig").splitlines()
    assert lines[0].split(",")[5:7] == ["direction", "quantity"]
    assert sum(",phase," in line for line in lines) == 3
    page = client.get(f"/coordinator/{comparison.code}/scores/?quantity=phase")
    assert page.status_code == 200
    body = page.content.decode()
    assert body.count("tangential · sensitivity phase") == 3


def test_the_assigned_values_of_a_magnitude_and_a_phase_are_not_under_one_unit(round_):
    """The results page's assigned values: a round of magnitudes and phases has no one unit,
    so the headings say each row has its own and the phase's x_pt is in degrees (the heading
    once read the device's D/(m/s^2) over a phase)."""
    comparison, points, _ = round_
    run, client = analysed_by_its_coordinator(comparison)
    page = client.get(f"/coordinator/{comparison.code}/results/")
    assert page.status_code == 200
    body = page.content.decode()
    table = body[body.index("Assigned value per measurement point") :]
    table = table[: table.index("</table>")]
    assert "(D/(m/s^2))" not in table and table.count("(unit in each row)") == 4
    phase = AssignedValue.objects.get(run=run, measurement_point=points["phase"])
    assert 1.95 <= phase.expanded_uncertainty < 2.05  # U = 2.0°: x_pt to 0.1° (§3.1)
    shown = f"{phase.value:.1f}"
    assert f'{shown}<span class="small text-body-secondary">°</span>' in table  # no space
