"""Kits, their circulation plan and hand-overs (docs/domain.md §15): rows in the database,
the rules of the loop, retried requests, and what each audience is shown."""

from __future__ import annotations

import datetime as dt
import threading

import numpy as np
import pytest
from django.db import connection

from common.errors import StateConflict, ValidationFailed
from labs.kits import (
    SlotPlan,
    circulation_set,
    circulation_status,
    handover_dispatch,
    handover_receive,
    kit_create,
    kit_drift,
    kit_measurements_replace,
    own_circulation,
)
from labs.models import Handover, KitMeasurement, KitSlot
from proficiency.models import Kit, KitItem
from tests.factories import ComparisonFactory, DeviceFactory, ParticipantFactory, UserFactory

D = dt.date


@pytest.fixture
def round_(db):
    c = ComparisonFactory.create()
    devices = [DeviceFactory.create(comparison=c, name=f"MEMS {i}") for i in (1, 2)]
    pilot, *labs = (ParticipantFactory.create(comparison=c, is_reference=i == 0) for i in range(4))
    kit = kit_create(comparison_id=c.pk, name="Kit A",
                     serials={devices[0]: "A-001", devices[1]: "A-002"})  # fmt: skip
    plan = [SlotPlan(pilot, D(2027, 1, 4), D(2027, 1, 8)),
            SlotPlan(labs[0], D(2027, 1, 11), D(2027, 1, 22)),
            SlotPlan(labs[1], D(2027, 1, 25), D(2027, 2, 5)),
            SlotPlan(pilot, D(2027, 2, 8), D(2027, 2, 12))]  # fmt: skip
    circulation_set(kit=kit, plan=plan)
    return c, kit, pilot, labs, devices


def test_a_kit_holds_the_rounds_devices_by_serial(round_):
    c, kit, _, _, devices = round_
    assert list(KitItem.objects.filter(kit=kit).values_list("device__name", "serial")) == [
        ("MEMS 1", "A-001"), ("MEMS 2", "A-002")]  # fmt: skip
    other = DeviceFactory.create(comparison=ComparisonFactory.create(), name="Stranger")
    with pytest.raises(ValidationFailed, match="Stranger is not a device of this round"):
        kit_create(comparison_id=c.pk, name="Kit B", serials={other: "X"})
    assert not Kit.objects.filter(name="Kit B").exists()  # nothing stored half-way
    with pytest.raises(ValidationFailed, match="already has a kit named Kit A"):
        kit_create(comparison_id=c.pk, name="Kit A", serials={devices[0]: "X"})


def test_the_plan_is_the_loop_in_order_and_overlaps_are_refused_row_by_row(round_):
    _, kit, pilot, labs, _ = round_
    assert list(KitSlot.objects.filter(kit=kit).values_list("position", "participant")) == [
        (1, pilot.pk), (2, labs[0].pk), (3, labs[1].pk), (4, pilot.pk)]  # fmt: skip
    bad = [SlotPlan(labs[0], D(2027, 1, 10), D(2027, 1, 20)),
           SlotPlan(labs[1], D(2027, 1, 15), D(2027, 1, 12))]  # fmt: skip
    with pytest.raises(ValidationFailed) as caught:
        circulation_set(kit=kit, plan=bad)
    assert [(e["row"], e["field"]) for e in caught.value.errors] == [
        (2, "ends_on"), (2, "starts_on")]  # fmt: skip
    assert KitSlot.objects.filter(kit=kit).count() == 4  # the old plan stands
    stranger = ParticipantFactory.create()
    with pytest.raises(ValidationFailed, match="not valid") as caught:
        circulation_set(kit=kit, plan=[SlotPlan(stranger, D(2027, 1, 1), D(2027, 1, 2))])
    assert caught.value.errors[0]["field"] == "participant"


def test_the_kit_goes_round_the_loop_and_back_to_the_provider(round_):
    kit = round_[1]
    slots = list(KitSlot.objects.filter(kit=kit).order_by("position"))
    coordinator, receiver = UserFactory.create(), UserFactory.create()
    h = handover_dispatch(kit=kit, from_slot=None, user=coordinator)
    assert h.to_slot == slots[0]
    with pytest.raises(StateConflict, match="not been received"):
        handover_dispatch(kit=kit, from_slot=slots[0], user=receiver)
    for i, slot in enumerate(slots):
        arrival = Handover.objects.get(to_slot=slot)
        handover_receive(handover=arrival, user=receiver, condition="good")
        out = handover_dispatch(kit=kit, from_slot=slot, user=receiver, carrier_note="DHL 123")
        assert out.to_slot == (slots[i + 1] if i + 1 < len(slots) else None)
    back = Handover.objects.get(kit=kit, to_slot__isnull=True)
    assert back.from_slot == slots[-1]
    assert Handover.objects.filter(kit=kit).count() == 5
    with pytest.raises(StateConflict, match="already circulating"):
        circulation_set(kit=kit, plan=[])


