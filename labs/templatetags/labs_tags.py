"""Small display helpers of the laboratory pages: status badges and local times."""

from __future__ import annotations

import datetime as dt
from collections.abc import Iterable

from django import template
from django.contrib.auth.models import AnonymousUser, User
from django.db.models import QuerySet
from django.utils import timezone
from django.utils.html import format_html

from common.points import format_number, point_label
from labs.access import managed_labs
from labs.models import Laboratory, Participant, Submission
from labs.selectors import scope_text
from proficiency.models import ComparisonStatus, MeasurementPoint
from proficiency.protocols import BenchPlan

register = template.Library()

_BADGES: dict[str, str] = {
    ComparisonStatus.DRAFT: "text-bg-secondary",
    ComparisonStatus.OPEN: "text-bg-success",
    ComparisonStatus.CLOSED: "text-bg-dark",
    ComparisonStatus.ANALYSED: "text-bg-info",
    ComparisonStatus.PUBLISHED: "text-bg-primary",
}
_SUBMISSION_BADGES: dict[str, str] = {
    Submission.Status.DRAFT: "text-bg-warning",
    Submission.Status.SUBMITTED: "text-bg-primary",
    Submission.Status.ACCEPTED: "text-bg-success",
    Submission.Status.REJECTED: "text-bg-danger",
}


@register.simple_tag
def comparison_badge(status: str) -> str:
    label = dict(ComparisonStatus.choices).get(status, status)
    return format_html('<span class="badge {}">{}</span>', _BADGES.get(status, ""), label)


@register.simple_tag
def submission_badge(status: str | None) -> str:
    if not status:
        return format_html('<span class="badge text-bg-light border">{}</span>', "None yet")
    label = dict(Submission.Status.choices).get(status, status)
    return format_html(
        '<span class="badge {}">{}</span>', _SUBMISSION_BADGES.get(status, ""), label
    )


@register.simple_tag
def local_time(value: dt.datetime | None) -> str:
    """A ``<time>`` in the server's zone; base.html rewrites it in the reader's own zone."""
    if value is None:
        return format_html('<span class="text-body-secondary">{}</span>', "—")
    local = timezone.localtime(value)
    return format_html(
        '<time datetime="{}" data-local>{}</time>',
        value.astimezone(dt.UTC).isoformat(),
        local.strftime("%Y-%m-%d %H:%M %Z"),
    )


@register.simple_tag
def managed_laboratories(user: User | AnonymousUser) -> QuerySet[Laboratory]:
    """Laboratories whose API keys the user may manage (navigation link)."""
    return managed_labs(user)


@register.filter
def num(value: float | None) -> str:
    """A stored number in full precision without a trailing ``.0`` (``420``, ``8.25``)."""
    return "" if value is None else format_number(float(value))


@register.filter
def point(value: MeasurementPoint, sep: str = ", ") -> str:
    """A measurement point's label (``MEMS 1 · X · 5 Hz · linear vertical`` with ``" · "``)."""
    return point_label(value.key, sep=sep)


@register.filter
def nums(values: Iterable[float]) -> str:
    """``5, 10, 20`` for a list of frequencies."""
    return ", ".join(format_number(float(v)) for v in values)


@register.filter
def amplitude_rows(plan: BenchPlan) -> list[tuple[str, str, float]]:
    """A bench plan's expected excitation as (frequency, direction, amplitude) rows."""
    return [(format_number(f), d, a) for (f, d), a in sorted(plan.amplitudes.items())]


@register.filter
def scope(participant: Participant) -> str:
    """A participant's scope in words (``labs.selectors.scope_text``)."""
    return scope_text(participant)
