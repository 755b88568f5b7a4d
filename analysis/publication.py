"""Publication: the step that spans the apps (the comparison's status, the final reports, the
participants' e-mails), so it lives above them, not in the comparison domain."""

from __future__ import annotations

from django.conf import settings
from django.db import transaction
from django.urls import reverse

from analysis.reports.services import reports_enqueue, reports_preliminary_supersede
from common.errors import StateConflict
from labs.models import Notice
from labs.notices import absolute, notify
from proficiency.models import Comparison
from proficiency.models import ComparisonStatus as S
from proficiency.services import comparison_transition


def publish_refusal(comparison: Comparison) -> str | None:
    """Why ``comparison`` cannot be published now for want of an authoriser (read from the
    database), or None; the state rules are the transition's own."""
    if not Comparison.objects.filter(pk=comparison.pk).exclude(authorised_by_name="").exists():
        return (
            f"{comparison.code} cannot be published: publication issues the final reports, "
            "which need the name and role of the person authorising them. Enter them under "
            "'Report comments and authorisation' on the comparison's page, then publish."
        )
    return None


def comparison_publish(*, comparison: Comparison, user: object | None = None) -> Comparison:
    """analysed → published: results become visible to the participants, who are each sent
    a notice with the links to their results and the reports (labs.notices: the inbox and
    an e-mail after commit). Reports are issued by the report service: in
    the transaction of the status change every preliminary report is superseded, and after
    commit the tasks issue the final versions (a report still rendering for the analysed
    comparison holds the comparison's row, so the status change waits for it)."""
    if (refused := publish_refusal(comparison)) is not None:
        raise StateConflict(refused)
    with transaction.atomic():
        published = comparison_transition(comparison=comparison, to=S.PUBLISHED)
        reports_preliminary_supersede(comparison=published)
        reports_enqueue(comparison_id=published.pk)  # issued by Celery after commit
        notify_published(published)
    return published


def notify_published(comparison: Comparison) -> int:
    """Every participant of a published comparison is sent a notice linking its own results
    (a page only it sees) and the reports page; once each. The number of notices made."""
    results = reverse("coordinator:lab_results", args=[comparison.code])
    reports = absolute(reverse("reports", args=[comparison.code]))
    made = 0
    for participant in comparison.participants.select_related("laboratory", "comparison"):
        made += bool(
            notify(
                kind=Notice.Kind.PUBLISHED,
                participant=participant,
                dedupe_key=f"published:{participant.pk}",
                link=results,
                context={"reports_url": reports, "provider": settings.PT_PROVIDER_NAME},
            )
        )
    return made
