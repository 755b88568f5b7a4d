"""Publication: the step that spans the apps (the comparison's status, the final reports, the
participants' e-mails), so it lives above them, not in the comparison domain.

Publishing is a job, ``analysis.models.Publication`` (docs/lifecycles.md §1), claimed, kept
alive and re-queued by the protocol of ``common.jobs`` (docs/architecture.md §3):

* asked for (:func:`publication_start`), every refusal is said at once, under the
  comparison's row lock: no successful run, a status the life cycle does not let go to
  published, no authoriser, a publication already pending or running.  The job is
  pending, its task sent after commit; the comparison stays analysed;
* the task (:func:`publication_execute`) renders every final report first, the summary
  and each participant's, its progress counting them, while nothing is published;
* only when every report has rendered, in one transaction under the comparison's row
  lock: analysed → published, the final reports stored as the current ones, every
  preliminary one superseded, a notice for each participant (e-mailed after commit).
  A failure before or in that transaction (an error while rendering, the comparison
  moved meanwhile, a newer run current) fails the job with its error and publishes
  nothing: no status change, no report, no notice, no e-mail.
"""

from __future__ import annotations

import logging
import secrets
from collections.abc import Callable
from functools import partial
from typing import TYPE_CHECKING

from celery import uuid
from django.conf import settings
from django.db import transaction
from django.db.models import F
from django.urls import reverse
from django.utils import timezone

from analysis.models import Publication
from analysis.reports.services import (
    FinalReports,
    final_reports_discard,
    final_reports_render,
    final_reports_store,
    reports_preliminary_supersede,
)
from analysis.selectors import current_run
from analysis.tasks import publication_task
from common import jobs
from common.errors import ApplicationError, StateConflict
from common.jobs import heartbeat
from labs.models import Notice
from labs.notices import absolute, notify
from proficiency.models import Comparison
from proficiency.models import ComparisonStatus as S
from proficiency.services import comparison_transition, comparison_transition_check

if TYPE_CHECKING:
    from django.contrib.auth.models import User

log = logging.getLogger(__name__)
P = Publication.Status
ACTIVE = (P.PENDING, P.RUNNING)
BROKER_UNREACHABLE = (
    "The task queue (broker) could not be reached: nothing was published. Publish again."
)


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


def active_publication(comparison: Comparison) -> Publication | None:
    """The publication of ``comparison`` pending or running, if any (at most one)."""
    return Publication.objects.filter(comparison=comparison, status__in=ACTIVE).first()


def _requested(comparison: Comparison, user: User | None) -> Publication:
    """Every refusal of a publication, then its pending job; in the caller's transaction,
    under the comparison's row lock (two requests at once: the second finds the first)."""
    locked = Comparison.objects.select_for_update().get(pk=comparison.pk)
    run = current_run(locked)
    if run is None:
        raise StateConflict(f"{locked.code} has no successful analysis run to publish.")
    comparison_transition_check(comparison=locked, to=S.PUBLISHED)
    if (refused := publish_refusal(locked)) is not None:
        raise StateConflict(refused)
    if (active := active_publication(locked)) is not None:
        raise StateConflict(
            f"{locked.code} is being published already (publication {active.pk}, "
            f"{active.status}); wait for it to end."
        )
    return Publication.objects.create(
        comparison=locked, run=run, requested_by=user if getattr(user, "pk", None) else None
    )


def publication_start(*, comparison: Comparison, user: User | None = None) -> Publication:
    """Ask for ``comparison`` to be published: StateConflict (or InvalidTransition) at
    once when it cannot be; else its pending job, whose task is sent after commit
    (``common.jobs.send``; with the broker unreachable the job fails with a clear error
    and nothing is published).  The comparison stays analysed until the task publishes."""
    with transaction.atomic():
        publication = _requested(comparison, user)
        pk = publication.pk
        transaction.on_commit(lambda: _send(pk, on_unreachable=lambda: _fail_unsent(pk)))
    return publication


def comparison_publish(*, comparison: Comparison, user: User | None = None) -> Comparison:
    """Publish in this process (scripts, the shell, tests): the same request and the same
    job as :func:`publication_start`, executed here instead of by a worker.  The
    comparison (``comparison`` itself, read again) as it is afterwards; StateConflict
    with the job's error when it failed."""
    with transaction.atomic():
        publication = _requested(comparison, user)
    publication_execute(publication_id=publication.pk)
    publication.refresh_from_db()
    if publication.status == P.FAILED:
        raise StateConflict(publication.error)
    comparison.refresh_from_db()  # as a transition does, the caller's object follows
    return comparison


def _send(
    publication_id: int,
    *,
    task_id: str | None = None,
    on_unreachable: Callable[[], object] | None = None,
) -> bool:
    what = f"publication {publication_id}"
    args = (publication_id,)
    return jobs.send(publication_task, args, task_id=task_id, what=what,
                     on_unreachable=on_unreachable)  # fmt: skip


def _fail_unsent(publication_id: int) -> None:
    """A new publication whose task could not be sent fails at once: never a job pending
    for ever that blocks the next request (a coordinator publishes again)."""
    Publication.objects.filter(pk=publication_id, status=P.PENDING).update(
        status=P.FAILED, error=BROKER_UNREACHABLE, finished_at=timezone.now()
    )


def _claim(publication_id: int, delivery: str) -> str | None:
    """pending → running; or take over a running job whose heartbeat is stale, or that
    this very task (``delivery``: its Celery id, redelivered, or the one the sweep sent)
    had claimed (``common.jobs.claim``).  The claim's new token, or None."""
    token = secrets.token_hex(16)
    claim = {"token": token, "started_at": timezone.now(), "attempts": F("attempts") + 1,
             "progress": 1, "stage": "rendering the final reports", "error": ""}  # fmt: skip
    rows = Publication.objects.filter(pk=publication_id)
    fresh = {"status": P.RUNNING, **claim}
    return token if jobs.claim(rows, delivery=delivery, fresh=fresh, takeover=claim) else None


