"""The date at which a participant measured a travelling kit (docs/domain.md §13): the
date it states, else the midpoint of its holding of the kit, a late dispatch never
stretching that holding past the slot's end; the date's own uncertainty u_t enters the
drift term as b·u_t.  Numbers against hand computations on the rows the run stored."""

from __future__ import annotations

import datetime as dt
import math

import numpy as np
import pytest

from analysis.models import KitPointFit, KitScore
from labs.kit_dates import held, holding, midpoint, outside
from labs.kits import handover_dispatch, handover_receive
from labs.models import KitSlot, Result
from tests.analysis.kit_rounds import START, add_kit, make_round, pilot_series, started

NOON = dt.time(12, tzinfo=dt.UTC)


def noon(d: dt.date) -> dt.datetime:
    return dt.datetime.combine(d, NOON)


# --- the pure rules ----------------------------------------------------------------------------

SLOT = (100.5, 110.5)  # a slot from the noon of day 100 to the noon of day 110


@pytest.mark.parametrize(
    ("arrival", "departure", "interval"),
    [
        (None, None, (100.5, 110.5)),  # nothing logged: the slot
        (103.5, 108.5, (103.5, 108.5)),  # both logged within it
        (100.5, 131.5, (100.5, 110.5)),  # a late dispatch: cut at the slot's end
        (97.25, 105.5, (97.25, 105.5)),  # it came early: from its arrival
        (104.5, None, (104.5, 110.5)),  # not sent on yet: to the slot's end
        (112.5, 118.5, (112.5, 118.5)),  # it came after the slot: arrival to departure
        (112.5, None, (112.5, 122.5)),  # ... and was never sent on: the slot's length
        (106.5, 104.5, (100.5, 110.5)),  # sent before it came: the log is not used
    ],
)
def test_the_holding_interval(arrival, departure, interval):
    assert holding(SLOT, arrival, departure) == interval


def test_the_days_held_as_logged_are_not_cut():
    assert held(SLOT, 100.5, 131.5) == (100.5, 131.5)
    assert held(SLOT, 112.5, None) == (112.5, 112.5)
    assert held(SLOT, None, None) == SLOT


def test_a_uniform_date_over_ten_days():
    t, u_t = midpoint(100.5, 110.5)
    assert t == 105.5
    assert u_t == pytest.approx(10 / math.sqrt(12), rel=1e-15)  # 2.886751… days


def test_a_stated_date_counts_its_whole_day():
    day = dt.date.fromordinal(100)
    assert not outside(day, [(100.9, 101.2)])  # arrived at 21:36 that day
    assert not outside(day, [(99.0, 100.0)])  # left at midnight, as the day began
    assert outside(day, [(101.0, 105.0)])
    assert not outside(day, [(90.0, 95.0), (99.5, 100.5)])  # any of its turns


# --- in a run ----------------------------------------------------------------------------------


@pytest.fixture
def run_of(django_capture_on_commit_callbacks):
    return lambda comparison: started(comparison, django_capture_on_commit_callbacks)


@pytest.fixture
def drifting(db):
    """The round with Kit A, drifting 0.02 a day, passed through every laboratory; its
    slots in their order."""
    r = make_round()
    r["kit"] = add_kit(r, "Kit A", r["labs"], drift=0.02)
    r["slots"] = list(KitSlot.objects.filter(kit=r["kit"]).order_by("position"))
    return r


def _states(code: str, point, on: dt.date) -> None:
    """``code`` states it measured ``point`` on ``on``."""
    Result.objects.filter(measurement_point=point, submission__participant__code=code).update(
        measured_on=on
    )


def _fit(kit, point):
    """Slope, u(slope) and t̄ of the pilot's repeats (equal u: the plain polyfit, the
    Birge ratio inflating u(b) where the scatter exceeds U/k)."""
    t, y, u = pilot_series(kit, point)
    b, a = np.polyfit(t - t.mean(), y, 1)
    chi2 = np.sum((y - a - b * (t - t.mean())) ** 2 / u**2)
    u_b = np.sqrt(max(1.0, chi2 / (t.size - 2)) / np.sum((t - t.mean()) ** 2 / u**2))
    return b, u_b, t.mean()


def _kit_score(run, point, code: str) -> KitScore:
    return KitScore.objects.get(run=run, result__measurement_point=point,
                                result__submission__participant__code=code)  # fmt: skip


