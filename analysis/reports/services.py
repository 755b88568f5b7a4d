"""Issuing PT reports: render the current run, store the PDF, version and supersede.

A report is never changed once stored: a reissue is a new version, and the older
versions are kept with ``superseded = True``.  A report records the status it was
issued for (``Report.status``: preliminary while analysed, final once published, read
under the issuing lock).  Publication renders every final report before it publishes
(:func:`final_reports_render`) and, in its one transaction, stores them as the current
versions and supersedes every preliminary one (:func:`final_reports_store`), so a
preliminary report is never the current report of a published comparison.

The fan-out (``reports_issue_all_task``) issues the reports still missing from a
published comparison (one deleted since, or a round published before publication rendered
its reports itself), sent again by Celery beat while any is missing.  Its tasks work
under job rows (``ReportBatch``: the summary, and each batch of participants), claimed,
kept alive, ended and re-queued by the protocol of ``common.jobs`` (docs/lifecycles.md §4).
"""

from __future__ import annotations

import hashlib
import logging
import secrets
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from functools import partial
from typing import Any

from auditlog.context import set_actor
from celery import uuid
from django.conf import settings
from django.core.files.base import ContentFile
from django.db import connections, router, transaction
from django.db.models import F, Max
from django.utils import timezone

import proficiency
from analysis.bulk import planner_stats_refresh
from analysis.models import AnalysisRun, Report, ReportBatch
from analysis.reports.assemble import (
    ComparisonCommon,
    RunContext,
    comparison_common,
    participant_rows,
    report_data,
    report_histories,
    report_status,
    run_context,
)
from analysis.reports.data import ReportHistory, ResultRow, ScoreRow
from analysis.reports.figures import point_charts_build
from analysis.reports.render import render_report
from analysis.reports.tasks import (
    report_issue_batch_task,
    report_issue_task,
    reports_issue_all_task,
)
from analysis.selectors import current_run
from common import jobs
from common.errors import ApplicationError, StateConflict, ValidationFailed
from common.jobs import heartbeat
from labs.models import Participant
from proficiency.models import Comparison, ComparisonStatus

REPORTABLE = (ComparisonStatus.ANALYSED, ComparisonStatus.PUBLISHED)
MAX_TEXT = 20_000
MAX_NAME = 120
log = logging.getLogger(__name__)
B = ReportBatch.Status


def _check_notes(
    comparison: Comparison, comments: str, conclusions: str, name: str, role: str
) -> None:
    errors = [
        {"field": field, "message": f"At most {limit:,} characters ({len(value):,} given)."}
        for field, value, limit in (
            ("comments", comments, MAX_TEXT),
            ("conclusions", conclusions, MAX_TEXT),
            ("authorised_by_name", name, MAX_NAME),
            ("authorised_by_role", role, MAX_NAME),
        )
        if len(value) > limit
    ]
    if bool(name) != bool(role):
        missing = "authorised_by_role" if name else "authorised_by_name"
        message = "Give both the name and the role of the person authorising the reports."
        errors.append({"field": missing, "message": message})
    if errors:
        raise ValidationFailed("The report comments or authorisation are not valid.", errors=errors)
    if comparison.status == ComparisonStatus.PUBLISHED and not name:
        raise StateConflict(
            f"{comparison.code} is published: its final reports need an authoriser, which "
            "can be changed but not removed."
        )


@transaction.atomic
def report_notes_update(
    *,
    comparison: Comparison,
    comments: str,
    conclusions: str,
    authorised_by_name: str,
    authorised_by_role: str,
    user: object | None = None,
) -> Comparison:
    """Store the coordinator's comments, conclusions and the report's authoriser
    (docs/domain.md §9), audit-logged with ``user`` as actor. Reports already issued keep
    their text; a reissue prints the new one."""
    locked = Comparison.objects.select_for_update().get(pk=comparison.pk)
    name, role = authorised_by_name.strip(), authorised_by_role.strip()
    _check_notes(locked, comments, conclusions, name, role)
    locked.report_comments = comments.strip()
    locked.report_conclusions = conclusions.strip()
    locked.authorised_by_name, locked.authorised_by_role = name, role
    with set_actor(user if getattr(user, "pk", None) else None):
        locked.save(
            update_fields=[
                "report_comments",
                "report_conclusions",
                "authorised_by_name",
                "authorised_by_role",
                "updated_at",
            ]
        )
    return locked


