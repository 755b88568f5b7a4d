"""A laboratory's history across rounds (docs/domain.md §4.1): joined through the laboratory
(its codes differ between rounds), published rounds only with their published run, its own
results only, the comparable points rule, RSZ and RLP against numpy, the satisfactory shares,
the pages and who may read them, and a bounded number of queries."""

from __future__ import annotations

import datetime as dt
import re
from html import escape

import numpy as np
import pytest
from django.db import connection
from django.test.utils import CaptureQueriesContext
from django.utils import timezone

from analysis.history import ComparableKey, comparable, lab_history, round_date
from analysis.history_chart import CAPTION, history_chart
from analysis.models import AnalysisRun, AssignedValue, Publication, Score
from analysis.services import analysis_run_execute, analysis_run_start
from labs.models import Membership, Participant, Result, Submission
from proficiency.models import AssignedValueMethod, Comparison, ComparisonStatus, SigmaPtMode
from tests.factories import (
    ComparisonFactory,
    DeviceFactory,
    LaboratoryFactory,
    MeasurementPointFactory,
    UserFactory,
)

pytestmark = pytest.mark.django_db
PUBLISHED = ComparisonStatus.PUBLISHED
#: (lab, bias): lab A reads high, lab B low, lab C on the nominal value
BIAS = {"A": 1.012, "B": 0.994, "C": 1.001}


def _shows(body: str, code: str) -> bool:
    """``code`` stands on the page as a word: not inside a CSRF token, a chart's path data
    or another word (a random token once held "A1")."""
    text = re.sub(r"<svg.*?</svg>|<input[^>]*>|<meta[^>]*>", " ", body, flags=re.S)
    return re.search(rf"(?<![A-Za-z0-9]){re.escape(code)}(?![A-Za-z0-9])", text) is not None


def _round(
    code: str,
    year: int,
    codes: dict[str, str],
    labs: dict,
    *,
    tolerance: float = 1.0,
    points: list[dict] | None = None,
    model: str = "ACC-1",
) -> Comparison:
    """A closed round (nominal value 418, σ_pt 1 %) whose labs report at every point."""
    c = ComparisonFactory.create(
        code=code,
        status=ComparisonStatus.CLOSED,
        submission_deadline=dt.datetime(year, 6, 30, tzinfo=dt.UTC),
        assigned_value_method=AssignedValueMethod.NOMINAL,
        sigma_pt_mode=SigmaPtMode.RELATIVE,
        sigma_pt_value=1.0,
    )
    device = DeviceFactory.create(
        comparison=c, name="MEMS 1", model=model, tolerance=tolerance, unit="D/(m/s^2)"
    )
    specs = points or [{"frequency_hz": 5.0}, {"frequency_hz": 10.0}, {"axis": "Y"}]
    made = [
        MeasurementPointFactory.create(device=spec.pop("device", device), **spec)
        for spec in [dict(s) for s in specs]
    ]
    for name, lab_code in codes.items():
        p = Participant.objects.create(comparison=c, laboratory=labs[name], code=lab_code)
        s = Submission.objects.create(participant=p, version=1, status=Submission.Status.ACCEPTED)
        for i, point in enumerate(made):
            value = 418.0 * BIAS[name] * (1 + 0.001 * i * (year - 2020))
            Result.objects.create(
                submission=s,
                measurement_point=point,
                value=value,
                unit="D/(m/s^2)",
                expanded_uncertainty=6.0,
            )
    return c


def _analyse(c: Comparison) -> AnalysisRun:
    run = analysis_run_start(comparison=c, user=None)
    assert analysis_run_execute(run_id=run.pk) == "succeeded", run.error
    return AnalysisRun.objects.get(pk=run.pk)


def _publish(c: Comparison, run: AnalysisRun) -> None:
    """Published as the publication job leaves a round: its succeeded job and the status."""
    Publication.objects.create(
        comparison=c,
        run=run,
        status=Publication.Status.SUCCEEDED,
        progress=100,
        finished_at=timezone.now(),
    )
    Comparison.objects.filter(pk=c.pk).update(status=PUBLISHED)


@pytest.fixture
def labs():
    return {name: LaboratoryFactory.create(name=f"Lab {name}") for name in BIAS}


@pytest.fixture
def rounds(labs):
    """R1 (2022, z′ counts: u(x_pt) = 2.41 > 0.3 σ_pt) and R2 (2023, z counts: tolerance
    0.1 %) published; R3 (2024) only analysed.  Lab A is A1, Q9 and Z5 in them."""
    r1 = _round("R1", 2022, {"A": "A1", "B": "B1", "C": "C1"}, labs)
    r2 = _round("R2", 2023, {"A": "Q9", "B": "B7", "C": "C3"}, labs, tolerance=0.1)
    r3 = _round("R3", 2024, {"A": "Z5", "B": "B2"}, labs)
    runs = {c.code: _analyse(c) for c in (r1, r2, r3)}
    _publish(r1, runs["R1"])
    _publish(r2, runs["R2"])
    return {"R1": r1, "R2": r2, "R3": r3, "runs": runs}


