"""Per-laboratory performance summary: flag counts per score type,
by device, bench and axis, the largest scores; on the participant's results page and the
coordinator's performance pages. The counts are checked against a brute-force count of
the run's score rows, the z rule (z′ where u(x_pt) > 0.3 σ_pt) against the assigned
values read separately."""

from __future__ import annotations

from collections import Counter

import pytest
from django.contrib.auth import get_user_model

from analysis.models import AssignedValue, Score
from analysis.performance import lab_performance, performance
from labs.models import Participant
from proficiency.models import Comparison
from tests.analysis.test_web_numbers import CODE, C, login


def brute(run):
    """Per lab: Counter of (dimension, level, score type, flag), max |En|, max |z used|."""
    assigned = {a.measurement_point_id: a for a in AssignedValue.objects.filter(run=run)}
    counts: dict[str, Counter] = {}
    maxima: dict[str, list[float]] = {}
    scores = Score.objects.filter(run=run).select_related(
        "result__measurement_point__device", "result__submission__participant"
    )
    for s in scores:
        p, code = s.result.measurement_point, s.result.submission.participant.code
        c = counts.setdefault(code, Counter())
        levels = {"all": "all", "device": p.device.name, "bench": p.bench, "axis": p.axis}
        for dim, level in levels.items():
            c[dim, level, "en", s.flag] += 1
            if s.z_flag:
                c[dim, level, "z", s.z_flag] += 1
        a = assigned[p.pk]
        prime = a.sigma_pt is not None and a.standard_uncertainty > 0.3 * a.sigma_pt
        z = s.z_prime if prime else s.z
        m = maxima.setdefault(code, [0.0, 0.0])
        m[0] = max(m[0], abs(s.en))
        if z is not None:
            m[1] = max(m[1], abs(z))
    return counts, maxima


def tally_counter(row, dim):
    out: Counter = Counter()
    for kind in ("en", "z"):
        t = getattr(row, kind)
        for flag, n in (("satisfactory", t.satisfactory), ("warning", t.warning),
                        ("action", t.action), ("not scored", t.not_scored)):  # fmt: skip
            if n:
                out[dim, row.level, kind, flag] = n
    return out


@pytest.fixture
def varied(run):
    """Flags of every kind: one lab gets an En action, a z warning and a z′ that counts."""
    first = Score.objects.filter(run=run).order_by("pk").select_related("result")[0]
    point = first.result.measurement_point_id
    AssignedValue.objects.filter(run=run, measurement_point_id=point).update(
        standard_uncertainty=2.0, sigma_pt=5.0
    )  # u > 0.3 σ: z′ counts at this point
    Score.objects.filter(pk=first.pk).update(en=-7.5, flag="action", z=9.0, z_prime=4.5,
                                             z_flag="action")  # fmt: skip
    second = (
        Score.objects.filter(run=run, result__submission=first.result.submission)
        .exclude(pk=first.pk)
        .order_by("pk")[0]
    )
    Score.objects.filter(pk=second.pk).update(z=2.5, z_prime=2.4, z_flag="warning")
    return run, first.result.submission.participant.code


def test_counts_and_maxima_match_a_brute_force_count_of_the_score_rows(varied):
    run, code = varied
    counts, maxima = brute(run)
    found = performance(run)
    assert [s.code for s in found] == sorted(counts)
    for summary in found:
        got = tally_counter(summary.total, "all")
        for key, _, rows in summary.breakdowns:
            for row in rows:
                got += tally_counter(row, key)
        assert got == counts[summary.code], summary.code
        assert summary.max_abs_en == pytest.approx(maxima[summary.code][0], abs=0)
        assert summary.max_abs_z == pytest.approx(maxima[summary.code][1], abs=0)
    planted = next(s for s in found if s.code == code)
    assert planted.total.en.action >= 1 and planted.total.z.warning >= 1
    # z′ (4.5) counts at the planted point, not z (9.0)
    assert planted.max_abs_en == 7.5 and planted.max_abs_z == pytest.approx(
        max(4.5, maxima[code][1]), abs=0
    )
    assert maxima[code][1] < 9.0


def test_largest_scores_of_one_lab_are_its_own_largest_first(varied):
    run, code = varied
    summary = lab_performance(run, code)
    assert summary is not None
    own = {s.pk for s in Score.objects.filter(run=run, result__submission__participant__code=code)}
    assert {s.pk for s in summary.worst_en} <= own and {s.pk for s in summary.worst_z} <= own
    ens = [abs(s.en) for s in summary.worst_en]
    assert ens[0] == 7.5 and ens == sorted(ens, reverse=True) and len(ens) == min(5, len(own))
    top = summary.worst_z[0]
    assert top.z_is_prime and top.z_used == 4.5  # type: ignore[attr-defined]  # annotations
    assert lab_performance(run, "NOSUCH") is None


def test_participant_landing_page_starts_with_its_own_summary(client, varied, demo):
    run, code = varied
    Comparison.objects.filter(pk=demo.pk).update(status="published")
    membership = Participant.objects.get(comparison=demo, code=code).laboratory.members.first()
    assert membership is not None
    member = membership.user
    client.force_login(member)
    page = client.get(f"/results/{CODE}/").content.decode()
    assert f"How <code>{code}</code> did" in page
    assert page.index('id="performance"') < page.index("Assigned values</h2>")
    summary = lab_performance(run, code)
    assert summary is not None
    t = summary.total
    assert f"{t.en.satisfactory} of {t.en.scored} results satisfactory" in page
    assert f"{t.en.action} action signal" in page and "largest |En| 7.50" in page
    assert f"{t.z.warning} warning signal" in page
    assert f"/results/{CODE}/scores/?lab={code}&amp;order=en" in page
    others = set(Participant.objects.filter(comparison=demo).values_list("code", flat=True))
    for other in others - {code}:
        assert f"How <code>{other}</code>" not in page
    # the performance pages are the coordinator's: a participant gets 404
    assert client.get(C + "performance/").status_code == 404
    assert client.get(f"{C}performance/{code}/").status_code == 404


def test_coordinator_sees_every_participant_and_each_one_as_it_sees_itself(
    client, varied, demo, django_assert_max_num_queries
):
    _, code = varied
    login(client, "coordinator")
    with django_assert_max_num_queries(20):
        page = client.get(C + "performance/").content.decode()
    codes = sorted(Participant.objects.filter(comparison=demo).values_list("code", flat=True))
    for c in codes:
        assert f"{C}performance/{c}/" in page
    assert 'href="/coordinator/IMU-2024-DEMO/performance/"' in page  # the tab
    one = client.get(f"{C}performance/{code}/")
    assert one.status_code == 200
    assert f"How <code>{code}</code> did" in one.content.decode()
    assert client.get(f"{C}performance/NOSUCH/").status_code == 404
    # another round's coordinator, and a user who coordinates nothing: 404
    other = get_user_model().objects.create_user("other-coordinator", password="x")
    Comparison.objects.create(code="OTHER-1", title="Other")
    Comparison.objects.get(code="OTHER-1").coordinators.add(other)
    client.force_login(other)
    assert client.get(C + "performance/").status_code == 404
    assert client.get(f"{C}performance/{code}/").status_code == 404
