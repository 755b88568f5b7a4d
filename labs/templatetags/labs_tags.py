"""Small display helpers of the pages: status badges, local times and numbers as a
metrologist writes them (the one rule of ``common.numbers``, docs/domain.md §3.1)."""

from __future__ import annotations

import datetime as dt
from collections.abc import Iterable
from typing import Any

from django import template
from django.contrib.auth.models import AnonymousUser, User
from django.db.models import QuerySet
from django.utils import timezone
from django.utils.html import format_html

from common import numbers, quantities
from common.points import format_number, point_label
from common.quantities import unit_text, with_unit
from labs.access import managed_labs
from labs.models import Enrolment, Laboratory, Participant, Submission
from labs.notices import notices_unread_count
from labs.raw_figures import record_figures
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
def unread_notices(user: User | AnonymousUser) -> int:
    """The number of unread notices of the user's laboratories (navigation badge)."""
    return notices_unread_count(user)


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
def raw_figures(axes: list[dict[str, Any]] | None) -> dict[str, list[dict[str, Any]]]:
    """A recomputation's phases and gyroscope rows (``labs.raw_figures.record_figures``)."""
    return record_figures(axes or [])


# --- numbers a person reads (docs/domain.md §3.1); downloads and the API never round ------


@register.filter
def round_to(value: float | None, uncertainty: float | None) -> str:
    """The value rounded to the place of its uncertainty's second significant digit
    (``{{ r.value|round_to:r.expanded_uncertainty }}``: ``419.47``)."""
    return numbers.round_to_uncertainty(value, uncertainty)


@register.filter
def unc(value: float | None) -> str:
    """An uncertainty to two significant digits (``12.751038232238182`` → ``13``)."""
    return numbers.uncertainty(value)


@register.filter
def plain(value: float | None) -> str:
    """A number shown alone, without binary noise (``3.4160160000000004`` → ``3.416016``)."""
    return numbers.plain(value)


@register.filter
def fixed(value: float | None, places: int = 2) -> str:
    """A score with ``places`` decimals, as the PDF writes En, ζ and z (``0.12``)."""
    return numbers.fixed(value, int(places))


@register.filter
def signed_to(value: float | None, uncertainty: float | None) -> str:
    """D with its sign, rounded like its row's value: to the place of the row's U
    (``{{ s.d|signed_to:r.expanded_uncertainty }}``: ``+1.47`` beside ``419.47``), as the
    report writes it (docs/domain.md §3.1)."""
    return numbers.round_to_uncertainty(value, uncertainty, sign=True)


@register.filter
def signed(value: float | None, digits: int = 4) -> str:
    """D with its sign to ``digits`` significant digits, as the PDF (``+0.01235``)."""
    return numbers.significant(value, int(digits), sign=True)


@register.filter
def statistic(value: float | None, digits: int = 3) -> str:
    """A test statistic (χ², a Birge ratio) to ``digits`` significant digits (§3.1)."""
    return numbers.significant(value, int(digits))


@register.filter
def entered_u(result: Any) -> str:
    """A result's U as the laboratory wrote it: ``1.2 % (5.0 mV/(m/s²))`` for a relative U
    (the absolute value in brackets, rounded, its unit as people read it:
    ``0.5 % (0.071 D/(°/s))``), else the absolute U rounded."""
    absolute = numbers.uncertainty(result.expanded_uncertainty)
    entered = getattr(result, "expanded_uncertainty_entered", "")
    if not entered:
        return absolute
    return f"{entered} ({with_unit(absolute, result.unit)})"


def _path(item: Any, path: str) -> Any:
    for name in path.split("."):
        item = item.get(name) if isinstance(item, dict) else getattr(item, name, None)
    return item


@register.simple_tag
def unit_of(items: Iterable[Any], path: str = "unit") -> str:
    """The one unit of a table's rows (``path`` to it on each row, dotted), for the column
    headings; ``""`` when the rows mix units (each cell then shows its own) or are none."""
    units = {_path(item, path) for item in items}
    return units.pop() if len(units) == 1 and None not in units else ""


@register.simple_tag
def unit_heading(unit: str) -> str:
    """`` (mV/(m/s²))`` after a column heading (``°`` for degrees:
    ``common.quantities.unit_text``), or `` (unit in each row)`` for a table of several
    units."""
    if unit:
        return format_html(
            ' <span class="fw-normal text-nowrap d-block small">({})</span>', unit_text(unit)
        )
    return format_html(' <span class="fw-normal small">{}</span>', "(unit in each row)")


@register.filter
def unit(value: str | None) -> str:
    """A unit as a person reads it (``D/(m/s^2)`` → ``D/(m/s²)``, ``deg`` → ``°``:
    ``common.quantities.unit_text``)."""
    return unit_text(value or "")


@register.filter
def per_day(value: str | None) -> str:
    """The unit of a change per day of values in ``value`` (a drift's slope), as stored:
    ``deg/d``, ``(D/(m/s^2))/d`` (``common.quantities.per_day``); ``unit`` shows it."""
    return quantities.per_day(value or "")


@register.simple_tag
def unit_after(unit: str) -> str:
    """A cell's unit right after its number, as written (docs/domain.md §3.1): ``°`` with
    no space (``-1.92°``), any other unit after a space (``418.2 D/(m/s²)``)."""
    shown = unit_text(unit)
    gap = "" if shown == "°" else " "
    return format_html('{}<span class="small text-body-secondary">{}</span>', gap, shown)


@register.filter
def scope(participant: Participant | Enrolment) -> str:
    """A participant's scope (or the one an application asks for) in words
    (``labs.selectors.scope_text``)."""
    return scope_text(participant)