def _check_reportable(comparison: Comparison) -> None:
    if comparison.status not in REPORTABLE:
        raise StateConflict(
            f"{comparison.code} is {comparison.status}: reports are issued for analysed "
            "(preliminary) or published (final) comparisons."
        )


def _reportable_run(comparison: Comparison) -> AnalysisRun:
    _check_reportable(comparison)
    run = current_run(comparison)
    if run is None:
        raise StateConflict(f"{comparison.code} has no successful analysis run to report.")
    return run


def _check_kind(comparison: Comparison, kind: str, participant: Participant | None) -> None:
    if kind not in Report.Kind.values:
        raise ValidationFailed(f"Unknown report kind {kind!r}; use summary or participant.")
    if (kind == Report.Kind.PARTICIPANT) != (participant is not None):
        raise ValidationFailed("A participant report needs a participant; a summary has none.")
    if participant is not None and participant.comparison_id != comparison.pk:
        raise ValidationFailed(f"Participant {participant.code} is not in {comparison.code}.")


def report_edition(previous_runs: Sequence[int | None], run: AnalysisRun) -> int:
    """The edition printed in the report number: one per distinct run reported, so
    re-issuing the same run reproduces the same bytes (same number, same sha256)."""
    order = list(dict.fromkeys([*previous_runs, run.pk]))
    return order.index(run.pk) + 1


def report_issue(
    *,
    comparison: Comparison,
    kind: str,
    participant: Participant | None = None,
    authorised_by: str = "",
    comments: str = "",
) -> Report:
    """Render and store a new version of a report from the current run; supersede the older.

    The row lock that serialises the versions of one report is the participant's for a
    participant report and the comparison's for the summary, so that workers render the
    reports of different participants in parallel."""
    report = _issue(comparison, kind, participant, authorised_by, comments, reuse=None)
    assert report is not None
    return report


@transaction.atomic
def _issue(
    comparison: Comparison,
    kind: str,
    participant: Participant | None,
    authorised_by: str,
    comments: str,
    reuse: AnalysisRun | None,
) -> Report | None:
    """:func:`report_issue`; with ``reuse`` (the task's run), the current report of that
    run and of the comparison's status when there is one (looked up under the lock, so
    two deliveries at once issue one), None when ``reuse`` is no longer the current run."""
    locked = _lock(comparison, participant)
    _check_kind(locked, kind, participant)
    run = _reportable_run(locked)
    status = _issue_status(locked, authorised_by)
    previous = Report.objects.filter(comparison=locked, kind=kind, participant=participant)
    if reuse is not None:
        if run != reuse:
            return None
        found = previous.filter(run=run, status=status, superseded=False).order_by("-version")
        if (current := found.first()) is not None:
            return current
    runs = list(previous.order_by("version").values_list("run_id", flat=True))
    pdf = render_report(
        report_data(
            run=run,
            participant=participant,
            edition=report_edition(runs, run),
            authorised_by=authorised_by,
            comments=comments,
            status=status,
        )
    )
    version = (previous.aggregate(v=Max("version"))["v"] or 0) + 1
    report = _store(run, kind, participant, version, pdf, status)
    previous.exclude(pk=report.pk).filter(superseded=False).update(superseded=True)
    return report


def _lock(comparison: Comparison, participant: Participant | None) -> Comparison:
    if participant is None:
        return Comparison.objects.select_for_update().get(pk=comparison.pk)
    held = _hold_status(comparison.pk)
    _lock_participant(participant)
    return held


