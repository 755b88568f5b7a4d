"""Read-side queries of the laboratory side; each owns its joins."""

from __future__ import annotations

from django.db.models import Max, OuterRef, QuerySet, Subquery

from labs.importers import PointKey, ResultRow, TableContext
from labs.models import Result, Submission
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
        ) in enumerate(results, start=2)
    ]


def comparison_points(comparison: Comparison) -> dict[PointKey, MeasurementPoint]:
    """The comparison's measurement points by their key (device name, axis, f, bench, ...)."""
    points = comparison.measurement_points.select_related("device")
    return {
        PointKey(p.device.name, p.axis, p.frequency_hz, p.bench, p.direction, p.amplitude_m_s2): p
        for p in points
    }


def table_context(comparison: Comparison) -> TableContext:
    """What a results table for this comparison may contain (importer rules per comparison)."""
    units = dict(comparison.devices.values_list("name", "unit"))
    return TableContext.from_points(comparison_points(comparison), device_units=units)