def _z_used(score: Score) -> float:
    """The z that counts, decided here from the stored assigned value (ISO 13528 9.2.1)."""
    av = AssignedValue.objects.get(run=score.run, measurement_point=score.result.measurement_point)
    assert av.sigma_pt is not None and score.z is not None and score.z_prime is not None
    return score.z_prime if av.standard_uncertainty > 0.3 * av.sigma_pt else score.z


def _scores(lab, code: str) -> list[Score]:
    return list(
        Score.objects.filter(
            run__comparison__code=code, result__submission__participant__laboratory=lab
        )
        .select_related("run", "result__measurement_point")
        .order_by("result__measurement_point__pk")
    )


def test_history_joins_the_rounds_through_the_laboratory(labs, rounds):
    history = lab_history(labs["A"])
    assert [(r.code, r.own_code) for r in history.rounds] == [("R1", "A1"), ("R2", "Q9")]
    assert [r.date.year for r in history.rounds] == [2022, 2023]
    point = next(p for p in history.points if p.key.frequency_hz == 5.0)
    assert point.key.label == "ACC-1, X, 5 Hz, linear vertical"
    assert [(e.round_code, e.own_code) for e in point.entries] == [("R1", "A1"), ("R2", "Q9")]
    expected = [
        s
        for code in ("R1", "R2")
        for s in _scores(labs["A"], code)
        if s.result.measurement_point.frequency_hz == 5.0
    ]
    assert [e.en for e in point.entries] == [s.en for s in expected]
    assert [e.z for e in point.entries] == [_z_used(s) for s in expected]
    assert [e.z_used for e in point.entries] == ["z_prime", "z"]
    assert [(e.flag, e.z_flag) for e in point.entries] == [(s.flag, s.z_flag) for s in expected]


def test_unpublished_rounds_and_other_labs_are_left_out(labs, rounds):
    history = lab_history(labs["A"])
    codes = {e.own_code for p in history.points for e in p.entries}
    assert codes == {"A1", "Q9"}  # never Z5 (R3 analysed, not published), never B's or C's
    assert sum(len(p.entries) for p in history.points) == 6  # 3 points × 2 rounds, A's own
    assert [r.code for r in lab_history(labs["C"]).rounds] == ["R1", "R2"]
    assert {e.own_code for p in lab_history(labs["C"]).points for e in p.entries} == {"C1", "C3"}
    assert lab_history(LaboratoryFactory.create()).rounds == []


def test_the_published_run_counts_not_a_later_one(labs, rounds):
    """A run that succeeded after publication (asked for while the round was analysed) is
    not the published one: the history keeps the publication's run."""
    r1 = rounds["R1"]
    Comparison.objects.filter(pk=r1.pk).update(status=ComparisonStatus.ANALYSED, sigma_pt_value=2.0)
    later = _analyse(Comparison.objects.get(pk=r1.pk))
    Comparison.objects.filter(pk=r1.pk).update(status=PUBLISHED)
    assert later.finished_at > rounds["runs"]["R1"].finished_at
    (r,) = [r for r in lab_history(labs["A"]).rounds if r.code == "R1"]
    assert r.run_id == rounds["runs"]["R1"].pk
    published = {s.result_id: _z_used(s) for s in Score.objects.filter(run=rounds["runs"]["R1"])}
    mine = [e.z for p in lab_history(labs["A"]).points for e in p.entries
            if e.round_code == "R1" and e.z is not None]  # fmt: skip
    later_z = {_z_used(s) for s in Score.objects.filter(run=later)}
    assert not later_z & set(published.values())  # σ_pt doubled: every z differs
    assert len(mine) == 3 and sorted(mine) == sorted(
        v
        for s, v in published.items()
        if Result.objects.get(pk=s).submission.participant.code == "A1"
    )


def test_combined_scores_are_rsz_and_rlp_of_the_z_that_counts(labs, rounds):
    for point in lab_history(labs["A"]).points:
        z = np.array([e.z for e in point.entries], dtype=float)
        assert point.combined is not None
        assert point.combined.n == 2
        assert point.combined.rsz == pytest.approx(z.sum() / np.sqrt(2), rel=1e-12)
        assert point.combined.rlp == pytest.approx(np.sqrt((z**2).mean()), rel=1e-12)
        value = abs(z.sum() / np.sqrt(2))
        flag = "satisfactory" if value <= 2 else "warning" if value < 3 else "action"
        assert point.combined.rsz_flag == flag
        assert point.combined.rlp_flag == (
            "satisfactory" if point.combined.rlp <= 1.5 else "action"
        )
    # lab B reads 0.6 % low, lab A 1.2 % high: signs kept, RSZ of opposite sign
    b = lab_history(labs["B"]).points[0].combined
    a = lab_history(labs["A"]).points[0].combined
    assert a is not None and b is not None and a.rsz > 0 > b.rsz


