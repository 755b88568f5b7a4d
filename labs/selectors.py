"""Read-side queries of the laboratory side; each owns its joins."""

from __future__ import annotations

import datetime as dt
from collections.abc import Sequence
from dataclasses import dataclass

from django.contrib.auth.models import AnonymousUser, User
from django.db.models import (
    BigIntegerField,
    BooleanField,
    Case,
    CharField,
    Count,
    Exists,
    Expression,
    F,
    Max,
    OuterRef,
    Q,
    QuerySet,
    Subquery,
    Value,
    When,
    prefetch_related_objects,
)
from django.db.models.functions import Cast, Substr
from django.utils import timezone

from common import quantities
from common.errors import NotVisible
from common.points import POINT_LOOKUPS, format_number
from common.quantities import DEFAULT as DEFAULT_QUANTITY
from common.quantities import point_unit
from common.rows import JoinedQuery, ModelColumns
from labs.importers import COLUMNS, PointKey, ResultRow, TableContext, write_table
from labs.models import (
    Enrolment,
    KitSlot,
    Laboratory,
    Notice,
    Participant,
    Result,
    Submission,
)
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
            "measurement_point__quantity",
            "measurement_point__amplitude_m_s2",
            "value",
            "unit",
            "expanded_uncertainty",
            "coverage_factor",
            "dof",
            "note",
            "repeat_sd",
            "n_repeats",
            "measured_on",
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
            quantity=quantity,
            amplitude_m_s2=amp,
            sensitivity=value,
            unit=unit,
            expanded_uncertainty=big_u,
            coverage_factor=k,
            dof=dof,
            note=note,
            repeat_sd=repeat_sd,
            n_repeats=n_repeats,
            measured_on=measured_on,
        )
        for i, (
            code,
            device,
            axis,
            f,
            bench,
            direction,
            quantity,
            amp,
            value,
            unit,
            big_u,
            k,
            dof,
            note,
            repeat_sd,
            n_repeats,
            measured_on,
        ) in enumerate(results, start=2)
    ]


def comparison_points(comparison: Comparison) -> dict[PointKey, MeasurementPoint]:
    """The comparison's measurement points by their key (device name, axis, f, bench, ...)."""
    points = comparison.measurement_points.select_related("device")
    return {p.key: p for p in points}


def scope_filter(participant: Participant) -> Q:
    """The measurement points of ``participant``'s scope as a filter on its comparison's
    points (docs/domain.md §10): each of the scope's lists that is not empty must hold the
    point's value. The devices are read in the same SQL statement (no query here)."""
    chosen = Participant.scope_devices.through.objects.filter(participant_id=participant.pk)
    devices = Q(device__in=chosen.values("device_id")) | ~Exists(chosen)
    return devices & scope_levels_filter(
        benches=participant.scope_benches,
        axes=participant.scope_axes,
        frequencies_hz=participant.scope_frequencies_hz,
    )


def scope_levels_filter(
    *,
    device_ids: Sequence[int] = (),
    benches: Sequence[str] = (),
    axes: Sequence[str] = (),
    frequencies_hz: Sequence[float] = (),
) -> Q:
    """The rule of a scope written once: a point is in it when each list that is not empty
    holds the point's value (an empty list allows every value)."""
    q = Q()
    for lookup, values in (
        ("device_id__in", device_ids),
        ("bench__in", benches),
        ("axis__in", axes),
        ("frequency_hz__in", frequencies_hz),
    ):
        if values:
            q &= Q(**{lookup: list(values)})
    return q


def point_unit_expression(prefix: str = "") -> Expression:
    """A point's unit in SQL, as ``common.quantities.point_unit`` gives it: the kind's own
    unit (deg for a phase) or else its device's; ``prefix`` reaches the point from another
    model (``measurement_point__``)."""
    cases = [
        When(**{f"{prefix}quantity": k.name}, then=Value(k.default_unit))
        for k in quantities.KINDS
        if k.units
    ]
    return Case(*cases, default=F(f"{prefix}device__unit"), output_field=CharField())


