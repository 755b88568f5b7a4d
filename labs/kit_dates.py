"""The date at which a participant measured a travelling kit, and that date's own
uncertainty (docs/domain.md §13, §15).

Days are floats: a date stands for its noon (``toordinal() + 0.5``), a logged hand-over
for its instant (UTC); a planned slot runs from the noon of its first day to the noon of
its last.  A result's date is

* the date its laboratory states (``Result.measured_on``), with no uncertainty of its
  own; a stated date outside the laboratory's holding of the kit is kept and named;
* otherwise the midpoint of the interval over which the laboratory may have measured
  (:func:`holding`), with u_t = (end − start)/√12: the date uniform over that interval.

The pure functions come first; :func:`turns` reads a round's slots and hand-overs.
"""

from __future__ import annotations

import datetime as dt
import math
from collections import defaultdict
from collections.abc import Iterable
from dataclasses import dataclass

from labs.models import Handover, KitSlot
from proficiency.models import Comparison

__all__ = ["Turn", "date_of", "day_of", "held", "holding", "midpoint", "outside", "turns"]


def day_of(d: dt.date) -> float:
    """A date as a day number: its noon (the convention of the whole module)."""
    return d.toordinal() + 0.5


def instant_of(t: dt.datetime) -> float:
    """A logged instant as a day number (UTC)."""
    utc = t.astimezone(dt.UTC)
    return utc.toordinal() + (utc.hour * 3600 + utc.minute * 60 + utc.second) / 86400.0


def date_of(day: float) -> dt.date:
    """The date a day number falls on."""
    return dt.date.fromordinal(math.floor(day))


def holding(
    slot: tuple[float, float], arrival: float | None, departure: float | None
) -> tuple[float, float]:
    """The interval over which the participant may have measured, when it states no date.

    Start: the logged arrival, else the slot's start.  End: the logged departure, else the
    slot's end; but a late dispatch never stretches it past the slot's end, unless the kit
    also arrived after that end (it was then measured between the two).  A kit that
    arrived after its slot's end and has no logged departure: the slot's length from the
    arrival.  A log that contradicts itself (a departure before the start): the slot."""
    first, last = slot
    start = first if arrival is None else arrival
    late = arrival is not None and arrival > last
    if departure is None:
        end = start + (last - first) if late else last
    else:
        end = departure if late else min(departure, last)
    return (start, end) if end >= start else (first, last)


def held(
    slot: tuple[float, float], arrival: float | None, departure: float | None
) -> tuple[float, float]:
    """The days the participant held the kit as logged, to judge a stated date: from its
    logged arrival (else the slot's start) to its logged departure (else the slot's end, or
    the arrival if that is later); a log that contradicts itself: the slot."""
    first, last = slot
    start = first if arrival is None else arrival
    end = max(last, start) if departure is None else departure
    return (start, end) if end >= start else (first, last)


def midpoint(start: float, end: float) -> tuple[float, float]:
    """The date taken for an interval and its standard uncertainty: the midpoint, and
    (end − start)/√12, the date uniform over the interval."""
    return (start + end) / 2, (end - start) / math.sqrt(12.0)


def outside(stated: dt.date, intervals: Iterable[tuple[float, float]]) -> bool:
    """Whether no day of ``intervals`` falls on the ``stated`` date (the whole day
    [00:00, 24:00) counts: a kit that arrived at 14:00 was held on that date)."""
    day = stated.toordinal()
    return not any(day + 1 > start and day <= end for start, end in intervals)


@dataclass(frozen=True)
class Turn:
    """A participant's turn with a kit: the kit's index, the date taken when it states none
    (``day``) with its standard uncertainty (``u_day``), the days it held the kit as
    logged (``held``), the slot's first date and position (for the order of turns)."""

    kit: int
    day: float
    u_day: float
    held: tuple[float, float]
    start: dt.date
    position: int


def _handovers(comparison: Comparison) -> tuple[dict[int, float], dict[int, float]]:
    """Per slot: the logged arrival and the logged departure (day numbers)."""
    arrival: dict[int, float] = {}
    departure: dict[int, float] = {}
    moves = Handover.objects.filter(kit__comparison=comparison).values_list(
        "to_slot_id", "received_at", "from_slot_id", "dispatched_at"
    )
    for to_slot, received, from_slot, dispatched in moves:
        if to_slot and received:
            arrival[to_slot] = instant_of(received)
        if from_slot:
            departure[from_slot] = instant_of(dispatched)
    return arrival, departure


def turns(comparison: Comparison, index: dict[int, int]) -> dict[str, list[Turn]]:
    """Every participant's turns (by code), first first; ``index``: kit id -> kit index."""
    slots = list(KitSlot.objects.filter(kit__comparison=comparison)
                 .values_list("pk", "kit_id", "participant__code", "starts_on", "ends_on",
                              "position"))  # fmt: skip
    arrival, departure = _handovers(comparison)
    found: dict[str, list[Turn]] = defaultdict(list)
    for pk, kit_id, code, start, end, position in slots:
        slot = (day_of(start), day_of(end))
        came, left = arrival.get(pk), departure.get(pk)
        day, u_day = midpoint(*holding(slot, came, left))
        found[code].append(Turn(index[kit_id], day, u_day, held(slot, came, left), start,
                                position))  # fmt: skip
    for listed in found.values():
        listed.sort(key=lambda t: (t.start, t.kit, t.position))
    return dict(found)
