"""Participant reports issued in batches: one task per batch, idempotent
when delivered twice, the same bytes as the in-process render, the round's shared data
read once per run, and a number of queries per batch that does not grow with the round."""

import hashlib

import numpy as np
import pytest
from django.db import connection
from django.test.utils import CaptureQueriesContext

from analysis.models import Report, Score
from analysis.reports import assemble, charts, sections
from analysis.reports.assemble import clear_run_contexts, report_data, run_context
from analysis.reports.data import ReportData
from analysis.reports.render import render_report
from analysis.reports.services import report_batches, report_issue_batch, report_issue_once
from analysis.reports.tasks import report_issue_batch_task, reports_issue_all_task
from analysis.selectors import current_run
from analysis.services import analysis_run_start
from common.errors import ValidationFailed
from labs.models import Laboratory, Participant, Result, Submission
from proficiency.models import Comparison, Device
from proficiency.services import measurement_points_generate
from tests.conftest import use_stand_in_pdf

pytestmark = pytest.mark.django_db(transaction=True)


@pytest.fixture(autouse=True)
def fresh_contexts():
    clear_run_contexts()
    yield
    clear_run_contexts()


@pytest.fixture
def large(monkeypatch):
    """Every round counts as large: a participant report carries its own rows only."""
    monkeypatch.setattr(assemble, "FULL_TABLE_ROWS", 10)
    monkeypatch.setattr(sections, "FULL_TABLE_ROWS", 10)


def make_round(code: str, n_labs: int, n_freqs: int = 3) -> Comparison:
    """A published comparison of ``n_labs`` labs x ``n_freqs`` points, analysed (seeded)."""
    c = Comparison.objects.create(
        code=code, title=f"Batch test {code}", status="closed",
        assigned_value_method="weighted_mean", sigma_pt_mode="relative", sigma_pt_value=1.0,
    )  # fmt: skip
    device = Device.objects.create(comparison=c, name="MEMS 0")
    measurement_points_generate(
        comparison=c, devices=[device], axes=["X"],
        frequencies_hz=[10.0 * (i + 1) for i in range(n_freqs)], benches=["linear"],
    )  # fmt: skip
    points = list(c.measurement_points.values_list("id", flat=True))
    rng = np.random.default_rng(5)
    results = []
    for i in range(n_labs):
        lab = Laboratory.objects.create(name=f"{code} lab {i}")
        part = Participant.objects.create(comparison=c, laboratory=lab, code=f"L{i:03d}")
        sub = Submission.objects.create(participant=part, version=1, status="accepted")
        results += [
            Result(submission=sub, measurement_point_id=pid, value=100 + rng.normal(0, 1),
                   unit="mV/(m/s²)", expanded_uncertainty=rng.uniform(1, 3), coverage_factor=2.0)
            for pid in points
        ]  # fmt: skip
    Result.objects.bulk_create(results)
    analysis_run_start(comparison=c, user=None)
    Comparison.objects.filter(pk=c.pk).update(  # publication needs the authoriser
        status="published", authorised_by_name="A. Signer", authorised_by_role="Head"
    )
    c.refresh_from_db()
    assert current_run(c) is not None
    return c


def test_batches_cover_every_participant_in_code_order(analysed):
    run_id, batches = report_batches(analysed.comparison, size=5)
    codes = list(analysed.comparison.participants.order_by("code").values_list("pk", flat=True))
    assert run_id == analysed.pk
    assert [len(b) for b in batches] == [5, 5, 2]
    assert [pk for b in batches for pk in b] == codes


def test_fan_out_sends_the_summary_and_one_task_per_batch(stand_in_pdf, analysed, settings):
    settings.REPORTS_BATCH_SIZE = 5
    assert reports_issue_all_task(analysed.comparison.pk) == 13  # eager: issued inline
    reports = Report.objects.filter(comparison=analysed.comparison, superseded=False)
    assert reports.filter(kind="summary").count() == 1
    assert reports.filter(kind="participant").count() == 12
    assert set(reports.values_list("run_id", "version")) == {(analysed.pk, 1)}


def test_a_batch_delivered_twice_issues_each_report_once(monkeypatch, analysed):
    use_stand_in_pdf(monkeypatch)
    parts = list(analysed.comparison.participants.order_by("code").values_list("pk", flat=True))
    batch = parts[:5]
    # a report of the batch already issued (e.g. by a batch lost half-way through)
    done = report_issue_once(run_id=analysed.pk, kind="participant", participant_id=batch[1])
    first = report_issue_batch_task(analysed.pk, batch)
    assert done is not None and first[1] == done.pk and len(set(first)) == 5
    again = report_issue_batch_task(analysed.pk, batch)  # redelivered: nothing new
    assert again == first
    rows = Report.objects.filter(comparison=analysed.comparison)
    assert rows.count() == 5
    assert sorted(rows.values_list("participant_id", "version", "superseded")) == [
        (pk, 1, False) for pk in sorted(batch)
    ]