def scope_flag(participant: Participant | None, *, default: bool | None = None) -> Expression:
    """An annotation on measurement points: whether each is in ``participant``'s scope;
    ``default`` for every point without a participant."""
    if participant is None:
        return Value(default, output_field=BooleanField())
    return Case(
        When(scope_filter(participant), then=Value(True)),
        default=Value(False),
        output_field=BooleanField(),
    )


def participant_points(participant: Participant) -> QuerySet[MeasurementPoint]:
    """The measurement points ``participant`` reports, in the comparison's point order:
    those of its scope, every point of the comparison when it has none. The one answer
    for its grid, its template, its completeness and the review page."""
    return (
        MeasurementPoint.objects.filter(comparison_id=participant.comparison_id)
        .filter(scope_filter(participant))
        .select_related("device")
    )


@dataclass(frozen=True)
class ReviewRow:
    """One participant on the coordinator's review list: its latest version (none: the
    ``status`` is ``"none"``), how many of its scope's points that version has a result
    for, and whether the laboratory was asked to check one of its results."""

    participant: Participant
    submission_id: int | None
    version: int | None
    status: str
    n_results: int
    n_points: int
    checked: bool
    #: whether the participant has a scope (it reports part of the comparison's points)
    scoped: bool = False

    @property
    def complete(self) -> bool:
        """A result at every point of the participant's own scope (docs/domain.md §10)."""
        return self.version is not None and 0 < self.n_points == self.n_results

    @property
    def acceptable(self) -> bool:
        """What "accept all complete" accepts (docs/lifecycles.md §2): the latest version,
        submitted and not yet decided, complete for the scope, with no check request."""
        return self.status == Submission.Status.SUBMITTED and self.complete and not self.checked


#: the review list's statuses: a submission's, or ``none`` for a participant without one
REVIEW_STATUSES = (*Submission.Status.values, "none")


def _scope_key(p: Participant) -> tuple[object, ...]:
    # review_rows's annotation: the devices are prefetched where there are any
    devices = p.scope_devices.all() if getattr(p, "has_scope_devices", True) else ()
    return (tuple(sorted(d.pk for d in devices)), tuple(sorted(p.scope_benches)),
            tuple(sorted(p.scope_axes)), tuple(sorted(p.scope_frequencies_hz)))  # fmt: skip


