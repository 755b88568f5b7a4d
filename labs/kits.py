"""Travelling kits, their circulation plan and hand-overs (docs/domain.md §15).

Services change state atomically and by the rules of the circulation; who may call them
(the holder's laboratory, the coordinator) is checked by the views, as everywhere else.
Selectors give each audience its own view: a laboratory sees its own slots and the
hand-overs into and out of them, never who holds the kit before or after it; the
coordinator sees the whole plan with what is late, overdue or arrived damaged.
"""

from __future__ import annotations

import datetime as dt
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass

from django.contrib.auth.models import User
from django.core.files.base import File
from django.db import IntegrityError, transaction
from django.db.models import Q
from django.utils import timezone

from common.errors import StateConflict, ValidationFailed

# the kit's measurements (the pilot's repeats, the linking laboratories') and its drift
# live in labs.kit_measurements; named here too, where the kits' services are looked for
from labs.kit_measurements import MEASUREMENT_COLUMNS as MEASUREMENT_COLUMNS
from labs.kit_measurements import DriftRow as DriftRow
from labs.kit_measurements import kit_drift as kit_drift
from labs.kit_measurements import kit_linking_counts as kit_linking_counts
from labs.kit_measurements import kit_measurements_replace as kit_measurements_replace
from labs.models import Handover, KitSlot, Participant
from proficiency.models import Device, Kit, KitItem

MAX_SLOTS = 1000
MAX_TEXT = 1000


@dataclass(frozen=True)
class SlotPlan:
    """One line of a kit's circulation plan, in loop order."""

    participant: Participant
    starts_on: dt.date
    ends_on: dt.date


def _text(value: str, field: str, limit: int) -> str:
    text = value.strip()
    if len(text) > limit:
        raise ValidationFailed(f"{field} is longer than {limit} characters.")
    if any(ord(c) < 32 and c not in "\t\n\r" for c in text):
        raise ValidationFailed(f"{field} contains control characters.")
    return text


@transaction.atomic
def kit_create(*, comparison_id: int, name: str, serials: Mapping[Device, str]) -> Kit:
    """A kit of the round holding one copy of each given device, by serial number."""
    label = _text(name, "The kit's name", 40)
    if not label:
        raise ValidationFailed("A kit needs a name.")
    if not serials:
        raise ValidationFailed(f"Kit {label} holds no device.")
    foreign = [d.name for d in serials if d.comparison_id != comparison_id]
    if foreign:
        raise ValidationFailed(f"{', '.join(foreign)} is not a device of this round.")
    if Kit.objects.filter(comparison_id=comparison_id, name=label).exists():
        raise ValidationFailed(f"The round already has a kit named {label}.")
    kit = Kit.objects.create(comparison_id=comparison_id, name=label)
    items = []
    for device, serial in serials.items():
        text = _text(serial, f"The serial of {device.name}", 80)
        if not text:
            raise ValidationFailed(f"{device.name} in {label} needs its serial number.")
        items.append(KitItem(kit=kit, device=device, serial=text))
    KitItem.objects.bulk_create(items)
    return kit


def _check_plan(kit: Kit, plan: Sequence[SlotPlan]) -> None:
    if len(plan) > MAX_SLOTS:
        raise ValidationFailed(f"A loop holds at most {MAX_SLOTS} slots, got {len(plan)}.")
    errors = []
    for i, slot in enumerate(plan, start=1):
        if slot.participant.comparison_id != kit.comparison_id:
            message = f"{slot.participant.code} is not a participant of this round"
            errors.append({"row": i, "field": "participant", "message": message})
        if slot.ends_on < slot.starts_on:
            errors.append({"row": i, "field": "ends_on", "message": "ends before it starts"})
        if i > 1 and slot.starts_on < plan[i - 2].ends_on:
            message = f"starts before slot {i - 1} ends ({plan[i - 2].ends_on})"
            errors.append({"row": i, "field": "starts_on", "message": message})
    if errors:
        raise ValidationFailed(f"The circulation plan of {kit.name} is not valid.", errors=errors)