def _hold_status(comparison_id: int, known: Comparison | None = None) -> Comparison:
    """The comparison whose report is about to be rendered, its status held until the
    report is stored.  Published is final: read as is.  Before publication the row is
    read ``FOR SHARE`` (PostgreSQL; other databases: ``FOR UPDATE``, a no-op on SQLite,
    which runs one writer at a time): publication's ``FOR UPDATE`` waits for this
    transaction, and a report that had to wait for a publication reads it, so a
    preliminary report is never stored after publication.  Participant reports of one
    comparison share the lock (they still render in parallel); the comparison's lock is
    always taken before the participant's, as the submission import does.  ``known``:
    the comparison as the caller read it, enough when it was published already."""
    found = known if known is not None else Comparison.objects.get(pk=comparison_id)
    if found.status == ComparisonStatus.PUBLISHED:
        return found
    connection = connections[router.db_for_write(Comparison)]
    if connection.vendor != "postgresql":
        return Comparison.objects.select_for_update().get(pk=comparison_id)
    table = connection.ops.quote_name(Comparison._meta.db_table)
    pk = connection.ops.quote_name(Comparison._meta.pk.column)
    query = f"SELECT * FROM {table} WHERE {pk} = %s FOR SHARE"
    return next(iter(Comparison.objects.raw(query, [comparison_id])))


def _issue_status(comparison: Comparison, authorised_by: str = "") -> str:
    """The status a report issued now carries (the comparison read under the lock):
    final once published, preliminary before; a published comparison's report is never
    preliminary (publication needs an authoriser, who cannot be removed afterwards)."""
    status = report_status(comparison, authorised_by)
    if comparison.status == ComparisonStatus.PUBLISHED and status != Report.Status.FINAL:
        raise StateConflict(
            f"{comparison.code} is published: its reports are final and need the name and "
            "role of the person authorising them."
        )
    return status


def _lock_participant(participant: Participant) -> None:
    """FOR UPDATE of the participant's row only.  ``order_by()``: Participant's default
    ordering joins its comparison, and FOR UPDATE locks every joined row: every report
    of a comparison then waited for the one being rendered (two workers ran one at a
    time)."""
    rows = Participant.objects.select_for_update(of=("self",)).filter(pk=participant.pk)
    list(rows.order_by().values_list("pk"))


def report_issue_once(*, run_id: int, kind: str, participant_id: int | None) -> Report | None:
    """Issue unless a current (not superseded) report of this run, for the comparison's
    status (preliminary / final), already exists.

    The task body: safe to run twice, even at once (the check is made under the report's
    lock). Returns None when the run is no longer current."""
    run = AnalysisRun.objects.select_related("comparison").get(pk=run_id)
    if current_run(run.comparison) != run:
        return None
    participant = Participant.objects.get(pk=participant_id) if participant_id else None
    return _issue(run.comparison, kind, participant, "", "", reuse=run)


def report_issue_batch(*, run_id: int, participant_ids: Sequence[int]) -> list[int]:
    """Issue the participant reports of run ``run_id`` for these participants, skipping
    those that already have a current report of the run; the ids of their reports (new
    or found), or [] when the run is no longer current.  The batch task's body.

    Safe twice, even at once: each report is its own transaction under its participant's
    row lock, which re-checks for a current report of the run first; a batch redelivered
    after a lost worker skips the reports already stored.  The run's shared data is read
    once per process (:func:`~analysis.reports.assemble.run_context`) and the batch's own
    rows in one query, so the queries per batch do not grow with the round."""
    run = AnalysisRun.objects.select_related("comparison").get(pk=run_id)
    comparison = run.comparison
    if current_run(comparison) != run:
        return []
    _check_reportable(comparison)
    ids = list(dict.fromkeys(participant_ids))
    done = dict(
        Report.objects.filter(
            run=run,
            kind=Report.Kind.PARTICIPANT,
            superseded=False,
            status=report_status(comparison),
            participant_id__in=ids,
        ).values_list("participant_id", "pk")
    )
    todo = [pk for pk in ids if pk not in done]
    if todo:
        participants = Participant.objects.in_bulk(todo)
        wrong = [
            pk
            for pk in todo
            if pk not in participants or participants[pk].comparison_id != comparison.pk
        ]
        if wrong:
            raise ValidationFailed(f"Participants {wrong} are not in {comparison.code}.")
        context = run_context(run)
        own = participant_rows(run, context, todo) if context.rows is None else {}
        common = comparison_common(comparison)
        histories = report_histories(run, list(participants.values()))
        _round_charts_build(run, participants[todo[0]], own, common, context, histories)
        for pk in todo:
            report = _issue_current(
                run, participants[pk], own.get(pk), common, context, histories[pk]
            )
            done[pk] = report.pk
    return [done[pk] for pk in ids]