def _pass_on(kit, slots, to: int, arrived: dt.datetime) -> None:
    """The kit logged from the provider through ``slots[:to]`` (each on time, at the noon
    of its slot's first day), and into ``slots[to]`` at ``arrived``."""
    sent = handover_dispatch(kit=kit, from_slot=None, user=None, at=noon(START))
    handover_receive(handover=sent, user=None, condition="good", at=noon(START))
    for i in range(1, to + 1):
        when = arrived if i == to else noon(slots[i].starts_on)
        sent = handover_dispatch(kit=kit, from_slot=slots[i - 1], user=None, at=when)
        handover_receive(handover=sent, user=None, condition="good", at=when)


@pytest.mark.django_db
def test_a_late_dispatch_does_not_move_the_date(drifting, run_of):
    """L1 received the kit on the first day of its slot and kept it three weeks past the
    slot's end: its date stays the slot's middle, u_t = 10 d/√12 (the kit's logged
    departure would have moved it ten days later and made u_t three times larger)."""
    r = drifting
    kit, slots = r["kit"], r["slots"]
    _pass_on(kit, slots, 1, noon(slots[1].starts_on))
    handover_dispatch(kit=kit, from_slot=slots[1], user=None,
                      at=noon(slots[1].ends_on + dt.timedelta(days=21)))  # fmt: skip
    run = run_of(r["comparison"])
    assert slots[1].ends_on - slots[1].starts_on == dt.timedelta(days=10)
    t = slots[1].starts_on.toordinal() + 5 + 0.5  # noon of the slot's sixth day
    u_t = 10 / math.sqrt(12)
    for point in r["points"]:
        b, u_b, t_mean = _fit(kit, point)
        ks = _kit_score(run, point, "L1")
        assert ks.measured_on == slots[1].starts_on + dt.timedelta(days=5)
        assert ks.drift_correction == pytest.approx(-b * (t - t_mean), rel=1e-12)
        # u_drift² = (t − t̄)²·u²(b) + b²·u_t²
        hand = math.sqrt((t - t_mean) ** 2 * u_b**2 + b**2 * u_t**2)
        assert ks.u_drift == pytest.approx(hand, rel=1e-12)


@pytest.mark.django_db
def test_a_kit_that_came_after_its_slot_is_dated_by_its_log(drifting, run_of):
    """L1's kit arrived four days after its slot ended and left six days later: it was
    measured between the two, t = arrival + 3 d, u_t = 6 d/√12."""
    r = drifting
    kit, slots = r["kit"], r["slots"]
    came = slots[1].ends_on + dt.timedelta(days=4)
    _pass_on(kit, slots, 1, noon(came))
    handover_dispatch(kit=kit, from_slot=slots[1], user=None,
                      at=noon(came + dt.timedelta(days=6)))  # fmt: skip
    run = run_of(r["comparison"])
    point = r["points"][0]
    b, u_b, t_mean = _fit(kit, point)
    t = came.toordinal() + 3.5
    ks = _kit_score(run, point, "L1")
    assert ks.measured_on == came + dt.timedelta(days=3)
    assert ks.drift_correction == pytest.approx(-b * (t - t_mean), rel=1e-12)
    hand = math.hypot((t - t_mean) * u_b, b * 6 / math.sqrt(12))
    assert ks.u_drift == pytest.approx(hand, rel=1e-12)


@pytest.mark.django_db
def test_a_stated_date_is_used_with_no_uncertainty_of_its_own(drifting, run_of):
    r, kit, point = drifting, drifting["kit"], drifting["points"][0]
    slot = KitSlot.objects.get(kit=kit, participant__code="L2")
    on = slot.starts_on + dt.timedelta(days=3)
    _states("L2", point, on)
    run = run_of(r["comparison"])
    b, u_b, t_mean = _fit(kit, point)
    t = on.toordinal() + 0.5
    ks = _kit_score(run, point, "L2")
    assert ks.measured_on == on
    assert ks.drift_correction == pytest.approx(-b * (t - t_mean), rel=1e-12)
    assert ks.u_drift == pytest.approx(abs(t - t_mean) * u_b, rel=1e-12)  # u_t = 0
    assert not any(
        "L2" in note for note in KitPointFit.objects.get(run=run, measurement_point=point).notes
    )
    # its other result, with no date stated, keeps its slot's middle and its u_t
    other = _kit_score(run, r["points"][1], "L2")
    b1, u_b1, t_mean1 = _fit(kit, r["points"][1])
    middle = slot.starts_on.toordinal() + 5.5
    assert other.measured_on == slot.starts_on + dt.timedelta(days=5)
    assert other.u_drift == pytest.approx(
        math.hypot((middle - t_mean1) * u_b1, b1 * 10 / math.sqrt(12)), rel=1e-12
    )