def test_satisfactory_shares_per_round_count_the_stored_flags(labs, rounds):
    for r in lab_history(labs["A"]).rounds:
        scores = _scores(labs["A"], r.code)
        assert r.en_scored == len(scores) == 3
        assert r.en_satisfactory == sum(s.flag == "satisfactory" for s in scores)
        assert r.z_scored == sum(s.z_flag != "" for s in scores) == 3
        assert r.z_satisfactory == sum(s.z_flag == "satisfactory" for s in scores)
    # lab A reads 1.2 % high: with σ_pt = 1 % its z is about 1.2 in R1 (z′ smaller) and R2
    assert [r.z_share for r in lab_history(labs["A"]).rounds] == [1.0, 1.0]


def test_until_and_within_narrow_the_rounds(labs, rounds):
    until = dt.datetime(2022, 12, 31, tzinfo=dt.UTC)
    assert [r.code for r in lab_history(labs["A"], until=until).rounds] == ["R1"]
    within = Comparison.objects.filter(code="R2")
    assert [r.code for r in lab_history(labs["A"], within=within).rounds] == ["R2"]


def test_a_report_rendered_before_publication_has_its_own_round(labs, rounds):
    """A participant report of R3 (analysed, its final reports rendered before it is
    published) asks for the history up to R3 with R3's run."""
    r3, run = rounds["R3"], rounds["runs"]["R3"]
    history = lab_history(labs["A"], until=round_date(r3), run=run)
    assert [(r.code, r.own_code, r.run_id) for r in history.rounds][-1] == ("R3", "Z5", run.pk)
    assert [r.code for r in history.rounds] == ["R1", "R2", "R3"]
    assert all(len(p.entries) == 3 for p in history.points)
    early = lab_history(labs["A"], until=round_date(rounds["R1"]), run=rounds["runs"]["R1"])
    assert [r.code for r in early.rounds] == ["R1"]


def test_comparable_points_rule(labs):
    """A different model or bench is another point; a frequency equal to 1e-6 is the same
    one; a blank model falls back to the device's name; amplitude must agree."""
    r1 = _round(
        "M1",
        2022,
        {"A": "A1", "B": "B1"},
        labs,
        points=[
            {"frequency_hz": 10.0},
            {"frequency_hz": 20.0, "bench": "curvilinear", "direction": "tangential"},
        ],
    )
    r2 = _round(
        "M2",
        2023,
        {"A": "A2", "B": "B2"},
        labs,
        points=[
            {"frequency_hz": 10.0 * (1 + 2e-7)},
            {"frequency_hz": 20.0 * (1 + 1e-5), "bench": "curvilinear", "direction": "tangential"},
            {"frequency_hz": 20.0},
        ],
    )
    other = DeviceFactory.create(comparison=r2, name="MEMS 9", model="OTHER-2")
    p = MeasurementPointFactory.create(device=other, frequency_hz=10.0)
    blank = DeviceFactory.create(comparison=r2, name="Bare 1", model="")
    q = MeasurementPointFactory.create(device=blank, frequency_hz=10.0)
    for participant in r2.participants.all():
        for point in (p, q):
            Result.objects.create(
                submission=participant.submissions.get(),
                measurement_point=point,
                value=418.0,
                unit="D/(m/s^2)",
                expanded_uncertainty=6.0,
            )
    for c in (r1, r2):
        _publish(c, _analyse(c))
    by_label = {
        pt.key.label: [e.round_code for e in pt.entries] for pt in lab_history(labs["A"]).points
    }
    assert by_label == {
        "ACC-1, X, 10 Hz, linear vertical": ["M1", "M2"],  # 10·(1 + 2e-7) Hz joins 10 Hz
        "ACC-1, X, 20 Hz, linear vertical": ["M2"],  # same frequency, another bench
        "ACC-1, X, 20 Hz, curvilinear tangential": ["M1"],
        "ACC-1, X, 20.0002 Hz, curvilinear tangential": ["M2"],  # 1e-5 apart: not the same
        "OTHER-2, X, 10 Hz, linear vertical": ["M2"],  # another model
        "Bare 1, X, 10 Hz, linear vertical": ["M2"],  # no model: the device's name
    }
    base = ComparableKey("ACC-1", "linear", "vertical", "X", 10.0, 10.0)
    assert comparable(base, ComparableKey("ACC-1", "linear", "vertical", "X", 10.0, 10.0000001))
    assert not comparable(base, ComparableKey("ACC-1", "linear", "vertical", "X", 10.0, 20.0))
    assert not comparable(base, ComparableKey("ACC-1", "linear", "vertical", "X", 10.0, None))


