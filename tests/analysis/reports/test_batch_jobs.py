"""Report batches as job rows (``ReportBatch``): made once per run and report status by the
fan-out, claimed by the protocol of ``common.jobs``, ended done or failed, re-queued by
the stale-job sweep and retried by the next fan-out (docs/lifecycles.md §4).

Eager Celery, SQLite or PostgreSQL; the tests of heartbeats and of two fan-outs at once
need PostgreSQL (``needs_postgres``).  tests/faults/test_report_batch_killed.py loses a
real worker in the middle of a batch."""

import datetime as dt
import threading
import time

import pytest
from django.db import connections
from django.utils import timezone
from kombu.exceptions import OperationalError

from analysis.models import Report, ReportBatch
from analysis.reports import services
from analysis.reports.services import (
    report_batch_execute,
    report_batches_create,
    report_batches_send,
    report_batches_sweep,
    reports_missing,
    reports_pending_enqueue,
)
from analysis.reports.tasks import report_issue_batch_task, report_issue_task
from analysis.reports.tasks import reports_issue_all_task as fan_out
from analysis.tasks import jobs_sweep_task
from labs.models import Laboratory, Participant
from tests.analysis.reports.conftest import published_missing_reports
from tests.analysis.reports.test_batches import make_round

pytestmark = pytest.mark.django_db(transaction=True)


@pytest.fixture(autouse=True)
def batches_of_five(settings):
    settings.REPORTS_BATCH_SIZE = 5  # the demo's 12 participants: batches of 5, 5 and 2


@pytest.fixture
def renders(monkeypatch):
    """A stand-in PDF; the (participant code or None, status) of every report rendered."""
    rendered: list[tuple[str | None, str]] = []

    def render(data):
        rendered.append((data.own_code, data.status))
        return f"%PDF-1.4 {data.report_number} {data.status}".encode()

    monkeypatch.setattr("analysis.reports.services.render_report", render)
    return rendered


@pytest.fixture
def published(analysed, renders):
    """The demo published without its final reports (published before publication rendered
    them itself): no batch row and no report yet."""
    comparison = published_missing_reports(analysed.comparison)
    assert not ReportBatch.objects.exists() and not Report.objects.exists()
    return comparison


def long_ago() -> dt.datetime:
    return timezone.now() - dt.timedelta(hours=2)


def table(comparison) -> list[tuple]:
    """(kind, index, participants, status, attempts) of every batch row, summary first."""
    rows = ReportBatch.objects.filter(comparison=comparison)
    return list(rows.values_list("kind", "index", "participant_ids", "status", "attempts"))


def codes(comparison) -> list[int]:
    return list(comparison.participants.order_by("code").values_list("pk", flat=True))


def one_current_final_each(comparison) -> None:
    current = Report.objects.filter(comparison=comparison, superseded=False)
    keys = list(current.values_list("kind", "participant_id", "status"))
    assert sorted(keys, key=str) == sorted(
        [("summary", None, "final")] + [("participant", pk, "final") for pk in codes(comparison)],
        key=str,
    )


def test_the_fan_out_makes_the_batch_rows_once(analysed, published, renders):
    comparison = published
    assert fan_out(comparison.pk) == 13  # eager: issued now
    ids = codes(comparison)
    expected = [
        ("summary", 0, [], "done", 1),
        ("participants", 0, ids[:5], "done", 1),
        ("participants", 1, ids[5:10], "done", 1),
        ("participants", 2, ids[10:], "done", 1),
    ]
    assert table(comparison) == expected
    rows = list(ReportBatch.objects.all())
    assert {(r.run_id, r.report_status, r.error) for r in rows} == {(analysed.pk, "final", "")}
    assert all(r.started_at and r.finished_at and r.token and r.claimed_by for r in rows)
    issued = {r.pk: (r.participant_id, r.run_id) for r in Report.objects.filter(superseded=False)}
    assert sorted(pk for r in rows for pk in r.report_ids) == sorted(issued)
    assert [issued[pk][0] for pk in rows[1].report_ids] == ids[:5]
    one_current_final_each(comparison)
    n_rendered, finished = len(renders), {r.pk: r.finished_at for r in rows}

    assert fan_out(comparison.pk) == 13  # delivered again
    assert fan_out.delay(comparison.pk).get() == 13  # and again, through Celery
    assert table(comparison) == expected  # no new row, nothing claimed again
    assert {r.pk: r.finished_at for r in ReportBatch.objects.all()} == finished
    assert len(renders) == n_rendered and Report.objects.count() == 13