def test_a_batch_of_a_stale_run_issues_nothing(monkeypatch, analysed):
    use_stand_in_pdf(monkeypatch)
    analysis_run_start(comparison=analysed.comparison, user=None)  # a newer run is current
    ids = list(analysed.comparison.participants.values_list("pk", flat=True)[:3])
    assert report_issue_batch(run_id=analysed.pk, participant_ids=ids) == []
    assert Report.objects.count() == 0


def test_a_batch_refuses_a_participant_of_another_comparison(monkeypatch, analysed):
    use_stand_in_pdf(monkeypatch)
    other = make_round("OTHER", 2, 1)
    stranger = other.participants.first()
    assert stranger is not None
    with pytest.raises(ValidationFailed):
        report_issue_batch(run_id=analysed.pk, participant_ids=[stranger.pk])
    assert Report.objects.count() == 0


def test_a_new_run_supersedes_through_a_batch(monkeypatch, analysed):
    use_stand_in_pdf(monkeypatch)
    part = analysed.comparison.participants.order_by("code").first()
    old = report_issue_batch(run_id=analysed.pk, participant_ids=[part.pk])
    analysis_run_start(comparison=analysed.comparison, user=None)
    new_run = current_run(analysed.comparison)
    assert new_run is not None
    new = report_issue_batch(run_id=new_run.pk, participant_ids=[part.pk])
    rows = dict(Report.objects.values_list("pk", "superseded"))
    assert rows == {old[0]: True, new[0]: False}
    report = Report.objects.get(pk=new[0])
    assert (report.version, report.run_id) == (2, new_run.pk)
    assert b"-v2 " in report.file.read()  # a second run reported: edition 2


def test_a_batch_of_an_older_run_never_supersedes_a_newer_report(monkeypatch, analysed):
    """A batch still running when a new run became current (and its report was issued)
    leaves that report current."""
    use_stand_in_pdf(monkeypatch)
    part = analysed.comparison.participants.order_by("code").first()
    analysis_run_start(comparison=analysed.comparison, user=None)
    new_run = current_run(analysed.comparison)
    assert new_run is not None
    (new,) = report_issue_batch(run_id=new_run.pk, participant_ids=[part.pk])
    monkeypatch.setattr("analysis.reports.services.current_run", lambda c: analysed)
    assert report_issue_batch(run_id=analysed.pk, participant_ids=[part.pk]) == [new]
    assert list(Report.objects.values_list("pk", "run_id", "superseded")) == [
        (new, new_run.pk, False)
    ]


@pytest.mark.parametrize("size", ["small", "large"])
def test_batch_pdf_equals_the_in_process_render(analysed, request, size):
    if size == "large":
        request.getfixturevalue("large")
    parts = list(analysed.comparison.participants.order_by("code")[:3])
    ids = report_issue_batch(run_id=analysed.pk, participant_ids=[p.pk for p in parts])
    clear_run_contexts()  # the in-process render reads everything again
    for pk, part in zip(ids, parts, strict=True):
        report = Report.objects.get(pk=pk)
        pdf = render_report(report_data(run=analysed, participant=part))
        assert hashlib.sha256(pdf).hexdigest() == report.sha256
        assert report.file.read() == pdf


def test_large_round_report_from_own_rows_equals_the_one_from_every_row(analysed, large):
    """A large round's participant report carries its own rows and the round's figures;
    its bytes equal those of the report built from every row of the round."""
    part = analysed.comparison.participants.order_by("code")[4]
    lean = report_data(run=analysed, participant=part)
    context = run_context(analysed)
    results, scores = assemble._results_and_scores(analysed, context.index, context.use_z)
    own = Score.objects.filter(run=analysed, result__submission__participant=part).count()
    assert own > 0 and len(lean.results) == len(lean.scores) == own
    assert {r.lab for r in lean.results} == {part.code}
    assert len(results) == len(scores) == 891 and lean.stats is context.stats
    # the summary of a large round lists every row from columns (test_listing.py)
    summary = report_data(run=analysed)
    assert summary.results == () and summary.listing is not None and len(summary.listing) == 891
    full = ReportData(
        **{
            **{f: getattr(lean, f) for f in ReportData.__dataclass_fields__},
            "results": results,
            "scores": scores,
            "stats": None,  # computed from the rows by the renderer
        }
    )
    assert full.round.spread == lean.stats.spread
    assert full.round.largest_en == lean.stats.largest_en
    assert full.round.frequency == lean.stats.frequency
    assert (full.round.n_results, full.round.n_bad) == (891, lean.stats.n_bad)
    assert render_report(full) == render_report(lean)