def test_a_retried_dispatch_or_receipt_answers_the_same_row(round_):
    _, kit, *_ = round_
    first = handover_dispatch(kit=kit, from_slot=None, user=None)
    assert handover_dispatch(kit=kit, from_slot=None, user=None).pk == first.pk
    got = handover_receive(handover=first, user=None, condition="damaged", note="cable torn")
    again = handover_receive(handover=first, user=None, condition="damaged", note="cable torn")
    assert again.pk == got.pk and again.received_at == got.received_at
    with pytest.raises(StateConflict, match="already logged"):
        handover_receive(handover=first, user=None, condition="good")
    assert Handover.objects.get(pk=first.pk).condition == "damaged"


def test_a_damaged_arrival_needs_a_note_and_a_condition_from_the_list(round_):
    _, kit, *_ = round_
    h = handover_dispatch(kit=kit, from_slot=None, user=None)
    with pytest.raises(ValidationFailed, match="what is damaged"):
        handover_receive(handover=h, user=None, condition="damaged")
    with pytest.raises(ValidationFailed, match="must be one of"):
        handover_receive(handover=h, user=None, condition="fine")
    with pytest.raises(ValidationFailed, match="control characters"):
        handover_receive(handover=h, user=None, condition="incomplete", note="box\x00open")
    assert Handover.objects.get(pk=h.pk).received_at is None


def test_a_laboratory_sees_its_own_slot_only(round_, django_assert_max_num_queries):
    _, kit, pilot, labs, _ = round_
    h = handover_dispatch(kit=kit, from_slot=None, user=None)
    handover_receive(handover=h, user=None, condition="good")
    first = KitSlot.objects.get(kit=kit, position=1)
    handover_dispatch(kit=kit, from_slot=first, user=None)
    with django_assert_max_num_queries(3):
        mine = own_circulation(labs[0])
    assert [(o.slot.position, o.may_receive, o.may_dispatch) for o in mine] == [(2, True, False)]
    assert [i.serial for i in mine[0].items] == ["A-001", "A-002"]
    # the pilot has two slots, the second not reached yet
    assert [(o.slot.position, o.arrival is not None) for o in own_circulation(pilot)] == [
        (1, True), (4, False)]  # fmt: skip
    assert own_circulation(ParticipantFactory.create()) == []


def test_the_coordinator_sees_late_overdue_and_damaged(round_):
    _, kit, *_ = round_
    h = handover_dispatch(kit=kit, from_slot=None, user=None)
    handover_receive(handover=h, user=None, condition="good",
                     at=dt.datetime(2027, 1, 6, 9, tzinfo=dt.UTC))  # fmt: skip
    first = KitSlot.objects.get(kit=kit, position=1)
    out = handover_dispatch(kit=kit, from_slot=first, user=None,
                            at=dt.datetime(2027, 1, 8, 16, tzinfo=dt.UTC))  # fmt: skip
    handover_receive(handover=out, user=None, condition="incomplete", note="MEMS 2 missing",
                     at=dt.datetime(2027, 1, 11, 8, tzinfo=dt.UTC))  # fmt: skip
    status = circulation_status(kit, today=D(2027, 1, 27))
    assert [(s.slot.position, s.late, s.overdue, s.damaged) for s in status] == [
        (1, True, False, False),   # arrived on the 6th for a slot from the 4th
        (2, False, True, True),    # on time, incomplete, not sent on by the 22nd
        (3, True, False, False),   # should have arrived by the 25th
        (4, False, False, False),
    ]  # fmt: skip