def test_a_second_fan_out_with_another_batch_size_keeps_the_rows(published, settings):
    assert [len(r.participant_ids) for r in report_batches_create(comparison=published)] == [
        0, 5, 5, 2,
    ]  # fmt: skip
    settings.REPORTS_BATCH_SIZE = 4
    again = report_batches_create(comparison=published)
    assert [len(r.participant_ids) for r in again] == [0, 5, 5, 2]
    # a participant in no batch yet (added since) gets a batch of its own after the last
    lab = Laboratory.objects.create(name="Late Metrology")
    late = Participant.objects.create(comparison=published, laboratory=lab, code="ZZ-LATE")
    rows = report_batches_create(comparison=published)
    assert [(r.kind, r.index, r.participant_ids) for r in rows][-1:] == [
        ("participants", 3, [late.pk])
    ]
    assert ReportBatch.objects.count() == 5
    assert report_batches_send(comparison=published) == 14
    assert set(ReportBatch.objects.values_list("status", flat=True)) == {"done"}
    assert reports_missing(published) == 0


def test_two_fan_outs_at_once_make_each_row_once_and_send_each_task_once(
    needs_postgres, published, monkeypatch
):
    sent: list[tuple] = []

    def send(task, args, **options) -> bool:  # the broker: recorded
        sent.append((task.name, args))
        return True

    monkeypatch.setattr(services.jobs, "send", send)
    barrier, errors = threading.Barrier(2), []

    def fan() -> None:
        try:
            barrier.wait(10)
            report_batches_send(comparison=published)
        except BaseException as exc:
            errors.append(exc)
        finally:
            connections.close_all()

    threads = [threading.Thread(target=fan) for _ in range(2)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(30)
    assert not errors
    rows = list(ReportBatch.objects.all())
    assert [(r.kind, r.index) for r in rows] == [("summary", 0)] + [
        ("participants", i) for i in range(3)
    ]
    assert sorted(args[-1] for _, args in sent) == sorted(r.pk for r in rows)  # once each
    assert {r.status for r in rows} == {"pending"}
    assert all(r.claimed_by and r.heartbeat_at for r in rows)  # leased: marked as sent


def test_a_batch_delivered_twice_issues_each_report_once_and_ends_done(published, renders):
    summary, first_batch, *_ = report_batches_create(comparison=published)
    ids = first_batch.participant_ids
    args = (first_batch.run_id, ids, first_batch.pk)
    first = report_issue_batch_task.apply(args=args, task_id="first").get()
    again = report_issue_batch_task.apply(args=args, task_id="second").get()  # a duplicate
    assert again == first and len(first) == 5
    row = ReportBatch.objects.get(pk=first_batch.pk)
    assert (row.status, row.attempts, row.claimed_by, row.report_ids) == ("done", 1, "first", first)
    reports = Report.objects.filter(pk__in=first)
    assert sorted(reports.values_list("participant_id", "version", "status")) == sorted(
        (pk, 1, "final") for pk in ids
    )
    assert len(renders) == 5
    # the summary's task likewise
    summary_args = (summary.run_id, "summary", None, summary.pk)
    made = report_issue_task.apply(args=summary_args, task_id="s1").get()
    assert report_issue_task.apply(args=summary_args, task_id="s2").get() == made
    row = ReportBatch.objects.get(pk=summary.pk)
    assert (row.status, row.attempts, row.report_ids) == ("done", 1, [made])
    assert Report.objects.filter(kind="summary").count() == 1 and len(renders) == 6


def test_messages_without_a_batch_row_still_issue_their_reports(published, renders):
    """Messages queued before the rows existed: the old arguments, no row."""
    run = published.analysis_runs.get(status="succeeded")
    ids = codes(published)[:3]
    assert len(report_issue_batch_task.apply(args=(run.pk, ids)).get()) == 3
    assert report_issue_task.apply(args=(run.pk, "summary", None)).get() is not None
    assert Report.objects.count() == 4 and not ReportBatch.objects.exists()


def test_a_live_batch_is_never_taken_over_and_its_redelivery_takes_it_over(published, renders):
    _, batch, *_ = report_batches_create(comparison=published)
    assert services._batch_claim(batch.pk, "dead")  # claimed; its worker dies later
    args = (batch.run_id, batch.participant_ids, batch.pk)
    assert report_issue_batch_task.apply(args=args, task_id="other").get() == []  # held
    assert report_batches_sweep() == 0  # its heartbeat is fresh: alive for all we know
    row = ReportBatch.objects.get(pk=batch.pk)
    assert (row.status, row.attempts, row.claimed_by) == ("running", 1, "dead")
    assert not Report.objects.exists()
    # the same message delivered again after its worker was lost (acks_late)
    ids = report_issue_batch_task.apply(args=args, task_id="dead").get()
    row.refresh_from_db()
    assert (row.status, row.attempts, row.claimed_by, row.report_ids) == ("done", 2, "dead", ids)
    assert Report.objects.count() == 5


def test_a_stale_batch_is_re_queued_by_the_sweep_and_finishes(published, renders):
    rows = report_batches_create(comparison=published)
    batch = rows[1]
    assert services._batch_claim(batch.pk, "dead")
    lost_on = batch.participant_ids[1]  # issued one report, then the worker was lost
    services.report_issue_batch(run_id=batch.run_id, participant_ids=batch.participant_ids[:2])
    ReportBatch.objects.filter(pk=batch.pk).update(heartbeat_at=long_ago())
    assert jobs_sweep_task()["reports"] == 1  # the batch's task again (eager: done now)
    row = ReportBatch.objects.get(pk=batch.pk)
    assert (row.status, row.attempts, row.error) == ("done", 2, "")
    assert row.claimed_by not in ("", "dead")  # the task the sweep sent
    assert len(row.report_ids) == 5
    mine = Report.objects.filter(participant_id__in=batch.participant_ids)
    assert mine.count() == 5 and set(mine.values_list("version", flat=True)) == {1}
    assert [code for code, _ in renders].count(
        Participant.objects.get(pk=lost_on).code
    ) == 1  # stored before the loss: not rendered again
    # the other rows were made just now and are not silent: left alone
    assert table(published)[0][3] == "pending" and table(published)[2][3] == "pending"
    assert report_batches_sweep() == 0
    # the lost task's own redelivery, much later: a no-op
    args = (batch.run_id, batch.participant_ids, batch.pk)
    assert report_issue_batch_task.apply(args=args, task_id="dead").get() == row.report_ids
    assert ReportBatch.objects.get(pk=batch.pk).attempts == 2


def test_pending_batches_whose_messages_were_lost_are_sent_by_the_sweep(published, renders):
    report_batches_create(comparison=published)  # made, never sent (the fan-out lost)
    assert report_batches_sweep() == 0  # just made
    ReportBatch.objects.update(created_at=long_ago())
    assert report_batches_sweep() == 4
    assert {r[3] for r in table(published)} == {"done"}
    one_current_final_each(published)
    assert report_batches_sweep() == 0 and reports_missing(published) == 0


def test_a_batch_sent_while_the_broker_is_down_is_sent_by_the_sweep(published, monkeypatch):
    def refused(args, kwargs=None, **options):
        raise OperationalError("Error 111 connecting to 127.0.0.1:6399. Connection refused.")

    with monkeypatch.context() as m:
        m.setattr("analysis.reports.tasks.report_issue_batch_task.apply_async", refused)
        assert reports_pending_enqueue() == 1  # the fan-out ran; its batches could not be sent
        assert [r[3] for r in table(published)] == ["done", "pending", "pending", "pending"]
        assert report_batches_sweep() == 0  # sent a moment ago, as far as the rows know
    assert reports_pending_enqueue() == 1 and Report.objects.count() == 1  # not again
    ReportBatch.objects.filter(status="pending").update(heartbeat_at=long_ago())
    assert report_batches_sweep() == 3
    assert [r[3:] for r in table(published)] == [("done", 1)] * 4
    one_current_final_each(published)


def test_a_slow_batch_keeps_its_claim_by_its_heartbeat(needs_postgres, published, settings,
                                                       monkeypatch):  # fmt: skip
    settings.JOB_HEARTBEAT_SECONDS, settings.JOB_STALE_SECONDS = 0.1, 0.6
    _, batch, *_ = report_batches_create(comparison=published)
    ReportBatch.objects.exclude(pk=batch.pk).delete()  # the sweep would send them: silent
    sweeps: list[int] = []

    def slow(data):  # 2.5 stale periods on its first report, swept in the middle of it
        if not sweeps:
            time.sleep(1.2)
            sweeps.append(report_batches_sweep())
            time.sleep(0.3)
        return f"%PDF-1.4 {data.report_number}".encode()

    monkeypatch.setattr("analysis.reports.services.render_report", slow)
    args = (batch.run_id, batch.participant_ids, batch.pk)
    assert len(report_issue_batch_task.apply(args=args, task_id="slow").get()) == 5
    assert sweeps == [0]
    row = ReportBatch.objects.get(pk=batch.pk)
    assert (row.status, row.attempts, row.claimed_by) == ("done", 1, "slow")


def test_an_error_in_rendering_fails_the_batch_and_the_next_fan_out_retries_it(
    analysed, monkeypatch
):
    """The batch ends failed with the error (never running); the round stays published
    (a publication whose rendering fails publishes nothing: test_publication_jobs); the
    sweep leaves a failed batch alone; Celery beat's ``reports_pending_task`` sends the
    fan-out again while reports are missing, which retries it (and only it)."""
    comparison = analysed.comparison
    ids = codes(comparison)
    broken = comparison.participants.get(pk=ids[1]).code
    rendered: list[str | None] = []

    def render(data):
        if data.own_code == broken:
            raise RuntimeError("the disk is full")
        rendered.append(data.own_code)
        return f"%PDF-1.4 {data.report_number} {data.status}".encode()

    monkeypatch.setattr("analysis.reports.services.render_report", render)
    comparison = published_missing_reports(comparison)
    assert fan_out(comparison.pk) == 13
    assert [r[3:] for r in table(comparison)] == [
        ("done", 1), ("failed", 1), ("done", 1), ("done", 1),
    ]  # fmt: skip
    failed = ReportBatch.objects.get(status="failed")
    assert failed.error == "RuntimeError: the disk is full"
    assert failed.finished_at is not None and failed.report_ids == []
    assert reports_missing(comparison) == 4  # the batch's first report was stored
    assert jobs_sweep_task()["reports"] == 0  # not the sweep's to retry
    assert ReportBatch.objects.get(pk=failed.pk).status == "failed"

    assert reports_pending_enqueue() == 1  # beat, while it still fails: failed again
    failed.refresh_from_db()
    assert (failed.status, failed.attempts, failed.error) == (
        "failed", 2, "RuntimeError: the disk is full",
    )  # fmt: skip
    broken = "nobody"  # the disk has room again
    assert reports_pending_enqueue() == 1
    failed.refresh_from_db()
    assert (failed.status, failed.attempts, failed.error) == ("done", 3, "")
    assert [r[4] for r in table(comparison)] == [1, 3, 1, 1]  # only the failed one again
    assert rendered.count(comparison.participants.get(pk=ids[0]).code) == 1  # kept
    one_current_final_each(comparison)
    assert reports_missing(comparison) == 0 and reports_pending_enqueue() == 0


def test_a_rule_broken_fails_the_batch_with_its_message(published, renders):
    stranger = make_round("OTHER", 1, 1).participants.get()
    row = ReportBatch.objects.create(
        comparison=published, run=published.analysis_runs.get(status="succeeded"),
        report_status="final", kind="participants", participant_ids=[stranger.pk],
    )  # fmt: skip
    assert report_batch_execute(batch_id=row.pk, delivery="t") == []
    row.refresh_from_db()
    assert row.status == "failed"
    assert row.error == f"Participants [{stranger.pk}] are not in {published.code}."


def test_a_done_batch_missing_a_report_since_is_done_again(published, renders):
    comparison = published
    assert fan_out(comparison.pk) == 13
    lost = Report.objects.get(participant_id=codes(comparison)[7])
    lost.delete()  # e.g. in the admin
    assert reports_missing(comparison) == 1
    assert reports_pending_enqueue() == 1
    assert [r[4] for r in table(comparison)] == [1, 1, 2, 1]  # the batch of participant 7
    one_current_final_each(comparison)