def _round_charts_build(
    run: AnalysisRun,
    participant: Participant,
    own: dict[int, tuple[tuple[ResultRow, ...], tuple[ScoreRow, ...]]],
    common: ComparisonCommon,
    context: RunContext,
    histories: dict[int, ReportHistory],
) -> None:
    """Build every point chart of a large round once per process (a no-op afterwards),
    outside the reports' transactions: with at least as many participants as points,
    nearly every point is among some participant's worst and gets drawn anyway, so a
    worker pays for the round's charts up front instead of across its next reports."""
    if context.rows is not None or len(context.participants) < len(context.points):
        return
    data = report_data(
        run=run, participant=participant, own=own.get(participant.pk), common=common,
        context=context, history=histories[participant.pk],
    )  # fmt: skip
    point_charts_build(data)


@transaction.atomic
def _issue_current(
    run: AnalysisRun,
    participant: Participant,
    own: tuple[tuple[ResultRow, ...], tuple[ScoreRow, ...]] | None,
    common: ComparisonCommon,
    context: RunContext,
    own_history: ReportHistory,
) -> Report:
    """The current participant report of ``run`` for the comparison's status (read under
    the locks: :func:`_hold_status`): found under the participant's row lock, else
    rendered and stored (superseding the older versions, a preliminary one included)."""
    status = _issue_status(_hold_status(run.comparison_id, known=run.comparison))
    _lock_participant(participant)
    history = list(
        Report.objects.filter(
            comparison_id=run.comparison_id, kind=Report.Kind.PARTICIPANT, participant=participant
        )
        .order_by("version")
        .values_list("pk", "run_id", "version", "superseded", "status")
    )
    current = [
        pk
        for pk, run_id, _, superseded, made_for in history
        if run_id == run.pk and not superseded and made_for == status
    ]
    newer = [pk for pk, run_id, *_ in history if run_id is not None and run_id > run.pk]
    if current or newer:  # newer: a later run became current during this batch
        return Report.objects.get(pk=(current or newer)[-1])
    edition = report_edition([r for _, r, *_ in history], run)
    data = report_data(
        run=run, participant=participant, edition=edition, own=own, common=common,
        context=context, status=status, history=own_history,
    )  # fmt: skip
    version = max((v for _, _, v, *_ in history), default=0) + 1
    pdf = render_report(data)
    report = _store(run, Report.Kind.PARTICIPANT, participant, version, pdf, status)
    older = [pk for pk, _, _, superseded, _ in history if not superseded]
    if older:
        Report.objects.filter(pk__in=older).update(superseded=True)
    return report


def _store(
    run: AnalysisRun,
    kind: str,
    participant: Participant | None,
    version: int,
    pdf: bytes,
    status: str,
) -> Report:
    report = Report(
        comparison=run.comparison,
        run=run,
        kind=kind,
        participant=participant,
        version=version,
        status=status,
        sha256=hashlib.sha256(pdf).hexdigest(),
        size=len(pdf),
        software_version=proficiency.__version__,
    )
    report.file.save(f"{report.token}.pdf", ContentFile(pdf), save=False)
    report.save()
    return report


def report_jobs(comparison: Comparison) -> list[tuple[int, str, int | None]]:
    """(run id, kind, participant id) of every report a comparison's current run needs."""
    run = _reportable_run(comparison)
    jobs: list[tuple[int, str, int | None]] = [(run.pk, Report.Kind.SUMMARY, None)]
    ids = comparison.participants.order_by("code").values_list("pk", flat=True)
    return jobs + [(run.pk, Report.Kind.PARTICIPANT, pk) for pk in ids]