@pytest.mark.django_db
def test_a_stated_date_outside_the_holding_is_kept_and_named(drifting, run_of):
    r, kit, point = drifting, drifting["kit"], drifting["points"][1]
    slot = KitSlot.objects.get(kit=kit, participant__code="L3")
    on = slot.ends_on + dt.timedelta(days=5)
    _states("L3", point, on)
    run = run_of(r["comparison"])
    b, _, t_mean = _fit(kit, point)
    ks = _kit_score(run, point, "L3")
    assert ks.measured_on == on
    assert ks.drift_correction == pytest.approx(-b * (on.toordinal() + 0.5 - t_mean), rel=1e-12)
    notes = KitPointFit.objects.get(run=run, measurement_point=point).notes
    assert (
        f"L3 states it measured on {on}, outside its holding of Kit A ({slot.starts_on} to "
        f"{slot.ends_on}): the stated date is used"
    ) in notes
    elsewhere = KitPointFit.objects.get(run=run, measurement_point=r["points"][0]).notes
    assert not any("L3 states" in n for n in elsewhere)


@pytest.mark.django_db
def test_kept_constant_the_date_uncertainty_adds_to_u_stab(drifting, run_of):
    """u_stab treatment: u_drift² = u_stab(t)² + b²·u_t², u_stab(t) = |b·(t − t̄)|/√3."""
    r, kit = drifting, drifting["kit"]
    c = r["comparison"]
    c.drift_treatment = "u_stab"
    c.save(update_fields=["drift_treatment"])
    run = run_of(c)
    point = r["points"][0]
    b, _, t_mean = _fit(kit, point)
    slot = KitSlot.objects.get(kit=kit, participant__code="L4")
    t = slot.starts_on.toordinal() + 5.5
    ks = _kit_score(run, point, "L4")
    hand = math.sqrt((b * (t - t_mean)) ** 2 / 3 + b**2 * 100 / 12)
    assert ks.drift_correction == 0.0
    assert ks.u_drift == pytest.approx(hand, rel=1e-12)


@pytest.mark.django_db
def test_the_kits_pages_u_stab_is_the_runs_u_drift(run_of):
    """The kits page's largest u_stab (``kit_drift``) is the largest u_drift the run adds,
    kept constant, to a result on the kit, by the same rule: the pilot states a date near
    t̄; L1 received the kit four days into its slot and kept it three weeks past its end,
    so it is dated from its arrival to its slot's end, u_t = 6 d/√12, the farthest."""
    from labs.kits import kit_drift

    r = make_round()
    c = r["comparison"]
    c.drift_treatment = "u_stab"
    c.save(update_fields=["drift_treatment"])
    kit = add_kit(r, "Kit A", r["labs"], drift=0.02)
    slots = list(KitSlot.objects.filter(kit=kit).order_by("position"))
    came = slots[1].starts_on + dt.timedelta(days=4)
    _pass_on(kit, slots, 1, noon(came))
    handover_dispatch(kit=kit, from_slot=slots[1], user=None,
                      at=noon(slots[1].ends_on + dt.timedelta(days=21)))  # fmt: skip
    Result.objects.filter(submission__participant__code="L0").update(
        measured_on=START + dt.timedelta(days=60)
    )
    run = run_of(c)
    rows, notes = kit_drift(kit)
    assert notes == [] and len(rows) == len(r["points"]) == 2
    t = (came.toordinal() + slots[1].ends_on.toordinal()) / 2 + 0.5
    u_t = (slots[1].ends_on - came).days / math.sqrt(12)
    for point, row in zip(r["points"], rows, strict=True):
        u_drift = KitScore.objects.filter(run=run, result__measurement_point=point, kit=kit)
        largest = max(u_drift.values_list("u_drift", flat=True))
        assert row.u_stab_max == pytest.approx(largest, rel=1e-12)
        b, _, t_mean = _fit(kit, point)
        hand = math.hypot(b * (t - t_mean) / math.sqrt(3), b * u_t)
        assert _kit_score(run, point, "L1").u_drift == pytest.approx(hand, rel=1e-12)
        assert largest == _kit_score(run, point, "L1").u_drift