@transaction.atomic
def circulation_set(*, kit: Kit, plan: Sequence[SlotPlan]) -> list[KitSlot]:
    """Replace a kit's circulation plan (loop order = the order of ``plan``); refused once
    the kit has left the provider, when the plan is what the hand-overs follow."""
    Kit.objects.select_for_update().get(pk=kit.pk)
    if Handover.objects.filter(kit=kit).exists():
        raise StateConflict(f"{kit.name} is already circulating: its plan can no longer change.")
    _check_plan(kit, plan)
    KitSlot.objects.filter(kit=kit).delete()
    return KitSlot.objects.bulk_create(
        KitSlot(kit=kit, participant=s.participant, position=i, starts_on=s.starts_on,
                ends_on=s.ends_on)
        for i, s in enumerate(plan, start=1)
    )  # fmt: skip


def next_slot(kit: Kit, after: KitSlot | None) -> KitSlot | None:
    """The slot that receives the kit after ``after`` (the first one after the provider),
    None when the kit goes back to the provider."""
    slots = KitSlot.objects.filter(kit=kit).order_by("position")
    if after is not None:
        slots = slots.filter(position__gt=after.position)
    return slots.first()


@transaction.atomic
def handover_dispatch(
    *, kit: Kit, from_slot: KitSlot | None, user: User | None, carrier_note: str = "",
    at: dt.datetime | None = None,
) -> Handover:  # fmt: skip
    """The holder of ``from_slot`` (None: the provider) sends the kit on to the next slot.
    Sending again what was already sent answers the same hand-over (a retried request);
    a holder who has not received the kit cannot send it."""
    Kit.objects.select_for_update().get(pk=kit.pk)
    if from_slot is not None and from_slot.kit_id != kit.pk:
        raise ValidationFailed(f"That slot is not one of {kit.name}'s.")
    sent = Handover.objects.filter(kit=kit, from_slot=from_slot)  # None: the provider's
    if (done := sent.first()) is not None:
        return done
    arrival = None  # the provider's first dispatch follows no arrival
    if from_slot is not None:
        arrival = Handover.objects.filter(to_slot=from_slot).first()
        if arrival is None or arrival.received_at is None:
            raise StateConflict(f"{kit.name} has not been received in this slot yet.")
    to = next_slot(kit, from_slot)
    if from_slot is None and to is None:
        raise StateConflict(f"{kit.name} has no circulation plan yet.")
    note = _text(carrier_note, "The carrier note", 500)
    when = at or timezone.now()
    _not_before(when, arrival.received_at if arrival else None, "sent on", "its arrival")
    try:
        with transaction.atomic():
            return Handover.objects.create(
                kit=kit, from_slot=from_slot, to_slot=to, dispatched_at=when,
                dispatched_by=user, carrier_note=note,
            )  # fmt: skip
    except IntegrityError:  # another request sent it a moment ago
        raise StateConflict(f"{kit.name} was just sent from this slot.") from None


def _not_before(when: dt.datetime, earlier: dt.datetime | None, what: str, since: str) -> None:
    """A hand-over's times follow the kit: it arrives after it was sent and is sent on
    after it arrived (a time given by the caller, or a clock set back, could say otherwise)."""
    if earlier is not None and when < earlier:
        raise ValidationFailed(
            f"The kit cannot be {what} at {when.astimezone(dt.UTC):%Y-%m-%d %H:%M} UTC, before "
            f"{since} ({earlier.astimezone(dt.UTC):%Y-%m-%d %H:%M} UTC).",
            errors=[{"field": "at", "message": f"before {since}"}],
        )


