"""Report visibility (docs/architecture.md §2, §5), the analysis part of the access rules (the
rest is labs.access): who may list and download which report.

Coordinators: every report of their comparison, preliminary ones included.
Participants: once the comparison is published, the final versions of the summary and of
their own report (never a preliminary one, even one issued before publication).
Everything else is NotVisible (404): another lab's report cannot be confirmed to exist.
"""

from __future__ import annotations

from django.db.models import Q, QuerySet

from analysis.models import Report
from common.errors import NotVisible
from labs.access import Caller, ComparisonAccess, comparison_access
from proficiency.models import ComparisonStatus


def reports_visible(access: ComparisonAccess) -> QuerySet[Report]:
    found = Report.objects.filter(comparison=access.comparison).select_related("participant")
    if not access.is_coordinator:
        if access.participant is None or access.comparison.status != ComparisonStatus.PUBLISHED:
            return found.none()
        found = found.filter(
            Q(kind=Report.Kind.SUMMARY) | Q(participant=access.participant),
            status=Report.Status.FINAL,
        )
    return found.order_by("kind", "participant__code", "-version")


def report_for_download(caller: Caller, token: str) -> Report:
    """The report behind a download token, if the caller may read it; else NotVisible."""
    report = Report.objects.select_related("comparison").filter(token=token).first()
    if report is None:
        raise NotVisible("No such report is visible to you.")
    try:
        access = comparison_access(caller, report.comparison.code)
    except NotVisible:
        raise NotVisible("No such report is visible to you.") from None
    if not reports_visible(access).filter(pk=report.pk).exists():
        raise NotVisible("No such report is visible to you.")
    return report


def download_name(report: Report) -> str:
    who = report.participant.code if report.participant else "summary"
    return f"{report.comparison.code}-{who}-v{report.version}.pdf"