def report_batches(comparison: Comparison, size: int | None = None) -> tuple[int, list[list[int]]]:
    """The current run's id and its participants' ids in code order, in batches of
    ``size`` (default ``settings.REPORTS_BATCH_SIZE``, 25): one task each.  Refreshes
    the planner's statistics of the tables the batches read
    (:func:`analysis.bulk.planner_stats_refresh`)."""
    step = _batch_size(size)
    run = _reportable_run(comparison)
    planner_stats_refresh()
    ids = list(comparison.participants.order_by("code").values_list("pk", flat=True))
    return run.pk, _in_batches(ids, step)


def _batch_size(size: int | None) -> int:
    return size if size else int(getattr(settings, "REPORTS_BATCH_SIZE", 25))


def _in_batches(ids: Sequence[int], step: int) -> list[list[int]]:
    return [list(ids[i : i + step]) for i in range(0, len(ids), step)]


def reports_issue_all(*, comparison: Comparison) -> list[Report]:
    """Summary + one report per participant, synchronously (the task fans them out)."""
    run_id, batches = report_batches(comparison)
    summary = report_issue_once(run_id=run_id, kind=Report.Kind.SUMMARY, participant_id=None)
    if summary is None:
        return []
    ids = [
        pk for batch in batches for pk in report_issue_batch(run_id=run_id, participant_ids=batch)
    ]
    found = Report.objects.in_bulk(ids)
    return [summary, *(found[pk] for pk in ids)]


# --- report batches: the fan-out's job rows (docs/lifecycles.md §4) ----------------------


def report_batches_create(*, comparison: Comparison, size: int | None = None) -> list[ReportBatch]:
    """The job rows issuing the current run's reports for the comparison's status: the
    summary, then the participants in code order in batches of ``size``
    (:func:`report_batches`); every row of that run and status, the summary first.

    Made once: a second fan-out, even at the same time, finds them (unique per run, report
    status, kind and index, inserted with ``ON CONFLICT DO NOTHING``); only participants in
    no batch yet (added since, or batched with another size) get new batches after the
    last one."""
    run_id, batches = report_batches(comparison, size)
    status = report_status(comparison)
    rows = ReportBatch.objects.filter(run_id=run_id, report_status=status)
    known = list(
        rows.filter(kind=ReportBatch.Kind.PARTICIPANTS).values_list("index", "participant_ids")
    )
    first = 0
    if known:
        covered = {pk for _, ids in known for pk in ids}
        left = [pk for batch in batches for pk in batch if pk not in covered]
        batches, first = _in_batches(left, _batch_size(size)), 1 + max(i for i, _ in known)
    made = {"comparison_id": comparison.pk, "run_id": run_id, "report_status": status}
    summary = ReportBatch(**made, kind=ReportBatch.Kind.SUMMARY)
    ReportBatch.objects.bulk_create(
        [summary, *(ReportBatch(**made, kind=ReportBatch.Kind.PARTICIPANTS, index=first + i,
                                participant_ids=ids) for i, ids in enumerate(batches))],
        ignore_conflicts=True,
    )  # fmt: skip
    return list(rows.order_by("-kind", "index"))


def report_batches_send(*, comparison: Comparison) -> int:
    """The fan-out, ``reports_issue_all_task``'s body: the run's batch rows
    (:func:`report_batches_create`) and a task for each that needs one: pending and not
    sent within ``JOB_STALE_SECONDS``, failed, or done but missing a report since (one
    deleted); a running row is left to its task (and to the sweep if it goes silent).  A
    failed or incomplete row goes back to pending first, keeping its attempts and error.

    Safe twice, even at once: a row is reset and sent by conditional UPDATEs, so a
    fan-out delivered twice sends each task once.  The number of reports the run needs."""
    rows = report_batches_create(comparison=comparison)
    issued = set(
        Report.objects.filter(
            run_id=rows[0].run_id, status=rows[0].report_status, superseded=False
        ).values_list("participant_id", flat=True)
    )  # None: the summary
    for row in rows:
        wanted = {None} if row.kind == ReportBatch.Kind.SUMMARY else set(row.participant_ids)
        if row.status == B.RUNNING or (row.status == B.DONE and wanted <= issued):
            continue
        if row.status in (B.DONE, B.FAILED):
            again = ReportBatch.objects.filter(pk=row.pk, status=row.status)
            if not again.update(status=B.PENDING, token="", heartbeat_at=None):
                continue  # reset or claimed by another fan-out meanwhile
            row.status, row.heartbeat_at = B.PENDING, None
        if row.heartbeat_at is None or row.heartbeat_at < jobs.stale_before():
            _batch_send(row)
    return 1 + sum(len(r.participant_ids) for r in rows if r.kind == ReportBatch.Kind.PARTICIPANTS)


