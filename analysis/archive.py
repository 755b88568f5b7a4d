"""A round's archive: one ZIP of a run's outputs per audience, built as a job
(docs/architecture.md §3; the contents: docs/interfaces.md §6).

* asked for (:func:`archive_request`): one row per run and audience, made once under
  unique constraints, so asking again returns the row there is — ready, queued or
  running.  A failed one, or a ready one missing a report issued from the run since, is
  queued again (the same row).  A small run (at most ``ARCHIVE_INLINE_MAX_SCORES``
  scores) is built right there, in the request; a larger one by ``archive_build_task``,
  sent after commit;
* the task (:func:`archive_execute`) claims the row (``common.jobs.claim``), beats while
  it writes the ZIP to a temporary file (``analysis.archive_contents``: streamed, bounded
  memory), stores the file, then marks the row ready with its size and SHA-256 only
  while its claim holds.  Any error fails the row with the error and leaves no file: a
  row that is not ready has none (a CHECK constraint), and a stored file whose row could
  not be marked ready is deleted;
* lost (its worker gone, its message lost): the stale-job sweep sends it again
  (:func:`archives_sweep`), and the task sent takes the claim over.  A task delivered
  twice finds the row ready and does nothing; built again, the ZIP is the same bytes.
"""

from __future__ import annotations

import hashlib
import logging
import secrets
import tempfile
from functools import partial
from typing import TYPE_CHECKING, Any

from celery import uuid
from django.conf import settings
from django.core.files import File
from django.core.files.storage import default_storage
from django.db import IntegrityError, transaction
from django.db.models import F
from django.utils import timezone

from analysis.archive_contents import (
    Audience,
    archive_entries,
    archive_reports,
    stamp,
    write_archive,
)
from analysis.models import AnalysisRun, RoundArchive, archive_path
from analysis.selectors import current_run
from analysis.tasks import archive_build_task
from common import jobs
from common.errors import ApplicationError, StateConflict
from common.jobs import heartbeat
from labs.models import Participant
from proficiency.models import Comparison, ComparisonStatus

if TYPE_CHECKING:
    from django.contrib.auth.models import AbstractBaseUser, AnonymousUser

log = logging.getLogger(__name__)
A = RoundArchive.Status
ACTIVE = (A.PENDING, A.RUNNING)


def archive_of(run: AnalysisRun, participant: Participant | None = None) -> RoundArchive | None:
    """The archive of ``run`` for the coordinators (``participant`` None) or a participant."""
    return RoundArchive.objects.filter(run=run, participant=participant).first()


def archive_shown(run: AnalysisRun, own_code: str | None) -> RoundArchive | None:
    """The archive a results page shows: the coordinators' (``own_code`` None) or that of
    the participant of ``run``'s comparison with code ``own_code``."""
    if own_code is None:
        return archive_of(run)
    return RoundArchive.objects.filter(run=run, participant__code=own_code).first()


def archive_request(
    *,
    comparison: Comparison,
    run: AnalysisRun,
    participant: Participant | None = None,
    user: AbstractBaseUser | AnonymousUser | None = None,
) -> RoundArchive:
    """Ask for the archive of ``run`` (a succeeded run of ``comparison``) for the
    coordinators, or for ``participant``: the one row of that run and audience, made if
    there is none, queued again if it failed or lacks a report issued since.  Idempotent:
    asking again returns the same row.  Built here for a small run, else by a task."""
    _check_readable(comparison, run, participant)
    inline = run.scores.count() <= settings.ARCHIVE_INLINE_MAX_SCORES
    with transaction.atomic():
        archive, queued = _requested(run, participant, user)
        if queued and not inline:
            pk = archive.pk
            transaction.on_commit(lambda: _send_pk(pk))
    if queued and inline:
        archive_execute(archive_id=archive.pk)
        archive.refresh_from_db()
    return archive


def _check_readable(
    comparison: Comparison, run: AnalysisRun, participant: Participant | None
) -> None:
    """What the results pages allow, said once: a successful run of the round; for a
    participant of the round, only once published and only the current run."""
    if run.comparison_id != comparison.pk or run.status != AnalysisRun.Status.SUCCEEDED:
        raise StateConflict(f"Run {run.pk} is not a successful analysis run of {comparison.code}.")
    if participant is None:
        return
    if participant.comparison_id != comparison.pk:
        raise StateConflict(
            f"Participant {participant.code} does not take part in {comparison.code}."
        )
    if comparison.status != ComparisonStatus.PUBLISHED:
        raise StateConflict(f"The results of {comparison.code} are not published yet.")
    current = current_run(comparison)
    if current is None or current.pk != run.pk:
        raise StateConflict(f"Run {run.pk} is not the published results of {comparison.code}.")


def _requested(
    run: AnalysisRun, participant: Participant | None, user: Any
) -> tuple[RoundArchive, bool]:
    """The row (locked) and whether it was queued now; two requests at once find one row
    (the unique constraints, the second waiting on the first's insert or lock)."""
    rows = RoundArchive.objects.select_for_update().filter(run=run, participant=participant)
    archive = rows.first()
    if archive is None:
        try:
            with transaction.atomic():
                made = RoundArchive.objects.create(
                    comparison_id=run.comparison_id, run=run, participant=participant,
                    requested_by=user if getattr(user, "pk", None) else None,
                )  # fmt: skip
            return made, True
        except IntegrityError:  # made by a request at the same time
            archive = rows.get()
    if archive.status in ACTIVE or not _needs_rebuild(archive):
        return archive, False
    transaction.on_commit(partial(_discard_file, archive.file.name))  # once it is nobody's
    rows.filter(pk=archive.pk).update(status=A.PENDING, file="", size=0, sha256="",
                                      heartbeat_at=None, token="", finished_at=None)  # fmt: skip
    archive.refresh_from_db()
    return archive, True


