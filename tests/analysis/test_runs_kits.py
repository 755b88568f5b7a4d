"""Kits in the analysis run (docs/domain.md §13, §14): a round without kits, or with a kit
that does not drift, gives today's numbers exactly; a drifting kit is corrected as
numpy.polyfit says, or its u_stab added; two kits are linked to one reference exactly as
a dense weighted least-squares solve of the same observations, read back from the rows."""

from __future__ import annotations

import datetime as dt

import numpy as np
import pytest

from analysis.models import AnalysisChunk, AnalysisRun, KitPointFit, KitScore, Score
from analysis.services import analysis_chunk_execute
from labs.models import KitSlot, Result
from tests.analysis.kit_rounds import (
    START,
    add_kit,
    day_of,
    make_round,
    pilot_series,
    started,
    u_day_of,
)

pytestmark = pytest.mark.django_db


@pytest.fixture
def run_of(django_capture_on_commit_callbacks):
    return lambda comparison: started(comparison, django_capture_on_commit_callbacks)


def scores(run: AnalysisRun) -> dict[int, tuple]:
    rows = Score.objects.filter(run=run).values_list(
        "result_id", "d", "d_percent", "en", "zeta", "flag", "correlation_failed"
    )
    return {r[0]: r[1:] for r in rows}  # fmt: skip


def results(r: dict, point) -> dict[str, Result]:
    found = Result.objects.filter(measurement_point=point).select_related("submission__participant")
    return {x.submission.participant.code: x for x in found}


def turn_day(code: str, kit) -> float:
    slot = KitSlot.objects.filter(kit=kit, participant__code=code).order_by("position").first()
    assert slot is not None
    return day_of(slot.starts_on, slot.ends_on)


def turn_u(code: str, kit) -> float:
    """u_t of that date: the slot's width over √12 (no hand-over logged, no date stated)."""
    slot = KitSlot.objects.filter(kit=kit, participant__code=code).order_by("position").first()
    assert slot is not None
    return u_day_of(slot.starts_on, slot.ends_on)


def test_a_round_without_kits_scores_as_today_by_hand(run_of):
    r = make_round()
    run = run_of(r["comparison"])
    assert not KitScore.objects.filter(run=run).exists()
    assert not KitPointFit.objects.filter(run=run).exists()
    for point in r["points"]:
        res = results(r, point)
        ref = res["L0"]
        for code, x in res.items():
            s = Score.objects.get(run=run, result=x)
            assert s.d == x.value - ref.value
            if code != "L0":  # outside x_pt: U(D)² = U² + U_ref² (ISO 13528 9.7)
                assert s.en == pytest.approx(
                    s.d / np.hypot(x.expanded_uncertainty, ref.expanded_uncertainty), rel=1e-13
                )


def test_one_kit_that_does_not_drift_changes_no_score(run_of):
    r = make_round()
    before = scores(run_of(r["comparison"]))
    add_kit(r, "Kit A", r["labs"], drift=0.0)
    run = run_of(r["comparison"])
    assert scores(run) == before  # bit for bit
    kit_rows = KitScore.objects.filter(run=run)
    assert kit_rows.count() == len(before)
    assert {(k.drift_correction, k.u_drift, k.linked_d) for k in kit_rows} == {(0.0, 0.0, None)}
    fits = KitPointFit.objects.filter(run=run)
    assert [f.drift[0]["model"] for f in fits] == ["constant", "constant"]
    assert {f.reference for f in fits} == {""}  # one kit: nothing to link, D is the DoE


def _polyfit(kit, point):
    t, y, u = pilot_series(kit, point)
    b, a = np.polyfit(t - t.mean(), y, 1)  # equal u: the weighted fit is the plain one
    resid = y - (a + b * (t - t.mean()))
    chi2 = np.sum(resid**2 / u**2)
    u_b = np.sqrt(max(1.0, chi2 / (t.size - 2)) / np.sum((t - t.mean()) ** 2 / u**2))
    return b, u_b, t.mean()


