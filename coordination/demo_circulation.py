"""Demo data: the demo round's two kits (docs/domain.md §15), and the hand-overs every
kit of the demo goes through (coordination/demo_kits.py circulates its kits with
:func:`circulate` too).
"""

from __future__ import annotations

import datetime as dt
import zlib
from collections.abc import Sequence

import numpy as np

from coordination.demo_results import NOMINAL
from labs.kits import (
    SlotPlan,
    circulation_set,
    handover_dispatch,
    handover_receive,
    kit_create,
    kit_measurements_replace,
)
from labs.models import KitSlot, Participant, Result, Submission
from proficiency.models import Comparison, Kit, MeasurementPoint

#: what the fourth holder of the second kit found on its arrival
DAMAGE = "MEMS 2: connector bent in transport"


def round_kits(
    comparison: Comparison, kits: Sequence[tuple[str, str, float]], pilot_lab: str
) -> None:
    """``kits`` (name, serial prefix, drift of the pilot's MEMS 1 repeats per day) circulated
    in loops in the first half of 2024, the laboratory ``pilot_lab`` as pilot before,
    between and after (docs/domain.md §15): every hand-over logged, one arrival damaged, and
    the pilot's repeats of MEMS 1 on the linear bench showing a drifting kit (§13). Made
    once; a round that has kits keeps them."""
    if comparison.kits.exists():
        return
    participants = list(comparison.participants.select_related("laboratory").order_by("code"))
    pilot = next(p for p in participants if p.laboratory.name == pilot_lab)
    others = [p for p in participants if p != pilot]
    devices = list(comparison.devices.order_by("name"))
    points = list(comparison.measurement_points.filter(bench="linear")
                  .select_related("device").order_by("pk"))  # fmt: skip
    for index, (name, prefix, drift) in enumerate(kits):
        serials = {d: f"{prefix}-{i:03d}" for i, d in enumerate(devices, 1)}
        kit = kit_create(comparison_id=comparison.pk, name=name, serials=serials)
        day = dt.date(2024, 1, 8)
        plan = [SlotPlan(pilot, day, day + dt.timedelta(days=4))]
        loop = others[index::2]
        for i, p in enumerate(loop):
            day += dt.timedelta(days=14)
            plan.append(SlotPlan(p, day, day + dt.timedelta(days=10)))
            if i % 2 == 1 and i < len(loop) - 1:  # the pilot again, every two laboratories
                day += dt.timedelta(days=14)
                plan.append(SlotPlan(pilot, day, day + dt.timedelta(days=4)))
        day += dt.timedelta(days=14)
        plan.append(SlotPlan(pilot, day, day + dt.timedelta(days=4)))
        slots = circulation_set(kit=kit, plan=plan)
        circulate(kit, slots, damaged=(4, DAMAGE) if index == 1 else None)
        _pilot_repeats(kit, points, [s for s in slots if s.participant_id == pilot.pk], drift,
                       _own_values(pilot))  # fmt: skip


def noon(day: dt.date) -> dt.datetime:
    return dt.datetime.combine(day, dt.time(12), tzinfo=dt.UTC)


def circulate(
    kit: Kit, slots: list[KitSlot], *, damaged: tuple[int, str] | None = None,
    pending: int | None = None,
) -> None:  # fmt: skip
    """The hand-overs of a loop: the kit sent two days before the first slot, each holder
    receiving it on its slot's first day and sending it on at its end, and its return
    received two days after the last slot (at noon, UTC).  ``damaged``: the slot (from 1)
    whose holder found the kit damaged, with the holder's note; ``pending``: the slot (from
    1) the kit is on its way to, its arrival and everything after it not logged yet."""
    sent = handover_dispatch(kit=kit, from_slot=None, user=None, carrier_note="courier",
                             at=noon(slots[0].starts_on - dt.timedelta(days=2)))  # fmt: skip
    for i, slot in enumerate(slots, 1):
        if i == pending:
            return
        broken = damaged is not None and i == damaged[0]
        handover_receive(handover=sent, user=None, condition="damaged" if broken else "good",
                         note=damaged[1] if damaged and broken else "",
                         at=noon(slot.starts_on))  # fmt: skip
        sent = handover_dispatch(kit=kit, from_slot=slot, user=None, carrier_note="courier",
                                 at=noon(slot.ends_on))  # fmt: skip
    handover_receive(handover=sent, user=None, condition="good",
                     at=noon(slots[-1].ends_on + dt.timedelta(days=2)))  # fmt: skip


def _own_values(participant: Participant) -> dict[int, float]:
    """The participant's accepted results by point id."""
    rows = Result.objects.filter(submission__participant=participant,
                                 submission__status=Submission.Status.ACCEPTED)  # fmt: skip
    return dict(rows.values_list("measurement_point_id", "value"))


def _pilot_repeats(kit: Kit, points: list[MeasurementPoint], slots: list[KitSlot],
                   drift: float, own: dict[int, float]) -> None:  # fmt: skip
    """The pilot's measurement of each linear-bench point in each of its slots: its own
    result there (the nominal value where it has none) with a small scatter, plus, on MEMS
    1, ``drift`` per day since the first slot (Kit B's MEMS 1 ages)."""
    rng = np.random.default_rng(zlib.crc32(kit.name.encode()))
    first = slots[0].starts_on
    lines = ["device,axis,frequency_hz,bench,direction,amplitude_m_s2,measured_on,"
             "sensitivity,expanded_uncertainty"]  # fmt: skip
    for p in points:
        amplitude = "" if p.amplitude_m_s2 is None else repr(p.amplitude_m_s2)
        rate = drift if p.device.name == "MEMS 1" else 0.0
        for slot in slots:
            base = own.get(p.pk, NOMINAL + 1.5)
            value = base + rate * (slot.starts_on - first).days + rng.normal(0, 0.03)
            lines.append(f"{p.device.name},{p.axis},{p.frequency_hz!r},{p.bench},{p.direction},"
                         f"{amplitude},{slot.starts_on},{value:.4f},0.08")  # fmt: skip
    kit_measurements_replace(kit=kit, text="\n".join(lines))