def _needs_rebuild(archive: RoundArchive) -> bool:
    """A failed archive, or a ready one whose reports are no longer those of its audience
    (a report issued from the run since, a new version, publication's final ones)."""
    if archive.status == A.FAILED:
        return True
    audience = Audience(archive.run, archive.participant)
    return sorted(r.pk for r in archive_reports(audience)) != sorted(archive.report_ids)


def _send_pk(archive_id: int) -> bool:
    row = RoundArchive.objects.filter(pk=archive_id, status=A.PENDING).first()
    return _send(row) if row is not None else False


def _send(row: RoundArchive) -> bool:
    """Send the row's task under a new Celery id unless another sweep or task moved its
    heartbeat since it was read (``common.jobs.lease``); with the broker unreachable the
    row waits for the sweep."""
    task_id = uuid()
    if not jobs.lease(RoundArchive.objects.all(), pk=row.pk, status=row.status,
                      heartbeat_at=row.heartbeat_at, claimed_by=task_id):  # fmt: skip
        return False
    what = f"archive {row.pk} (run {row.run_id})"
    return jobs.send(archive_build_task, (row.pk,), task_id=task_id, what=what)


def _claim(archive_id: int, delivery: str) -> str | None:
    """pending → running; or take over a running row whose heartbeat is stale, or that
    this very task (``delivery``) had claimed.  The claim's new token, or None."""
    token = secrets.token_hex(16)
    claim = {"token": token, "started_at": timezone.now(), "attempts": F("attempts") + 1}
    rows = RoundArchive.objects.filter(pk=archive_id)
    fresh = {"status": A.RUNNING, "error": "", **claim}
    return token if jobs.claim(rows, delivery=delivery, fresh=fresh, takeover=claim) else None


def archive_execute(*, archive_id: int, delivery: str = "") -> str:
    """The task's body: claim row ``archive_id``, build and store its ZIP, end it ready or
    failed (whatever the error: a row is never left running by a task that ended).  A row
    ready, failed or held by a live task is left as it is.  The row's status at the end."""
    token = _claim(archive_id, delivery)
    related = ("comparison", "run__comparison", "participant")
    row = RoundArchive.objects.select_related(*related).filter(pk=archive_id).first()
    if row is None:  # deleted with its run or comparison
        return "deleted"
    if token is None:
        return row.status
    beat = partial(jobs.beat, RoundArchive, archive_id, status=A.RUNNING, token=token)
    with heartbeat(beat, f"archive {archive_id}"):
        try:
            _build_and_store(row, token)
        except ApplicationError as exc:
            _failed(archive_id, token, exc.message)
        except Exception as exc:  # any other error is shown too, never a row stuck running
            log.exception("archive %s of run %s failed", archive_id, row.run_id)
            _failed(archive_id, token, f"{type(exc).__name__}: {exc}")
    return RoundArchive.objects.get(pk=archive_id).status


def _failed(archive_id: int, token: str, error: str) -> None:
    now = timezone.now()
    RoundArchive.objects.filter(pk=archive_id, status=A.RUNNING, token=token).update(
        status=A.FAILED, error=error, finished_at=now, heartbeat_at=now
    )


def _build_and_store(row: RoundArchive, token: str) -> None:
    """Write the ZIP to a temporary file, store it, then mark the row ready in one
    conditional UPDATE; the stored file is deleted if that does not happen."""
    audience = Audience(row.run, row.participant)
    reports = archive_reports(audience)
    with tempfile.TemporaryFile(suffix=".zip") as tmp:
        write_archive(tmp, archive_entries(audience, reports), stamp(row.run))
        size, digest = tmp.tell(), _sha256(tmp)
        tmp.seek(0)
        name = default_storage.save(archive_path(row, ""), File(tmp))
    try:
        now = timezone.now()
        held = RoundArchive.objects.filter(pk=row.pk, status=A.RUNNING, token=token)
        done = held.update(status=A.READY, file=name, size=size, sha256=digest, error="",
                           report_ids=[r.pk for r in reports], finished_at=now,
                           heartbeat_at=now)  # fmt: skip
    except BaseException:
        _discard_file(name)
        raise
    if not done:  # taken over meanwhile: the task holding it stores its own
        _discard_file(name)
        log.warning("archive %s was taken over by another task", row.pk)


def _sha256(tmp: Any) -> str:
    tmp.seek(0)
    digest = hashlib.sha256()
    while block := tmp.read(2**20):
        digest.update(block)
    return digest.hexdigest()


def _discard_file(name: str) -> None:
    if name:
        default_storage.delete(name)


def archives_sweep() -> int:
    """Celery beat (``jobs_sweep_task``): send again the archives pending or running and
    silent for ``JOB_STALE_SECONDS`` (message lost, broker down, worker lost); the task
    sent takes the claim over.  Each send is decided by a conditional UPDATE, so two
    sweeps at once send it once.  The number of tasks sent."""
    silent = RoundArchive.objects.filter(jobs.silent("created_at"), status__in=ACTIVE)
    sent = 0
    for row in silent.order_by("pk"):
        log.warning("archive %s of run %s silent since %s: queued again", row.pk, row.run_id,
                    row.heartbeat_at or row.created_at)  # fmt: skip
        sent += _send(row)
    return sent


def archive_filename(archive: RoundArchive) -> str:
    """``<round>-run<N>.zip``: the download's name."""
    return f"{archive.run.comparison.code}-run{archive.run_id}.zip"
