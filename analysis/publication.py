"""Publication: the step that spans the apps (the comparison's status, the final reports, the
participants' e-mails), so it lives above them, not in the comparison domain."""

from __future__ import annotations

from django.core.mail import send_mass_mail
from django.db import transaction

from analysis.reports.services import reports_enqueue, reports_preliminary_supersede
from common.errors import StateConflict
from labs.models import Membership
from proficiency.models import Comparison
from proficiency.models import ComparisonStatus as S
from proficiency.services import comparison_transition


def comparison_publish(*, comparison: Comparison, user: object | None = None) -> Comparison:
    """analysed → published: results become visible to the participants, who are told by
    e-mail (console back end by default). Reports are issued by the report service: in
    the transaction of the status change every preliminary report is superseded, and after
    commit the tasks issue the final versions (a report still rendering for the analysed
    comparison holds the comparison's row, so the status change waits for it)."""
    if not Comparison.objects.filter(pk=comparison.pk).exclude(authorised_by_name="").exists():
        raise StateConflict(
            f"{comparison.code} cannot be published: publication issues the final reports, "
            "which need the name and role of the person authorising them. Enter them under "
            "'Report comments and authorisation' on the comparison's page, then publish."
        )
    with transaction.atomic():
        published = comparison_transition(comparison=comparison, to=S.PUBLISHED)
        reports_preliminary_supersede(comparison=published)
        reports_enqueue(comparison_id=published.pk)  # issued by Celery after commit
    emails = sorted(
        set(
            Membership.objects.filter(
                laboratory__participations__comparison=published, user__email__gt=""
            ).values_list("user__email", flat=True)
        )
    )
    subject = f"[{published.code}] results published"
    body = (
        f"The results of {published.code} ({published.title}) are published. Sign in to see "
        "your scores and download your report."
    )
    send_mass_mail([(subject, body, None, [e]) for e in emails], fail_silently=False)
    return published