class _TakenOver(Exception):
    """The job's claim is no longer this task's (the sweep gave it to another)."""


def publication_execute(*, publication_id: int, delivery: str = "") -> str:
    """The task's body: claim the job, render every final report, then publish in one
    transaction; the job ends succeeded, or failed with the error (whatever the error: a
    job is never left running by a task that ended).  A job already ended, or held by a
    live task, is left as it is: a second delivery does nothing.  ``delivery``: this
    task's Celery id.  The job's status when this task ends."""
    token = _claim(publication_id, delivery)
    job = Publication.objects.select_related("run__comparison").filter(pk=publication_id).first()
    if job is None:  # deleted with its comparison
        return "deleted"
    if token is None:  # ended, or held by a live task
        return job.status
    beat = partial(jobs.beat, Publication, publication_id, status=P.RUNNING, token=token)
    with heartbeat(beat, f"publication {publication_id}"):
        try:
            _publish(job, token)
        except _TakenOver:
            log.warning("publication %s was taken over by another task", publication_id)
        except ApplicationError as exc:
            _failed(publication_id, token, exc.message)
        except Exception as exc:  # any other error is shown too, never a job stuck running
            log.exception("publication %s of %s failed", publication_id, job.comparison_id)
            _failed(publication_id, token, f"{type(exc).__name__}: {exc}")
    return Publication.objects.get(pk=publication_id).status


def _failed(publication_id: int, token: str, error: str) -> None:
    """End a running job failed, unless another task holds it or it succeeded."""
    now = timezone.now()
    Publication.objects.filter(pk=publication_id, status=P.RUNNING, token=token).update(
        status=P.FAILED, error=error, finished_at=now, heartbeat_at=now
    )


def _progress(publication_id: int, token: str, done: int, total: int) -> None:
    """The job's progress while its reports render: 1 (claimed) to 95 (all rendered)."""
    Publication.objects.filter(pk=publication_id, status=P.RUNNING, token=token).update(
        progress=1 + 94 * done // total, heartbeat_at=timezone.now(),
        stage=f"rendering the final reports: {done} of {total}",
    )  # fmt: skip


def _check_still(comparison: Comparison, job: Publication) -> None:
    """What the request checked, checked again (the comparison as read now): it may have
    been moved back to closed, analysed again, or lost its authoriser meanwhile."""
    if comparison.status != S.ANALYSED:
        raise StateConflict(
            f"{comparison.code} is {comparison.get_status_display().lower()}, no longer "
            "analysed: nothing was published."
        )
    run = current_run(comparison)
    if run is None or run.pk != job.run_id:
        raise StateConflict(
            f"Analysis run {run.pk if run else '—'} of {comparison.code} became the current "
            f"one after publication of run {job.run_id} was asked for: nothing was "
            "published. Publish again to publish the current results."
        )
    if (refused := publish_refusal(comparison)) is not None:
        raise StateConflict(refused)


def _publish(job: Publication, token: str) -> None:
    run = job.run
    _check_still(Comparison.objects.get(pk=run.comparison_id), job)
    rendered = final_reports_render(run=run, progress=partial(_progress, job.pk, token))
    try:
        _publish_rendered(job, token, rendered)
    except BaseException:
        if not Publication.objects.filter(pk=job.pk, status=P.SUCCEEDED).exists():
            final_reports_discard(rendered)  # rolled back: their files are nobody's
        raise


@transaction.atomic
def _publish_rendered(job: Publication, token: str, rendered: FinalReports) -> None:
    """The one transaction of publication, under the comparison's row lock (a report being
    issued for the analysed comparison holds it, so this waits for it, then supersedes it),
    only while the job's claim is still this task's."""
    locked = Comparison.objects.select_for_update().get(pk=job.comparison_id)
    held = Publication.objects.select_for_update().filter(pk=job.pk, status=P.RUNNING, token=token)
    if not held.exists():
        raise _TakenOver
    _check_still(locked, job)
    published = comparison_transition(comparison=locked, to=S.PUBLISHED)
    reports_preliminary_supersede(comparison=published)
    reports = final_reports_store(run=job.run, rendered=rendered)
    notify_published(published)
    now = timezone.now()
    held.update(status=P.SUCCEEDED, progress=100, stage="published", finished_at=now,
                heartbeat_at=now, report_ids=[r.pk for r in reports])  # fmt: skip


def publications_sweep() -> int:
    """Celery beat (``jobs_sweep_task``): send again the task of every publication pending
    or running and silent for ``JOB_STALE_SECONDS`` (its message lost, the broker down
    after it was sent, its worker lost); the task sent takes the claim over and renders
    again.  Each send is decided by a conditional UPDATE (``common.jobs.lease``), so two
    sweeps at once send it once.  The number of tasks sent."""
    silent = Publication.objects.filter(jobs.silent("created_at"), status__in=ACTIVE)
    sent = 0
    for row in silent.order_by("pk"):
        task_id = uuid()
        if jobs.lease(Publication.objects.all(), pk=row.pk, status=row.status,
                      heartbeat_at=row.heartbeat_at, claimed_by=task_id):  # fmt: skip
            log.warning("publication %s silent since %s: queued again", row.pk,
                        row.heartbeat_at or row.created_at)  # fmt: skip
            sent += _send(row.pk, task_id=task_id)
    return sent


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