def test_a_drifting_kit_is_corrected_as_polyfit_says(run_of):
    r = make_round()
    kit = add_kit(r, "Kit A", r["labs"], drift=0.02)
    run = run_of(r["comparison"])
    for point in r["points"]:
        b, u_b, t_mean = _polyfit(kit, point)
        fit = KitPointFit.objects.get(run=run, measurement_point=point)
        assert fit.drift[0]["model"] == "linear"
        assert fit.drift[0]["slope"] == pytest.approx(b, rel=1e-12)
        res = results(r, point)
        moved = {}
        for code, x in res.items():
            dt_ = turn_day(code, kit) - t_mean
            ks = KitScore.objects.get(run=run, result=x)
            assert ks.drift_correction == pytest.approx(-b * dt_, rel=1e-12)
            # u_drift² = (t − t̄)²·u²(b) + b²·u_t² (docs/domain.md §13)
            u_drift = np.sqrt((dt_ * u_b) ** 2 + (b * turn_u(code, kit)) ** 2)
            assert ks.u_drift == pytest.approx(u_drift, rel=1e-12)
            assert ks.kit_id == kit.pk and ks.linked_d is None
            moved[code] = (x.value - b * dt_, np.hypot(x.expanded_uncertainty / 2, u_drift))
        for code, x in res.items():
            s = Score.objects.get(run=run, result=x)
            # the reference corrected to the participant's date: D = x − x_ref − b(t − t_ref)
            assert s.d == pytest.approx(moved[code][0] - moved["L0"][0], abs=1e-9)
            if code != "L0":
                big_u = 2 * np.hypot(moved[code][1], moved["L0"][1])
                assert s.en == pytest.approx(s.d / big_u, rel=1e-9)


def test_a_drifting_kit_kept_constant_adds_u_stab_and_keeps_d(run_of):
    r = make_round()
    c = r["comparison"]
    c.drift_treatment = "u_stab"
    c.save(update_fields=["drift_treatment"])
    kit = add_kit(r, "Kit A", r["labs"], drift=0.02)
    run = run_of(c)
    assert run.parameters["drift_treatment"] == "u_stab"
    point = r["points"][0]
    b, _, t_mean = _polyfit(kit, point)
    res = results(r, point)
    for code, x in res.items():
        dt_ = turn_day(code, kit) - t_mean
        ks = KitScore.objects.get(run=run, result=x)
        assert ks.drift_correction == 0.0
        # u_stab(t)² + b²·u_t² (docs/domain.md §13)
        u_stab = abs(b * dt_) / np.sqrt(3)
        assert ks.u_drift == pytest.approx(np.hypot(u_stab, b * turn_u(code, kit)), rel=1e-12)
        assert Score.objects.get(run=run, result=x).d == x.value - res["L0"].value


def _dense_two_kits(r, kits, point, b_u_t):
    """The observations rebuilt from the rows: every result on its kit (the pilot's on Kit
    A, its first slot), drift-corrected; the pilot's repeats as a transfer series with a
    free offset. Unknowns K_A, K_B, b_L1..b_L6, b_T (b_pilot = 0), solved by lstsq."""
    res = results(r, point)
    codes = [f"L{i}" for i in range(1, 7)]
    y, u, rows = [], [], []

    def corrected(kit_i, t, value, u0, u_t=0.0):
        b, u_b, t_mean = b_u_t[kit_i]
        if b is None:
            return value, u0
        return value - b * (t - t_mean), np.sqrt(u0**2 + ((t - t_mean) * u_b) ** 2 + (b * u_t) ** 2)

    for code in ["L0", *codes]:
        x = res[code]
        kit_i = 0 if code in ("L0", "L1", "L2", "L3") else 1
        v, s = corrected(kit_i, turn_day(code, kits[kit_i]), x.value, x.expanded_uncertainty / 2,
                         turn_u(code, kits[kit_i]))  # fmt: skip
        col = None if code == "L0" else 2 + codes.index(code)
        y.append(v)
        u.append(s)
        rows.append((kit_i, col))
    for kit_i, kit in enumerate(kits):
        t, yy, uu = pilot_series(kit, point)
        for ti, yi, ui in zip(t, yy, uu, strict=True):
            v, s = corrected(kit_i, ti, yi, ui)
            y.append(v)
            u.append(s)
            rows.append((kit_i, 8))
    a = np.zeros((len(y), 9))
    for n, (kit_i, col) in enumerate(rows):
        a[n, kit_i] = 1
        if col is not None:
            a[n, col] = 1
    w = 1 / np.asarray(u)
    theta = np.linalg.lstsq(a * w[:, None], np.asarray(y) * w, rcond=None)[0]
    cov = np.linalg.inv((a * w[:, None]).T @ (a * w[:, None]))
    return res, codes, theta, cov