def _batch_send(row: ReportBatch) -> bool:
    """Send the task of ``row`` under a new Celery id, unless another fan-out, sweep or
    task moved the row's heartbeat since it was read (``common.jobs.lease``): the id is
    written as ``claimed_by``, so a running row's task takes the claim over.  Whether
    sent; with the broker unreachable the row waits for the sweep."""
    task_id = uuid()
    if not jobs.lease(ReportBatch.objects.all(), pk=row.pk, status=row.status,
                      heartbeat_at=row.heartbeat_at, claimed_by=task_id):  # fmt: skip
        return False
    task: Any
    args: tuple[Any, ...]
    if row.kind == ReportBatch.Kind.SUMMARY:
        task, args = report_issue_task, (row.run_id, Report.Kind.SUMMARY, None, row.pk)
    else:
        task, args = report_issue_batch_task, (row.run_id, row.participant_ids, row.pk)
    what = f"report batch {row.pk} (run {row.run_id}, {row.kind} {row.index})"
    return jobs.send(task, args, task_id=task_id, what=what)


def _batch_claim(batch_id: int, delivery: str) -> str | None:
    """pending → running; or take over a running row whose heartbeat is stale, or that
    this very task (``delivery``: its Celery id, redelivered, or the one the sweep sent)
    had claimed (``common.jobs.claim``).  The claim's new token, or None."""
    token = secrets.token_hex(16)
    claim = {"token": token, "started_at": timezone.now(), "attempts": F("attempts") + 1}
    rows = ReportBatch.objects.filter(pk=batch_id)
    fresh = {"status": B.RUNNING, "error": "", "report_ids": [], **claim}
    return token if jobs.claim(rows, delivery=delivery, fresh=fresh, takeover=claim) else None


def report_batch_execute(*, batch_id: int, delivery: str = "") -> list[int]:
    """The body of a report task sent with its batch row: claim row ``batch_id`` and issue
    its reports (the summary, :func:`report_issue_once`, or the batch's participant
    reports, :func:`report_issue_batch`), its heartbeat beating while they render; then
    the row is done with the ids of its reports, or failed with the error (whatever the
    error: a row is never left running by a task that ended).  ``delivery``: this task's
    Celery id.  A row done, failed or held by a live task is left as it is.

    The ids of the batch's reports (none when it failed or another task holds it)."""
    token = _batch_claim(batch_id, delivery)
    row = ReportBatch.objects.filter(pk=batch_id).first()
    if row is None:  # deleted with its run or comparison
        return []
    if token is None:  # done, failed, or held by a live task
        return list(row.report_ids) if row.status == B.DONE else []
    beat = partial(jobs.beat, ReportBatch, batch_id, status=B.RUNNING, token=token)
    with heartbeat(beat, f"report batch {batch_id}"):
        outcome = _batch_outcome(row)
    now = timezone.now()
    ReportBatch.objects.filter(pk=batch_id, status=B.RUNNING, token=token).update(
        **outcome, finished_at=now, heartbeat_at=now
    )  # not if taken over meanwhile: the task that took it over ends it
    return list(outcome["report_ids"])