@pytest.mark.django_db(transaction=True)
def test_two_dispatches_at_once_make_one_handover(needs_postgres):
    c = ComparisonFactory.create()
    d = DeviceFactory.create(comparison=c)
    p = ParticipantFactory.create(comparison=c)
    kit = kit_create(comparison_id=c.pk, name="Kit A", serials={d: "1"})
    circulation_set(kit=kit, plan=[SlotPlan(p, D(2027, 1, 1), D(2027, 1, 2))])
    barrier, got = threading.Barrier(2), []

    def send():
        try:
            barrier.wait()
            got.append(handover_dispatch(kit=kit, from_slot=None, user=None).pk)
        finally:
            connection.close()

    threads = [threading.Thread(target=send) for _ in range(2)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert len(got) == 2 and got[0] == got[1]
    assert Handover.objects.filter(kit=kit).count() == 1


HEADER = "device,axis,frequency_hz,bench,direction,measured_on,sensitivity,expanded_uncertainty\n"


def _points(c, device):
    from tests.factories import MeasurementPointFactory

    return [MeasurementPointFactory.create(device=device, frequency_hz=f) for f in (5.0, 10.0)]


def test_the_pilots_repeats_give_each_points_drift(round_):
    """MEMS 1 at 5 Hz drifts by 0.01 per day; at 10 Hz it scatters about a constant."""
    c, kit, _, _, devices = round_
    _points(c, devices[0])
    days = [D(2027, 1, 4), D(2027, 1, 25), D(2027, 2, 15), D(2027, 3, 8)]
    drift = [418.0 + 0.01 * (d - days[0]).days for d in days]
    flat = [418.3, 418.28, 418.31, 418.29]
    lines = [f"MEMS 1,X,5,linear,vertical,{d},{v},0.01" for d, v in zip(days, drift, strict=True)]
    lines += [f"MEMS 1,X,10,linear,vertical,{d},{v},0.04" for d, v in zip(days, flat, strict=True)]
    assert kit_measurements_replace(kit=kit, text=HEADER + "\n".join(lines)) == 8
    rows, notes = kit_drift(kit)
    assert notes == [] and [r.model for r in rows] == ["linear", "constant"]
    t = np.array([(d - days[0]).days for d in days], dtype=float)
    slope = np.polyfit(t, drift, 1, w=np.full(4, 1 / 0.005))[0]
    assert rows[0].slope_per_day == pytest.approx(slope) == pytest.approx(0.01)
    # every holder's result is dated, the pilot's too (its first slot, 4–8 Jan: midpoint
    # 6 Jan, u_t = 4 d/√12), the farthest from t̄ = 31.5 days after 4 Jan: u_stab² + b²·u_t²
    mid, u_t = 2.0, 4 / np.sqrt(12)
    assert rows[0].u_stab_max == pytest.approx(
        np.hypot(0.01 * (31.5 - mid) / np.sqrt(3), 0.01 * u_t), rel=1e-9
    )
    assert rows[1].u_stab_max == 0.0 and rows[1].value == pytest.approx(np.mean(flat))


def test_bad_pilot_lines_are_named_and_nothing_is_stored(round_):
    c, kit, _, _, devices = round_
    _points(c, devices[0])
    text = HEADER + "MEMS 1,X,5,linear,vertical,2027-01-04,418.1,0.02\n" \
        "MEMS 1,X,7,linear,vertical,2027-01-04,418.1,0.02\n" \
        "MEMS 1,X,5,linear,vertical,Jan 5,418.1,0.02\n" \
        "MEMS 1,X,5,linear,vertical,2027-01-06,nan,0.02\n"  # fmt: skip
    with pytest.raises(ValidationFailed) as caught:
        kit_measurements_replace(kit=kit, text=text)
    assert [(e["row"], e["message"][:30]) for e in caught.value.errors] == [
        (3, "MEMS 1, X, 7 Hz, linear vertic"), (4, "measured_on must be a date YYY"),
        (5, "sensitivity must be finite and")]  # fmt: skip
    assert not KitMeasurement.objects.exists()
    with pytest.raises(ValidationFailed, match="first line must name the columns"):
        kit_measurements_replace(kit=kit, text="a,b\n1,2")
    kit_measurements_replace(
        kit=kit, text=HEADER + "MEMS 1,X,5,linear,vertical,2027-01-04,418.1,0.02"
    )
    assert kit_drift(kit) == (
        [],
        ["MEMS 1, X, 5 Hz, linear vertical: measured on one date only, no drift can be judged"],
    )


def test_pilot_columns_by_name_in_any_order_with_a_points_amplitude(round_):
    from tests.factories import MeasurementPointFactory

    _, kit, _, _, devices = round_
    MeasurementPointFactory.create(device=devices[0], frequency_hz=5.0, amplitude_m_s2=14.77,
                                   bench="curvilinear", direction="radial")  # fmt: skip
    text = ("measured_on,sensitivity,expanded_uncertainty,coverage_factor,device,axis,"
            "frequency_hz,bench,direction,amplitude_m_s2\n"
            "2027-01-04,418.1,0.02,2,MEMS 1,X,5,curvilinear,radial,14.77\n"
            "2027-02-04,418.2,0.02,,MEMS 1,X,5,curvilinear,radial,14.77\n")  # fmt: skip
    assert kit_measurements_replace(kit=kit, text=text) == 2
    assert sorted(KitMeasurement.objects.values_list("value", "coverage_factor")) == [
        (418.1, 2.0), (418.2, 2.0)]  # fmt: skip
    with pytest.raises(ValidationFailed, match="missing: measured_on"):
        kit_measurements_replace(kit=kit, text=text.replace("measured_on", "when"))


def test_hostile_pilot_csv_is_refused_with_a_reason_and_nothing_stored(round_):
    _, kit, _, _, devices = round_
    _points(None, devices[0])
    good = "MEMS 1,X,5,linear,vertical,2027-01-04,418.1,0.02"
    for text, reason in (
        (HEADER + "MEMS 1,X," + "9" * 200_000 + ",linear,vertical,2027-01-04,1,1", "readable CSV"),
        (HEADER + good.replace("MEMS 1", "MEMS\x001"), "not a measurement point"),
        (HEADER + good + ",\x00", "more fields than the header"),
        (HEADER + good + "," * 1_000_000, "more fields than the header"),  # a million cells
        (HEADER + good.replace("418.1", "1e400"), "sensitivity must be finite"),
        (HEADER + good.replace("0.02", "-0.02"), "expanded_uncertainty must be finite and > 0"),
        (HEADER + good.replace("2027-01-04", "2027-02-30"), "measured_on must be a date"),
    ):
        with pytest.raises(ValidationFailed) as caught:
            kit_measurements_replace(kit=kit, text=text)
        said = caught.value.message + " ".join(e["message"] for e in caught.value.errors)
        assert reason in said, (text[:60], said)
    assert not KitMeasurement.objects.exists()