def review_rows(comparison: Comparison) -> list[ReviewRow]:
    """Every participant of ``comparison`` by code with its latest version, completeness
    and check requests: the review page, its filters, its next and previous links and
    "accept all complete" read this one list.

    A fixed number of queries whatever the size of the round: the participants, their
    scopes' devices, one count of points per distinct scope (most participants share
    one), and the in-scope results and check requests of each latest version."""
    latest = Submission.objects.filter(participant=OuterRef("pk")).order_by("-version")
    chosen = Participant.scope_devices.through.objects.filter(participant_id=OuterRef("pk"))
    participants = list(
        comparison.participants.select_related("laboratory").annotate(
            latest_id=Subquery(latest.values("pk")[:1]),
            latest_version=Subquery(latest.values("version")[:1]),
            latest_status=Subquery(latest.values("status")[:1]),
            has_scope_devices=Exists(chosen),
        )
    )
    scoped = [
        p for p in participants
        if p.has_scope_devices or p.scope_benches or p.scope_axes or p.scope_frequencies_hz
    ]  # fmt: skip
    # the scopes' devices, for the groups below and the scope's text (no query when none)
    prefetch_related_objects(scoped, "scope_devices")
    # in Python's order of the codes, which the next and previous links compare with
    participants.sort(key=lambda p: p.code)
    if not participants:
        return []
    groups: dict[tuple[object, ...], list[Participant]] = {}
    for p in participants:
        groups.setdefault(_scope_key(p), []).append(p)
    scopes = list(groups.values())  # each group's first participant stands for its scope
    n_points = MeasurementPoint.objects.filter(comparison=comparison).aggregate(
        **{f"s{i}": Count("pk", filter=scope_filter(g[0])) for i, g in enumerate(scopes)}
    )
    latest_of = {id(p): p.latest_id for p in participants}
    in_scope: Q | None = None
    for g in scopes:
        ids = [latest_of[id(p)] for p in g if latest_of[id(p)] is not None]
        if ids:
            points = MeasurementPoint.objects.filter(comparison=comparison)
            inside = Q(submission_id__in=ids) & Q(
                measurement_point__in=points.filter(scope_filter(g[0])).values("pk")
            )
            in_scope = inside if in_scope is None else in_scope | inside
    n_results: dict[int, int] = {}
    checked: set[int] = set()
    if in_scope is not None:
        # a check request is a notice keyed "check:<result id>" (labs.notices.notify_check);
        # its version stays asked until the laboratory sends a new one
        asked = Notice.objects.filter(comparison=comparison, kind=Notice.Kind.CHECK).annotate(
            result_id=Cast(Substr("dedupe_key", len("check:") + 1), BigIntegerField())
        )
        counted = (
            Result.objects.filter(submission_id__in=[pk for pk in latest_of.values() if pk])
            .values("submission_id")
            .annotate(
                n=Count("pk", filter=in_scope),
                asked=Count("pk", filter=Q(pk__in=asked.values("result_id"))),
            )
        )
        for row in counted:
            n_results[row["submission_id"]] = row["n"]
            if row["asked"]:
                checked.add(row["submission_id"])
    size = {id(p): n_points[f"s{i}"] for i, g in enumerate(scopes) for p in g}
    return [
        ReviewRow(
            participant=p,
            submission_id=p.latest_id,
            version=p.latest_version,
            status=p.latest_status or "none",
            n_results=n_results.get(p.latest_id, 0),
            n_points=size[id(p)],
            checked=p.latest_id in checked,
            scoped=any(_scope_key(p)),
        )
        for p in participants
    ]


def acceptable_submissions(comparison: Comparison) -> list[ReviewRow]:
    """The rows "accept all complete" accepts now (:attr:`ReviewRow.acceptable`), by code."""
    return [row for row in review_rows(comparison) if row.acceptable]


def scope_text(participant: Participant | Enrolment) -> str:
    """The scope in words: ``devices MEMS 1; bench linear``; ``every measurement point``
    when it has none (one query for the devices unless ``scope_devices`` is prefetched).
    An application's requested scope (``Enrolment``) has the same fields and reads the same."""
    names = sorted(d.name for d in participant.scope_devices.all())  # prefetched, or one query
    parts = []
    for word, plural, values in (
        ("device", "devices", names),
        ("bench", "benches", list(participant.scope_benches)),
        ("axis", "axes", list(participant.scope_axes)),
        ("frequency", "frequencies",
         [f"{format_number(f)} Hz" for f in sorted(participant.scope_frequencies_hz)]),
    ):  # fmt: skip
        if values:
            parts.append(f"{plural if len(values) > 1 else word} {', '.join(values)}")
    return "; ".join(parts) or "every measurement point"


@dataclass(frozen=True)
class ComparisonTable:
    """What a results table of one comparison may contain (``context``, the importer's
    rules) and the id of each of its measurement points by key (``point_ids``)."""

    context: TableContext
    point_ids: dict[PointKey, int]