def test_shared_data_is_read_once_per_run(monkeypatch, analysed, large):
    use_stand_in_pdf(monkeypatch)
    builds = []
    real = assemble._build_context

    def counted(*a):
        builds.append(1)
        return real(*a)

    monkeypatch.setattr(assemble, "_build_context", counted)
    _, batches = report_batches(analysed.comparison, size=4)
    for batch in batches:
        report_issue_batch(run_id=analysed.pk, participant_ids=batch)
    assert len(builds) == 1 and Report.objects.count() == 12


def batch_queries(comparison: Comparison, size: int) -> tuple[int, int]:
    """Queries of a cold batch (the run's context built) and of a warm one."""
    run = current_run(comparison)
    assert run is not None
    ids = list(comparison.participants.order_by("code").values_list("pk", flat=True))
    counts = []
    for batch in (ids[:size], ids[size : 2 * size]):
        with CaptureQueriesContext(connection) as ctx:
            assert len(report_issue_batch(run_id=run.pk, participant_ids=batch)) == size
        counts.append(len(statements(ctx)))
    return counts[0], counts[1]


def statements(ctx: CaptureQueriesContext) -> list[str]:
    """The queries, without transaction control (SQLite's BEGIN / COMMIT are captured)."""
    control = ("BEGIN", "COMMIT", "ROLLBACK", "SAVEPOINT", "RELEASE")
    return [q["sql"] for q in ctx.captured_queries if not q["sql"].startswith(control)]


def test_queries_per_batch_do_not_grow_with_the_round(monkeypatch, large):
    use_stand_in_pdf(monkeypatch)
    small, big = make_round("SMALL", 8, 2), make_round("BIG", 40, 6)
    assert batch_queries(small, 3) == batch_queries(big, 3)
    cold, warm = batch_queries(make_round("MID", 20, 4), 4)
    cold5, warm5 = batch_queries(make_round("MID5", 20, 4), 5)
    # per report: its participant's row lock, its versions, the insert (nothing to supersede)
    assert warm5 - warm == cold5 - cold == 3
    # per batch: run, current run, issued reports, participants, context key (a count),
    # own rows, coordinators, devices; the laboratories' histories (analysis.history:
    # participations, publications, the latest runs of rounds without one, scores)
    assert warm == 8 + 4 + 3 * 4


def test_large_round_reads_own_rows_in_one_query(monkeypatch, analysed, large):
    use_stand_in_pdf(monkeypatch)
    run_context(analysed)  # warm
    ids = list(analysed.comparison.participants.order_by("code").values_list("pk", flat=True))
    with CaptureQueriesContext(connection) as ctx:
        report_issue_batch(run_id=analysed.pk, participant_ids=ids[:6])
    score_reads = [sql for sql in statements(ctx) if "analysis_score" in sql]
    # the batch's laboratories' histories read their scores once more, with the z that
    # counts from the assigned values (analysis.history)
    history = [sql for sql in score_reads if "analysis_assignedvalue" in sql]
    score_reads = [sql for sql in score_reads if sql not in history]
    assert len(history) == 1
    assert len(score_reads) == 1
    assert "participant_id" in score_reads[0] and " IN (" in score_reads[0]
    assert all(b"%PDF-1.4" in r.file.read() for r in Report.objects.all())
    assert sorted(Report.objects.values_list("participant_id", flat=True)) == sorted(ids[:6])


def point_charts_built(monkeypatch) -> list[str]:
    """The titles of the point charts drawn from now on (the chart cache emptied)."""
    built: list[str] = []
    real = charts.PointChart.__init__

    def counted(self, *a, **k):
        built.append(k["title"])
        return real(self, *a, **k)

    monkeypatch.setattr(charts.PointChart, "__init__", counted)
    charts.point_chart.cache_clear()
    return built


def test_a_large_rounds_first_batch_builds_every_point_chart(monkeypatch, large):
    """With at least as many participants as points, every point's chart is drawn with
    the process's first batch of the run (not in whichever later report first shows
    it), once: later batches draw none."""
    use_stand_in_pdf(monkeypatch)  # the reports draw nothing themselves
    c = make_round("CHARTS", 8, 3)
    ids = list(c.participants.order_by("code").values_list("pk", flat=True))
    built = point_charts_built(monkeypatch)
    run = current_run(c)
    assert run is not None
    report_issue_batch(run_id=run.pk, participant_ids=ids[:2])
    assert sorted(built) == [f"MEMS 0, X, {f} Hz, linear vertical" for f in (10, 20, 30)]
    report_issue_batch(run_id=run.pk, participant_ids=ids[2:5])
    assert len(built) == 3


def test_a_round_with_fewer_participants_than_points_draws_charts_as_needed(monkeypatch, large):
    use_stand_in_pdf(monkeypatch)
    c = make_round("FEW", 4, 5)
    ids = list(c.participants.order_by("code").values_list("pk", flat=True))
    built = point_charts_built(monkeypatch)
    run = current_run(c)
    assert run is not None
    report_issue_batch(run_id=run.pk, participant_ids=ids)
    assert built == []