def test_queries_do_not_grow_with_the_rounds(labs, rounds):
    with CaptureQueriesContext(connection) as two:
        lab_history(labs["A"])
    for year in (2019, 2020):
        c = _round(f"P{year}", year, {"A": f"P{year % 100}", "B": "B"}, labs)
        _publish(c, _analyse(c))
    with CaptureQueriesContext(connection) as four:
        history = lab_history(labs["A"])
    assert len(history.rounds) == 4
    assert len(two.captured_queries) == len(four.captured_queries) <= 4


def _member(lab, username: str):
    user = UserFactory.create(username=username)
    Membership.objects.create(user=user, laboratory=lab, role=Membership.Role.STAFF)
    return user


def test_history_page_for_the_lab_members_only(client, labs, rounds):
    a, b = _member(labs["A"], "a-staff"), _member(labs["B"], "b-staff")
    client.force_login(a)
    page = client.get("/lab/history/")
    assert page.status_code == 200
    body = page.content.decode()
    assert "ACC-1, X, 5 Hz, linear vertical" in body and "<svg" in body
    assert escape(CAPTION) in body  # the trend chart's caption, the one the report prints
    assert "<code>A1</code>" in body and "<code>Q9</code>" in body and not _shows(body, "Z5")
    assert not _shows(body, "B1") and not _shows(body, "B7") and "Lab B" not in body
    dashboard = client.get("/lab/").content.decode()
    assert f"/lab/history/?lab={labs['A'].pk}" in dashboard
    client.force_login(b)
    body = client.get("/lab/history/").content.decode()
    assert "<code>B1</code>" in body and not _shows(body, "A1") and not _shows(body, "Q9")
    assert client.get(f"/lab/history/?lab={labs['A'].pk}").status_code == 404
    client.force_login(UserFactory.create(username="nobody"))
    assert client.get("/lab/history/").status_code == 404
    client.logout()
    assert client.get("/lab/history/").status_code == 302


def test_coordinator_sees_the_history_of_the_rounds_they_coordinate(client, labs, rounds):
    coordinator = UserFactory.create(username="coord-r2")
    for code in ("R2", "R3"):
        rounds[code].coordinators.add(coordinator)
    client.force_login(coordinator)
    page = client.get("/coordinator/R3/performance/Z5/")
    assert page.status_code == 200
    body = page.content.decode()
    assert "History across rounds" in body and "<code>Q9</code>" in body
    assert escape(CAPTION) in body
    assert not _shows(body, "A1")  # R1 is another coordinator's round
    client.force_login(UserFactory.create(username="root", is_superuser=True))
    body = client.get("/coordinator/R3/performance/Z5/").content.decode()
    assert "<code>A1</code>" in body and "<code>Q9</code>" in body


def test_history_chart_is_an_svg_of_the_rounds():
    svg = history_chart(["R1", "R2"], [[0.5, -1.4], [0.2]], [[1.0], []])
    assert svg.startswith("<svg") and "R1" in svg and "R2" in svg
    assert history_chart(["R1", "R2"], [[0.5, -1.4], [0.2]], [[1.0], []]) == svg


def test_the_security_world_history_leaks_nothing_of_lab_a(django_capture_on_commit_callbacks):
    """A round published without a publication job (its status set, as data from before the
    jobs) counts its latest succeeded run; lab A reads its code there, lab B never does."""
    from tests.security.world import LAB_A_CODE, LAB_A_NAME, LAB_A_VALUE_TEXTS, build_world

    world = build_world(django_capture_on_commit_callbacks)
    Comparison.objects.filter(pk=world.c1.pk).update(status=PUBLISHED)
    (r,) = lab_history(world.lab_a).rounds
    assert (r.code, r.own_code, r.run_id) == (world.c1.code, LAB_A_CODE, world.run.pk)
    own = world.client("a_staff").get("/lab/history/").content.decode()
    assert f"<code>{LAB_A_CODE}</code>" in own
    other = world.client("b_staff").get("/lab/history/").content.decode()
    assert "<code>KB2</code>" in other and "<code>KB9</code>" not in other  # C2: not published
    leaks = [t for t in (LAB_A_CODE, LAB_A_NAME, *LAB_A_VALUE_TEXTS) if t in other]
    assert leaks == []