def comparison_table(
    comparison: Comparison, participant: Participant | None = None
) -> ComparisonTable:
    """The comparison's :class:`ComparisonTable`, from one query of plain tuples (no model
    instance per point): 100,000 points in well under a second.

    With ``participant``, the context carries its scope (rows outside it are refused, a
    complete table needs its points only); a participant whose scope leaves no point out
    gets the whole comparison's context, with no further query.  The first day of the
    kits' plan rides along on every row (an uncorrelated subquery: computed once)."""
    planned = KitSlot.objects.filter(kit__comparison=comparison).order_by("starts_on")
    rows = (
        comparison.measurement_points.order_by(
            "device__name", "bench", "direction", "axis", "frequency_hz", "quantity", "pk"
        )
        .annotate(
            in_scope=scope_flag(participant, default=True),
            planned=Subquery(planned.values("starts_on")[:1]),
        )
        .values_list("pk", "device__unit", *POINT_LOOKUPS, "amplitude_m_s2", "in_scope", "planned")
    )
    keys: list[PointKey] = []
    scoped: list[PointKey] = []
    units: dict[str, str] = {}
    point_ids: dict[PointKey, int] = {}
    first_planned: dt.date | None = None
    for pk, unit, *fields, amplitude, inside, planned_on in rows:
        key = PointKey.from_fields(fields, amplitude)
        first_planned = planned_on
        keys.append(key)
        if inside:
            scoped.append(key)
        units[key.device] = unit
        point_ids[key] = pk
    context = TableContext.from_points(keys, device_units=units)
    context = context.with_dates(*measurement_dates(comparison, first_planned))
    if participant is not None and len(scoped) < len(keys):
        context = context.with_scope(scoped, scope_text(participant))
    return ComparisonTable(context, point_ids)


#: The time zone furthest ahead of UTC (Kiribati, UTC+14): its today is the latest date
#: on which anyone can have measured.
_AHEAD_OF_UTC = dt.timedelta(hours=14)


def measurement_dates(comparison: Comparison, planned: dt.date | None) -> tuple[dt.date, dt.date]:
    """The dates a result of ``comparison`` may state as measured on (docs/interfaces.md §1):
    from the comparison's first day — the day it was created, or the first day of its
    kits' circulation plan (``planned``) if that is earlier (a round entered once under
    way) — to today anywhere on Earth."""
    first = comparison.created_at.astimezone(dt.UTC).date()
    if planned is not None:
        first = min(first, planned)
    return first, (timezone.now().astimezone(dt.UTC) + _AHEAD_OF_UTC).date()


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


def results_template(
    comparison: Comparison, *, format: str, participant: Participant | None = None
) -> bytes:
    """The results table of docs/interfaces.md §1 with one row per measurement point, sensitivity
    and U left empty, k = 2 filled in (the web download and the API serve the same file);
    for a ``participant``, the points of its scope only (:func:`participant_points`)."""
    chosen = (
        participant_points(participant)
        if participant is not None
        else comparison.measurement_points.select_related("device")
    )
    points = chosen.order_by(
        "device__name", "bench", "direction", "axis", "frequency_hz", "quantity",
        "amplitude_m_s2", "pk",
    )  # fmt: skip
    rows = (
        {
            "device": p.device.name,
            "axis": p.axis,
            "frequency_hz": p.frequency_hz,
            "bench": p.bench,
            "direction": p.direction,
            "quantity": p.quantity,
            "amplitude_m_s2": p.amplitude_m_s2,
            "unit": point_unit(p.quantity, p.device.unit),
            "coverage_factor": 2,
        }
        for p in points
    )
    columns = TEMPLATE_COLUMNS
    if not has_other_kinds(comparison):  # a round of magnitudes: the template as before
        columns = [c for c in columns if c != "quantity"]
    if not has_kits(comparison):  # the date measured matters to a kit's drift only
        columns = [c for c in columns if c != "measured_on"]
    return write_table(rows, format=format, columns=columns)  # type: ignore[arg-type]


def has_kits(comparison: Comparison) -> bool:
    """Whether the comparison circulates kits (docs/domain.md §15): its template and grid
    then ask each result's ``measured_on`` (docs/interfaces.md §1)."""
    return comparison.kits.exists()


def has_other_kinds(comparison: Comparison) -> bool:
    """Whether a point of the comparison is of another kind than the magnitude: its
    templates and downloads then carry the ``quantity`` column (docs/interfaces.md §1)."""
    return comparison.measurement_points.exclude(quantity=DEFAULT_QUANTITY).exists()