def test_two_kits_are_linked_as_a_dense_least_squares_solve(run_of):
    r = make_round()
    kit_a = add_kit(r, "Kit A", r["labs"][:3], drift=0.0)
    kit_b = add_kit(r, "Kit B", r["labs"][3:], drift=0.02, offset=0.6)
    run = run_of(r["comparison"])
    for point in r["points"]:
        fit = KitPointFit.objects.get(run=run, measurement_point=point)
        assert fit.reference == "pilot" and fit.unlinked == []
        models = {d["kit"]: d["model"] for d in fit.drift}
        assert models == {"Kit A": "constant", "Kit B": "linear"}
        res, codes, theta, cov = _dense_two_kits(
            r, [kit_a, kit_b], point, [(None, None, None), _polyfit(kit_b, point)]
        )
        values = [k["value"] for k in fit.kit_values]
        assert values == pytest.approx(theta[:2].tolist(), rel=1e-10)
        assert fit.dof == 8 - 2 and fit.chi2 is not None  # 8 repeats fix two levels K + b_T
        for j, code in enumerate(codes):
            ks = KitScore.objects.get(run=run, result=res[code])
            assert ks.linked_d == pytest.approx(theta[2 + j], abs=1e-8)
            assert ks.linked_u == pytest.approx(np.sqrt(cov[2 + j, 2 + j]), rel=1e-8)
            own = res[code].expanded_uncertainty / 2
            assert ks.linked_u is not None
            assert ks.u_link == pytest.approx(np.sqrt(ks.linked_u**2 - own**2 - ks.u_drift**2),
                                              rel=1e-6)  # fmt: skip
            assert ks.kit_id == (kit_a.pk if j < 3 else kit_b.pk)
        pilot = KitScore.objects.get(run=run, result=res["L0"])
        assert (pilot.linked_d, pilot.linked_u, pilot.kit_id) == (0.0, 0.0, kit_a.pk)


def test_against_the_weighted_mean_the_labs_doe_balance(run_of):
    r = make_round(method="weighted_mean")
    add_kit(r, "Kit A", r["labs"][:3])
    add_kit(r, "Kit B", r["labs"][3:], offset=0.6)
    run = run_of(r["comparison"])
    point = r["points"][1]
    assert KitPointFit.objects.get(run=run, measurement_point=point).reference == "weighted_mean"
    rows = KitScore.objects.filter(run=run, result__measurement_point=point).select_related(
        "result"
    )
    w = np.array([1 / (k.result.expanded_uncertainty / 2) ** 2 for k in rows])
    d = np.array([k.linked_d for k in rows])
    assert float(np.sum(w * d)) == pytest.approx(0.0, abs=1e-9)


def test_a_participant_without_a_kit_is_named_not_scored_and_a_linking_lab_warned(run_of):
    r = make_round()
    add_kit(r, "Kit A", r["labs"][:3])
    add_kit(r, "Kit B", [*r["labs"][3:5], r["labs"][0]])  # L1 holds slots on both kits
    run = run_of(r["comparison"])
    point = r["points"][0]
    fit = KitPointFit.objects.get(run=run, measurement_point=point)
    assert fit.unlinked == ["L6"]
    assert any("L6" in n for n in fit.notes)
    assert any(n.startswith("L1 holds slots on two kits: its result is taken on Kit A")
               for n in fit.notes)  # fmt: skip
    l6 = KitScore.objects.get(run=run, result__measurement_point=point,
                              result__submission__participant__code="L6")  # fmt: skip
    assert (l6.kit, l6.linked_d, l6.u_link) == (None, None, None)
    # its score against x_pt stands: only the link names it
    assert Score.objects.filter(run=run, result=l6.result).exists()


def test_a_chunk_stored_again_replaces_its_kit_rows(run_of):
    r = make_round()
    add_kit(r, "Kit A", r["labs"][:3])
    add_kit(r, "Kit B", r["labs"][3:], drift=0.02)
    run = run_of(r["comparison"])
    counts = (KitScore.objects.filter(run=run).count(), KitPointFit.objects.filter(run=run).count())
    first = sorted(KitScore.objects.filter(run=run).values_list("result_id", "linked_d"))
    AnalysisRun.objects.filter(pk=run.pk).update(status="running", chunks_done=0, progress=5)
    AnalysisChunk.objects.filter(run=run).update(done=False, token="")
    assert analysis_chunk_execute(run_id=run.pk, index=0, then_finish=False) == "running"
    assert counts == (KitScore.objects.filter(run=run).count(),
                      KitPointFit.objects.filter(run=run).count()) == (14, 2)  # fmt: skip
    assert sorted(KitScore.objects.filter(run=run).values_list("result_id", "linked_d")) == first


