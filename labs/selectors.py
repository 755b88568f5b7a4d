"""Read-side queries of the laboratory side; each owns its joins."""

from __future__ import annotations

from dataclasses import dataclass

from django.contrib.auth.models import AnonymousUser, User
from django.db.models import Count, Max, OuterRef, QuerySet, Subquery

from common.errors import NotVisible
from common.points import POINT_LOOKUPS
from common.rows import JoinedQuery, ModelColumns
from labs.importers import COLUMNS, PointKey, ResultRow, TableContext, write_table
from labs.models import Laboratory, Participant, Result, Submission
from proficiency.models import Comparison, MeasurementPoint


def current_submissions(
    comparison: Comparison, statuses: tuple[str, ...] = (Submission.Status.ACCEPTED,)
) -> QuerySet[Submission]:
    """Per participant, its latest version among ``statuses`` (older versions are history)."""
    latest = (
        Submission.objects.filter(participant=OuterRef("participant"), status__in=statuses)
        .values("participant")
        .annotate(v=Max("version"))
        .values("v")
    )
    return Submission.objects.filter(
        participant__comparison=comparison, status__in=statuses, version=Subquery(latest)
    )


def comparison_result_rows(
    comparison: Comparison, statuses: tuple[str, ...] = (Submission.Status.ACCEPTED,)
) -> list[ResultRow]:
    """The current results of a comparison as results-table rows, labs by anonymous code."""
    results = (
        Result.objects.filter(submission__in=current_submissions(comparison, statuses))
        .order_by("submission__participant__code", "measurement_point_id")
        .values_list(
            "submission__participant__code",
            "measurement_point__device__name",
            "measurement_point__axis",
            "measurement_point__frequency_hz",
            "measurement_point__bench",
            "measurement_point__direction",
            "measurement_point__amplitude_m_s2",
            "value",
            "unit",
            "expanded_uncertainty",
            "coverage_factor",
            "dof",
            "note",
            "repeat_sd",
            "n_repeats",
        )
    )
    return [
        ResultRow(
            row=i,
            lab=code,
            device=device,
            axis=axis,
            frequency_hz=f,
            bench=bench,
            direction=direction,
            amplitude_m_s2=amp,
            sensitivity=value,
            unit=unit,
            expanded_uncertainty=big_u,
            coverage_factor=k,
            dof=dof,
            note=note,
            repeat_sd=repeat_sd,
            n_repeats=n_repeats,
        )
        for i, (
            code,
            device,
            axis,
            f,
            bench,
            direction,
            amp,
            value,
            unit,
            big_u,
            k,
            dof,
            note,
            repeat_sd,
            n_repeats,
        ) in enumerate(results, start=2)
    ]


def comparison_points(comparison: Comparison) -> dict[PointKey, MeasurementPoint]:
    """The comparison's measurement points by their key (device name, axis, f, bench, ...)."""
    points = comparison.measurement_points.select_related("device")
    return {p.key: p for p in points}


@dataclass(frozen=True)
class ComparisonTable:
    """What a results table of one comparison may contain (``context``, the importer's
    rules) and the id of each of its measurement points by key (``point_ids``)."""

    context: TableContext
    point_ids: dict[PointKey, int]


def comparison_table(comparison: Comparison) -> ComparisonTable:
    """The comparison's :class:`ComparisonTable`, from one query of plain tuples (no model
    instance per point): 100,000 points in well under a second."""
    rows = comparison.measurement_points.order_by(
        "device__name", "bench", "direction", "axis", "frequency_hz", "pk"
    ).values_list("pk", "device__unit", *POINT_LOOKUPS, "amplitude_m_s2")
    keys: list[PointKey] = []
    units: dict[str, str] = {}
    point_ids: dict[PointKey, int] = {}
    for pk, unit, *fields in rows:
        key = PointKey(*fields)
        keys.append(key)
        units[key.device] = unit
        point_ids[key] = pk
    return ComparisonTable(TableContext.from_points(keys, device_units=units), point_ids)


def table_context(comparison: Comparison) -> TableContext:
    """What a results table for this comparison may contain (importer rules per comparison)."""
    return comparison_table(comparison).context


def user_laboratories(user: User | AnonymousUser) -> QuerySet[Laboratory]:
    """Laboratories the user is a member of (staff or manager)."""
    if not user.is_authenticated:
        return Laboratory.objects.none()
    return Laboratory.objects.filter(members__user=user)


def lab_comparisons(laboratory: Laboratory) -> QuerySet[Comparison]:
    """Comparisons the laboratory takes part in (what its people and its API keys see)."""
    return Comparison.objects.filter(participants__laboratory=laboratory)


def participant_for_lab(*, code: str, laboratory: Laboratory) -> Participant:
    """The laboratory's participation in comparison ``code``; NotVisible (404) when the
    comparison does not exist or the laboratory does not take part (no existence leak)."""
    # One SQL statement written once (common.rows): this runs on every API request
    # of a laboratory, and compiling it with the ORM cost more than running it.
    rows = _PARTICIPANT_BY_CODE.fetch([code, laboratory.pk])
    if not rows:
        raise NotVisible(f"No comparison {code!r} is visible to you.")
    participant, comparison = rows[0]
    participant.comparison = comparison  # type: ignore[attr-defined]
    participant.laboratory = laboratory  # type: ignore[attr-defined]
    return participant  # type: ignore[return-value]


#: a laboratory's participation (at most one: unique per comparison) in comparison ``code``
_PARTICIPANT_BY_CODE = JoinedQuery(
    [ModelColumns(Participant, "p"), ModelColumns(Comparison, "c")],
    'FROM "labs_participant" "p" INNER JOIN "proficiency_comparison" "c" '
    'ON "c"."id" = "p"."comparison_id" WHERE "c"."code" = %s AND "p"."laboratory_id" = %s',
)


def participant_for_user(*, code: str, user: User | AnonymousUser) -> Participant:
    """The participation in ``code`` of one of the user's laboratories (404 otherwise).
    A person in several participating laboratories gets the first by name."""
    participant = (
        Participant.objects.select_related("comparison", "laboratory")
        .filter(comparison__code=code, laboratory__in=user_laboratories(user))
        .order_by("laboratory__name")
        .first()
    )
    if participant is None:
        raise NotVisible(f"No comparison {code!r} is visible to you.")
    return participant


def participant_submissions(participant: Participant) -> QuerySet[Submission]:
    """All versions of one participant's submissions, newest first, with result counts."""
    return (
        participant.submissions.select_related("submitted_by")
        .annotate(n_results=Count("results"))
        .order_by("-version")
    )


TEMPLATE_COLUMNS = [c for c in COLUMNS if c != "lab"]


def results_template(comparison: Comparison, *, format: str) -> bytes:
    """The results table of docs/interfaces.md §1 with one row per measurement point, sensitivity
    and U left empty, k = 2 filled in (the web download and the API serve the same file)."""
    points = comparison.measurement_points.select_related("device").order_by(
        "device__name", "bench", "direction", "axis", "frequency_hz", "amplitude_m_s2", "pk"
    )
    rows = (
        {
            "device": p.device.name,
            "axis": p.axis,
            "frequency_hz": p.frequency_hz,
            "bench": p.bench,
            "direction": p.direction,
            "amplitude_m_s2": p.amplitude_m_s2,
            "unit": p.device.unit,
            "coverage_factor": 2,
        }
        for p in points
    )
    return write_table(rows, format=format, columns=TEMPLATE_COLUMNS)  # type: ignore[arg-type]