@transaction.atomic
def handover_receive(
    *, handover: Handover, user: User | None, condition: str, note: str = "",
    photo: File | None = None, at: dt.datetime | None = None,
) -> Handover:  # fmt: skip
    """The receiver logs the kit's arrival and its condition. The same receipt sent again
    answers it unchanged; a different one is refused (the first receipt stands)."""
    h = Handover.objects.select_for_update().get(pk=handover.pk)
    if condition not in Handover.Condition.values:
        raise ValidationFailed(
            f"The condition must be one of {', '.join(Handover.Condition.values)}.",
            errors=[{"field": "condition", "message": f"unknown condition {condition!r}"}],
        )
    text = _text(note, "The condition note", MAX_TEXT)
    if condition != Handover.Condition.GOOD and not text:
        required = [{"field": "condition_note", "message": "required"}]
        raise ValidationFailed("Say what is damaged or missing.", errors=required)
    if h.received_at is not None:
        if (h.condition, h.condition_note) == (condition, text):
            return h
        raise StateConflict("This arrival was already logged; ask the coordinator to correct it.")
    when = at or timezone.now()
    _not_before(when, h.dispatched_at, "received", "it was sent")
    h.received_at, h.received_by = when, user
    h.condition, h.condition_note = condition, text
    if photo is not None:
        h.photo = photo
    h.save()
    return h


# --- what each audience sees --------------------------------------------------------------


@dataclass(frozen=True)
class OwnSlot:
    """A laboratory's own turn with a kit: the kit's items, its dates, the arrival and the
    departure — but not the holders before or after it."""

    slot: KitSlot
    items: list[KitItem]
    arrival: Handover | None
    departure: Handover | None

    @property
    def may_receive(self) -> bool:
        return self.arrival is not None and self.arrival.received_at is None

    @property
    def may_dispatch(self) -> bool:
        return (self.arrival is not None and self.arrival.received_at is not None
                and self.departure is None)  # fmt: skip


def _by_slot(moves: Iterable[Handover]) -> tuple[dict[int, Handover], dict[int, Handover]]:
    """Hand-overs by the slot they arrive at and by the slot they leave from."""
    arrival: dict[int, Handover] = {}
    departure: dict[int, Handover] = {}
    for h in moves:
        if h.to_slot_id:
            arrival[h.to_slot_id] = h
        if h.from_slot_id:
            departure[h.from_slot_id] = h
    return arrival, departure


def own_circulation(participant: Participant) -> list[OwnSlot]:
    """The participant's own slots, in date order (three queries whatever their number)."""
    slots = list(KitSlot.objects.filter(participant=participant).select_related("kit")
                 .order_by("starts_on", "pk"))  # fmt: skip
    kit_ids = {s.kit_id for s in slots}
    items: dict[int, list[KitItem]] = {}
    for item in KitItem.objects.filter(kit_id__in=kit_ids).select_related("device"):
        items.setdefault(item.kit_id, []).append(item)
    arrival, departure = _by_slot(
        Handover.objects.filter(Q(to_slot__in=slots) | Q(from_slot__in=slots))
    )
    return [OwnSlot(s, items.get(s.kit_id, []), arrival.get(s.pk), departure.get(s.pk))
            for s in slots]  # fmt: skip


@dataclass(frozen=True)
class SlotStatus:
    """One slot of the plan as the coordinator reads it."""

    slot: KitSlot
    arrival: Handover | None
    departure: Handover | None
    late: bool  # the kit arrived after the slot started, or has not arrived and should have
    overdue: bool  # the slot has ended and the kit has not been sent on
    damaged: bool  # it arrived damaged or incomplete


def circulation_status(kit: Kit, today: dt.date | None = None) -> list[SlotStatus]:
    """Every slot of the kit with its hand-overs and what needs the coordinator's eye."""
    day = today or timezone.localdate()
    slots = list(KitSlot.objects.filter(kit=kit).select_related("participant__laboratory")
                 .order_by("position"))  # fmt: skip
    arrival, departure = _by_slot(Handover.objects.filter(kit=kit))
    out = []
    for s in slots:
        a, d = arrival.get(s.pk), departure.get(s.pk)
        received = a.received_at.date() if a and a.received_at else None
        late = (received > s.starts_on) if received else day > s.starts_on
        out.append(SlotStatus(
            slot=s, arrival=a, departure=d, late=late,
            overdue=d is None and day > s.ends_on,
            damaged=bool(a and a.condition in (Handover.Condition.DAMAGED,
                                               Handover.Condition.INCOMPLETE)),
        ))  # fmt: skip
    return out