def test_hand_overs_logged_date_the_turn(run_of):
    """The kit arrived late and left late: the turn is dated from its logged arrival to
    the slot's end (a late dispatch does not stretch it, docs/domain.md §13)."""
    from labs.kits import handover_dispatch, handover_receive

    r = make_round()
    kit = add_kit(r, "Kit A", r["labs"], drift=0.02)
    slots = list(KitSlot.objects.filter(kit=kit).order_by("position"))
    noon = dt.time(12, tzinfo=dt.UTC)
    sent = handover_dispatch(kit=kit, from_slot=None, user=None,
                             at=dt.datetime.combine(START, noon))  # fmt: skip
    handover_receive(handover=sent, user=None, condition="good",
                     at=dt.datetime.combine(START, noon))  # fmt: skip
    sent = handover_dispatch(kit=kit, from_slot=slots[0], user=None,
                             at=dt.datetime.combine(START, noon))  # fmt: skip
    late = dt.datetime.combine(slots[1].starts_on + dt.timedelta(days=6), noon)
    handover_receive(handover=sent, user=None, condition="good", at=late)
    handover_dispatch(
        kit=kit,
        from_slot=slots[1],
        user=None,
        at=dt.datetime.combine(slots[1].ends_on, noon) + dt.timedelta(days=2),
    )
    run = run_of(r["comparison"])
    point = r["points"][0]
    b, u_b, t_mean = _polyfit(kit, point)
    held = (late.date().toordinal() + slots[1].ends_on.toordinal()) / 2 + 0.5
    width = slots[1].ends_on.toordinal() - late.date().toordinal()  # noon to noon
    ks = KitScore.objects.get(run=run, result__measurement_point=point,
                              result__submission__participant__code="L1")  # fmt: skip
    assert ks.drift_correction == pytest.approx(-b * (held - t_mean), rel=1e-12)
    u_t = width / np.sqrt(12)
    assert ks.u_drift == pytest.approx(np.hypot((held - t_mean) * u_b, b * u_t), rel=1e-12)


def test_the_demo_run_links_both_loops_and_corrects_kit_b(run_of, demo_kit_drift):
    from io import StringIO

    from django.core.management import call_command

    from proficiency.models import Comparison

    call_command("load_demo", password="demo-password-1", stdout=StringIO())
    demo = Comparison.objects.get(code="IMU-2024-DEMO")
    run = run_of(demo)
    fits = list(KitPointFit.objects.filter(run=run).select_related("measurement_point__device"))
    linear = [f for f in fits if f.measurement_point.bench == "linear"]
    assert len(linear) == 27 and {f.reference for f in linear} == {"pilot"}
    assert all(f.unlinked == [] and f.dof == 6 for f in linear)
    curvilinear = [f for f in fits if f.measurement_point.bench == "curvilinear"]
    assert {f.reference for f in curvilinear} == {""}  # the pilot measures the linear bench only
    assert all(f.notes[-1].startswith("not linked: the pilot") for f in curvilinear)
    moved = KitScore.objects.filter(run=run).exclude(drift_correction=0)
    moved_where = moved.values_list("kit__name", "result__measurement_point__device__name")
    assert set(moved_where) == {("Kit B", "MEMS 1")}
    on_b = KitScore.objects.filter(
        run=run,
        kit__name="Kit B",
        result__measurement_point__bench="linear",
        result__measurement_point__device__name="MEMS 1",
    )
    # every result of Kit B's loop at MEMS 1's nine linear points (its laboratories, drawn
    # by random code, hold four or five linear-bench results each)
    assert moved.count() == on_b.count() in (36, 45)


def test_chunks_store_the_same_kit_rows_as_one_task(run_of, settings):
    r = make_round()
    add_kit(r, "Kit A", r["labs"][:3])
    add_kit(r, "Kit B", r["labs"][3:], drift=0.02)

    def rows(run):
        return sorted(
            KitScore.objects.filter(run=run).values_list(
                "result_id",
                "kit_id",
                "drift_correction",
                "u_drift",
                "linked_d",
                "linked_u",
                "u_link",
            )
        )

    one = run_of(r["comparison"])
    settings.ANALYSIS_CHUNK_RESULTS = 7  # one point per chunk
    chunked = run_of(r["comparison"])
    assert chunked.chunks_total == 2 and one.chunks_total == 1
    assert rows(chunked) == rows(one) and len(rows(one)) == 14
    assert scores(chunked) == scores(one)