def _batch_outcome(row: ReportBatch) -> dict[str, Any]:
    """Issue the row's reports: the fields of its end, done or failed."""
    try:
        if row.kind == ReportBatch.Kind.SUMMARY:
            summary = report_issue_once(run_id=row.run_id, kind=Report.Kind.SUMMARY,
                                        participant_id=None)  # fmt: skip
            ids = [summary.pk] if summary is not None else []
        else:
            ids = report_issue_batch(run_id=row.run_id, participant_ids=row.participant_ids)
    except ApplicationError as exc:
        return {"status": B.FAILED, "error": exc.message, "report_ids": []}
    except Exception as exc:  # any other error is shown too, never a row stuck running
        log.exception("report batch %s of run %s failed", row.pk, row.run_id)
        return {"status": B.FAILED, "error": f"{type(exc).__name__}: {exc}", "report_ids": []}
    return {"status": B.DONE, "error": "", "report_ids": ids}  # []: the run is no longer current


def report_batches_sweep() -> int:
    """Celery beat (``jobs_sweep_task``): send again the report batches silent for
    ``JOB_STALE_SECONDS``: pending ones never sent or whose message was lost (not claimed
    since they were sent), running ones whose worker was lost (no heartbeat); the task
    sent takes the claim over.  Each send is decided by a conditional UPDATE, so two
    sweeps at once send it once.  A failed batch is not retried here: the next fan-out of
    its comparison retries it (:func:`report_batches_send`; for a published comparison
    still missing reports, ``reports_pending_task``).  The number of tasks sent."""
    silent = ReportBatch.objects.filter(
        jobs.silent("created_at"), status__in=(B.PENDING, B.RUNNING)
    ).order_by("pk")
    sent = 0
    for row in silent:
        log.warning("report batch %s of run %s silent since %s: queued again", row.pk,
                    row.run_id, row.heartbeat_at or row.created_at)  # fmt: skip
        sent += _batch_send(row)
    return sent


def _send_reports_task(comparison_id: int) -> bool:
    """Send the fan-out; with the broker unreachable it is logged (``common.jobs.send``):
    the published comparison still missing reports is what :func:`reports_pending_enqueue`
    sends again."""
    what = f"reports of comparison {comparison_id}"
    return jobs.send(reports_issue_all_task, (comparison_id,), what=what)


def reports_missing(comparison: Comparison) -> int:
    """How many reports (summary + one per participant) of the current run are not issued
    for the comparison's status (a preliminary report of a published comparison is missing
    its final version)."""
    run = current_run(comparison)
    if run is None:
        return 0
    issued = Report.objects.filter(run=run, superseded=False, status=report_status(comparison))
    n_issued = issued.values("kind", "participant").distinct().count()
    return 1 + comparison.participants.count() - n_issued


def reports_preliminary_supersede(*, comparison: Comparison) -> int:
    """Publication's step, in its transaction: every current preliminary report (summary
    and participants') becomes superseded; the report tasks issue the final versions.
    The number superseded; idempotent."""
    current = Report.objects.filter(comparison=comparison, superseded=False)
    return current.exclude(status=Report.Status.FINAL).update(superseded=True)


def reports_pending_enqueue() -> int:
    """Beat task body: send the fan-out of every published comparison that still misses
    reports (lost enqueue, broker down at publication, a failed batch); the number sent.
    The fan-out makes the batch rows if there are none yet and sends only the batches to
    do (:func:`report_batches_send`), so a comparison whose reports are still rendering
    is safe."""
    pending = Comparison.objects.filter(status=ComparisonStatus.PUBLISHED).order_by("pk")
    return sum(_send_reports_task(c.pk) for c in pending if reports_missing(c) > 0)


# --- the final reports of a publication, rendered before it (docs/lifecycles.md §1, §4) ---


@dataclass(frozen=True)
class FinalReports:
    """The final reports of a run rendered before publication: unsaved rows, their files
    written, and the edition each prints (None: the summary)."""

    reports: list[Report]
    editions: dict[int | None, int]


