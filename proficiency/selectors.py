"""Read-side queries of the comparison domain; each owns its joins."""

from __future__ import annotations

import datetime as dt
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import cast

from django.db.models import Count, F, QuerySet

from proficiency.models import Comparison, MeasurementPoint
from proficiency.services import enrolment_open_filter

#: Rows related to a measurement point in the points' own order (device, axis, frequency, ...).
POINT_ORDER = [f"measurement_point__{f}" for f in cast(list[str], MeasurementPoint._meta.ordering)]


def open_calls(*, now: dt.datetime | None = None) -> QuerySet[Comparison]:
    """The rounds taking applications now (docs/lifecycles.md §7), the one that closes
    first first, with their devices."""
    return (
        Comparison.objects.filter(enrolment_open_filter(now=now))
        .prefetch_related("devices")
        # a call without an end last, on every database (SQLite puts NULL first)
        .order_by(
            F("enrolment_closes").asc(nulls_last=True),
            F("submission_deadline").asc(nulls_last=True),
            "code",
        )
    )


@dataclass
class CallLevels:
    """What a round's points span: the values a laboratory may choose its scope from."""

    benches: list[str] = field(default_factory=list)
    axes: list[str] = field(default_factory=list)
    frequencies_hz: list[float] = field(default_factory=list)
    n_points: int = 0


def call_levels(comparisons: Sequence[Comparison]) -> dict[int, CallLevels]:
    """Each comparison's benches, axes and frequencies (sorted) and its number of points, by
    pk, in one query (grouped by level, not a row per point)."""
    rows = (
        MeasurementPoint.objects.filter(comparison__in=comparisons)
        .values_list("comparison_id", "bench", "axis", "frequency_hz")
        .annotate(n=Count("pk"))
        .order_by()
    )
    seen: dict[int, tuple[set[str], set[str], set[float], list[int]]] = {
        c.pk: (set(), set(), set(), [0]) for c in comparisons
    }
    for pk, bench, axis, frequency, n in rows:
        benches, axes, frequencies, count = seen[pk]
        benches.add(bench)
        axes.add(axis)
        frequencies.add(frequency)
        count[0] += n
    return {
        pk: CallLevels(sorted(b), sorted(a), sorted(f), n[0]) for pk, (b, a, f, n) in seen.items()
    }