def final_reports_render(
    *, run: AnalysisRun, progress: Callable[[int, int], object] | None = None
) -> FinalReports:
    """Render every final report of ``run`` (the summary, then the participants in code
    order, their rows read a batch at a time) while its comparison is still analysed:
    the status "final" is given to the renderer, so the bytes are those a report issued
    after publication has (same number, same sha256).  Each PDF is written to storage at
    once; the rows are returned unsaved: :func:`final_reports_store` saves them in the
    publication's transaction, :func:`final_reports_discard` deletes the files of a
    publication that did not happen (and of every report rendered before an error here).
    ``progress(done, total)`` after each report."""
    comparison = run.comparison
    ids = list(comparison.participants.order_by("code").values_list("pk", flat=True))
    total, staged = 1 + len(ids), list[Report]()
    editions = _final_editions(run)
    try:
        context, common = run_context(run), comparison_common(comparison)
        summary = report_data(run=run, edition=editions[None], common=common, context=context,
                              status=Report.Status.FINAL)  # fmt: skip
        staged.append(_stage(run, Report.Kind.SUMMARY, None, render_report(summary)))
        if progress is not None:
            progress(len(staged), total)
        for batch in _in_batches(ids, _batch_size(None)):
            participants = Participant.objects.in_bulk(batch)
            own = participant_rows(run, context, batch) if context.rows is None else {}
            histories = report_histories(run, list(participants.values()))
            _round_charts_build(run, participants[batch[0]], own, common, context, histories)
            for pk in batch:
                data = report_data(
                    run=run, participant=participants[pk], edition=editions[pk],
                    own=own.get(pk), common=common, context=context, status=Report.Status.FINAL,
                    history=histories[pk],
                )  # fmt: skip
                staged.append(_stage(run, Report.Kind.PARTICIPANT, participants[pk],
                                     render_report(data)))  # fmt: skip
                if progress is not None:
                    progress(len(staged), total)
    except BaseException:
        final_reports_discard(FinalReports(staged, editions))
        raise
    return FinalReports(staged, editions)


def _final_editions(run: AnalysisRun) -> dict[int | None, int]:
    """The edition each report of ``run`` prints (None: the summary), from the versions
    issued so far (:func:`report_edition`)."""
    history: dict[int | None, list[int | None]] = {}
    rows = Report.objects.filter(comparison_id=run.comparison_id).order_by("version", "pk")
    for participant_id, run_id in rows.values_list("participant_id", "run_id"):
        history.setdefault(participant_id, []).append(run_id)
    ids = run.comparison.participants.values_list("pk", flat=True)
    return {pk: report_edition(history.get(pk, []), run) for pk in [None, *ids]}


def _stage(run: AnalysisRun, kind: str, participant: Participant | None, pdf: bytes) -> Report:
    """The unsaved row of a rendered report, its file written (version 0 until stored)."""
    report = Report(
        comparison=run.comparison, run=run, kind=kind, participant=participant, version=0,
        status=Report.Status.FINAL, sha256=hashlib.sha256(pdf).hexdigest(), size=len(pdf),
        software_version=proficiency.__version__,
    )  # fmt: skip
    report.file.save(f"{report.token}.pdf", ContentFile(pdf), save=False)
    return report


def final_reports_store(*, run: AnalysisRun, rendered: FinalReports) -> list[Report]:
    """Publication's step, in its transaction (the comparison's row locked by it): save
    the reports :func:`final_reports_render` made as the current versions, superseding
    every older one.  Refused (nothing saved) when a report was issued meanwhile for
    another run, which would change the edition printed in them."""
    if _final_editions(run) != rendered.editions:
        raise StateConflict(
            f"Reports of {run.comparison.code} were issued for another run meanwhile; "
            "publish again."
        )
    older = Report.objects.filter(comparison_id=run.comparison_id)
    last = older.order_by().values("kind", "participant_id").annotate(v=Max("version"))
    versions = {(r["kind"], r["participant_id"]): r["v"] for r in last}
    for report in rendered.reports:
        report.version = versions.get((report.kind, report.participant_id), 0) + 1
    older.filter(superseded=False).update(superseded=True)
    return Report.objects.bulk_create(rendered.reports)


def final_reports_discard(rendered: FinalReports) -> None:
    """Delete the files of rendered reports that were not stored."""
    for report in rendered.reports:
        if report.file:
            report.file.delete(save=False)
