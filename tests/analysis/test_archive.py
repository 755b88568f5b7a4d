"""A round's archive (docs/interfaces.md §6): its members against the downloads and the rows
they come from, a participant's archive holding no other laboratory, one row per run and
audience, the same bytes when built again, failures that leave no file, the background
path and the sweep."""

from __future__ import annotations

import csv
import datetime as dt
import io
import threading
import time
import tracemalloc
import zipfile
from pathlib import Path

import openpyxl
import pytest
from django.contrib.auth import get_user_model
from django.core.files.storage import default_storage
from django.db import connection
from django.utils import timezone

from analysis.archive import archive_execute, archive_request, archives_sweep
from analysis.archive_contents import Entry, write_archive
from analysis.models import AssignedValue, CompatibilityMatrix, KitPointFit, Report, RoundArchive
from analysis.publication import comparison_publish
from analysis.reports.services import report_issue
from analysis.tasks import archive_build_task
from common.errors import StateConflict
from labs.importers import write_table_to
from labs.models import Laboratory, Participant
from labs.selectors import comparison_result_rows
from tests.analysis.conftest import DEMO_CODE as CODE

pytestmark = pytest.mark.django_db
C = f"/coordinator/{CODE}/"


@pytest.fixture
def stand_in(monkeypatch):
    """Reports whose bytes say which they are (their layout is not what is tested here)."""
    monkeypatch.setattr(
        "analysis.reports.services.render_report",
        lambda data: f"%PDF-1.4 stand-in {data.report_number} {data.own_code}".encode(),
    )


def login(client, username):
    client.force_login(get_user_model().objects.get(username=username))


def members(data: bytes) -> dict[str, bytes]:
    with zipfile.ZipFile(io.BytesIO(data)) as z:
        return {name: z.read(name) for name in z.namelist()}


def csv_rows(data: bytes) -> list[dict[str, str]]:
    return list(csv.DictReader(io.StringIO(data.decode("utf-8-sig"))))


def sheet(data: bytes) -> list[tuple]:
    return list(openpyxl.load_workbook(io.BytesIO(data), read_only=True).active.values)


def download(client, url: str) -> bytes:
    response = client.get(url)
    assert response.status_code == 200, url
    return b"".join(response.streaming_content) if response.streaming else response.content


def test_coordinator_archive_holds_the_downloads_and_the_reports(client, run, demo, stand_in):
    summary = report_issue(comparison=demo, kind=Report.Kind.SUMMARY)
    login(client, "coordinator")
    assert b"Download everything (ZIP)" in client.get(C + "results/").content
    response = client.post(C + "archive/", {"run": run.pk})
    assert response.status_code == 302 and response["Location"] == C + "results/"
    page = client.get(C + "results/").content.decode()
    assert f'href="{C}archive/run{run.pk}.zip"' in page  # built inline: a small round
    response = client.get(f"{C}archive/run{run.pk}.zip")
    assert response["Content-Type"] == "application/zip"
    assert response["Content-Disposition"] == f'attachment; filename="{CODE}-run{run.pk}.zip"'
    zip_bytes = b"".join(response.streaming_content)
    files = members(zip_bytes)
    stored_factors = CompatibilityMatrix.objects.filter(run=run).values_list("factor", flat=True)
    factors = sorted(set(stored_factors))
    assert list(files) == [
        "README.txt", "assigned_values.csv", "doe_covariance.csv",
        *(f"matrices/{f}.csv" for f in factors),
        f"reports/{CODE}-summary-v1.pdf", "results.csv", "scores.csv", "scores.xlsx",
    ]  # fmt: skip
    # the demo's two kits: the covariance of the linked d at its 27 linked points, a ≤ b
    fits = KitPointFit.objects.filter(run=run).exclude(reference="")
    sizes = [len(f.doe_covariance["codes"]) for f in fits]
    assert len(sizes) == 27 and all(n > 2 for n in sizes)
    assert len(csv_rows(files["doe_covariance.csv"])) == sum(n * (n + 1) // 2 for n in sizes)
    # the scores: the same bytes as the scores download, the same cells as its XLSX
    assert files["scores.csv"] == download(client, C + "scores.csv")
    assert sheet(files["scores.xlsx"]) == sheet(download(client, C + "scores.xlsx"))
    assert len(csv_rows(files["scores.csv"])) == run.scores.count() > 0
    # the report as stored, byte for byte
    assert files[f"reports/{CODE}-summary-v1.pdf"] == summary.file.open("rb").read()
    # the results table: the accepted results the run scored, as export_results writes them
    expected = [r.as_record() for r in comparison_result_rows(demo)]
    got = csv_rows(files["results.csv"])
    assert len(got) == len(expected) == run.scores.count()
    key = lambda r: (r["lab"], r["device"], r["axis"], float(r["frequency_hz"]), r["bench"],  # noqa: E731
                     r["direction"])  # fmt: skip
    by_key = {key(r): r for r in got}
    for e in expected:
        row = by_key[key(e)]
        assert float(row["sensitivity"]) == e["sensitivity"]
        assert float(row["expanded_uncertainty"]) == e["expanded_uncertainty"]
    # assigned values and matrices: the stored rows at full precision
    stored = {
        (a.measurement_point.device.name, a.measurement_point.axis,
         a.measurement_point.frequency_hz, a.measurement_point.bench,
         a.measurement_point.direction): a
        for a in AssignedValue.objects.filter(run=run).select_related("measurement_point__device")
    }  # fmt: skip
    assigned = csv_rows(files["assigned_values.csv"])
    assert len(assigned) == len(stored) == 81
    for row in assigned:
        a = stored[(row["device"], row["axis"], float(row["frequency_hz"]), row["bench"],
                    row["direction"])]  # fmt: skip
        assert (float(row["value"]), float(row["standard_uncertainty"])) == (
            a.value, a.standard_uncertainty)  # fmt: skip
        assert float(row["expanded_uncertainty"]) == a.expanded_uncertainty
    for factor in factors:
        rows = csv_rows(files[f"matrices/{factor}.csv"])
        matrices = CompatibilityMatrix.objects.filter(run=run, factor=factor)
        assert len(rows) == sum(len(m.levels) * (len(m.levels) - 1) // 2 for m in matrices)
        m = matrices.get(group_key=rows[0]["group"])
        assert float(rows[0]["en"]) == m.en[0][1] and rows[0]["level_j"] == str(m.levels[1])
    readme = files["README.txt"].decode()
    finished = run.finished_at.astimezone(dt.UTC).strftime("%Y-%m-%d %H:%M UTC")
    assert f"proficiency test {CODE}" in readme
    assert f"analysis run {run.pk}, finished {finished}" in readme
    for name in files:
        assert f"  {name}:" in readme or name == "README.txt"
    for lab in Laboratory.objects.values_list("name", flat=True):  # codes only, never names
        assert all(lab.encode() not in body for body in files.values()), lab


@pytest.fixture
def published(run, demo, stand_in):
    return comparison_publish(comparison=demo)


def test_participant_archive_holds_only_its_own_and_the_summary(client, published, run):
    own = Participant.objects.select_related("laboratory").get(
        comparison=published, laboratory__name__startswith="Alpine"
    )
    member = own.laboratory.members.get(role="staff").user
    client.force_login(member)
    zip_url = f"/results/{CODE}/archive/run{run.pk}.zip"
    assert client.get(zip_url).status_code == 404  # not asked for yet
    page = client.get(f"/results/{CODE}/").content.decode()
    assert f'action="/results/{CODE}/archive/"' in page and "your report and the summary" in page
    assert client.post(f"/results/{CODE}/archive/").status_code == 302
    files = members(download(client, zip_url))
    reports = sorted(n for n in files if n.startswith("reports/"))
    own_report = Report.objects.get(participant=own, superseded=False)
    summary = Report.objects.get(comparison=published, kind="summary", superseded=False)
    assert reports == sorted([f"reports/{CODE}-{own.code}-v{own_report.version}.pdf",
                              f"reports/{CODE}-summary-v{summary.version}.pdf"])  # fmt: skip
    assert files[f"reports/{CODE}-{own.code}-v{own_report.version}.pdf"] == own_report.file.read()
    # its own results; every score by code, exactly as its scores download
    assert {r["lab"] for r in csv_rows(files["results.csv"])} == {own.code}
    assert files["scores.csv"] == download(client, f"/results/{CODE}/scores.csv")
    assert "doe_covariance.csv" not in files  # every row a pair of laboratories
    others = Participant.objects.filter(comparison=published).exclude(pk=own.pk)
    for other in others.select_related("laboratory"):
        assert not any(other.laboratory.name.encode() in body for body in files.values())
        # its report's bytes (the stand-in names its code) are nowhere in the archive
        report = Report.objects.get(participant=other, superseded=False).file.read()
        assert not any(report in body for body in files.values())
    assert own.laboratory.name.encode() not in files["README.txt"]
    # another laboratory gets 404 for this run's ZIP until it asks for its own
    other = others.select_related("laboratory").order_by("code")[0]
    client.force_login(other.laboratory.members.get(role="staff").user)
    assert client.get(zip_url).status_code == 404
    assert client.post(f"/results/{CODE}/archive/").status_code == 302
    theirs = members(download(client, zip_url))
    assert {r["lab"] for r in csv_rows(theirs["results.csv"])} == {other.code}
    assert RoundArchive.objects.filter(run=run).count() == 2


def test_asking_twice_gives_one_row_and_building_twice_the_same_bytes(
    run, demo, stand_in, django_capture_on_commit_callbacks
):
    first = archive_request(comparison=demo, run=run)
    again = archive_request(comparison=demo, run=run)
    assert first.pk == again.pk and RoundArchive.objects.count() == 1
    assert again.status == "ready" and again.size == Path(again.file.path).stat().st_size
    bytes_before, sha = Path(first.file.path).read_bytes(), first.sha256
    assert archive_build_task.delay(first.pk).get() == "ready"  # a second delivery: nothing
    assert RoundArchive.objects.get().sha256 == sha
    # built again from scratch (its task lost and redone), later: the very same bytes (a
    # ZIP dated by the clock would differ, its members' times having 2 s steps)
    time.sleep(2.1)
    RoundArchive.objects.filter(pk=first.pk).update(status="pending", file="", sha256="")
    assert archive_execute(archive_id=first.pk, delivery="redelivered") == "ready"
    rebuilt = RoundArchive.objects.get()
    assert rebuilt.sha256 == sha and Path(rebuilt.file.path).read_bytes() == bytes_before
    # a report issued from the run since: asking again builds the same row again, with it
    report = report_issue(comparison=demo, kind=Report.Kind.SUMMARY)
    with django_capture_on_commit_callbacks(execute=True):  # the older file goes on commit
        with_report = archive_request(comparison=demo, run=run)
    assert with_report.pk == first.pk and with_report.report_ids == [report.pk]
    assert f"reports/{CODE}-summary-v1.pdf" in members(Path(with_report.file.path).read_bytes())
    assert not Path(rebuilt.file.path).exists()  # the older file is gone


def _archive_files(settings) -> list[Path]:
    folder = Path(settings.MEDIA_ROOT) / "archives"
    return [p for p in folder.rglob("*") if p.is_file()] if folder.exists() else []


def test_a_failure_is_recorded_and_leaves_no_file(client, run, demo, stand_in, settings):
    report = report_issue(comparison=demo, kind=Report.Kind.SUMMARY)
    default_storage.delete(report.file.name)  # the ZIP fails half-way, at the report
    archive = archive_request(comparison=demo, run=run)
    assert archive.status == "failed" and "FileNotFoundError" in archive.error
    assert not archive.file and archive.sha256 == "" and _archive_files(settings) == []
    login(client, "coordinator")
    assert client.get(f"{C}archive/run{run.pk}.zip").status_code == 404
    status = client.get(C + "archive/status/").content.decode()
    assert "The last attempt failed" in status and "FileNotFoundError" in status
    default_storage.save(report.file.name, io.BytesIO(b"%PDF-1.4 restored"))
    retried = archive_request(comparison=demo, run=run)  # a failed one is built again
    assert retried.pk == archive.pk and retried.status == "ready" and retried.error == ""
    assert len(_archive_files(settings)) == 1


def test_an_archive_taken_over_while_storing_keeps_no_file(run, demo, settings, monkeypatch):
    """The task stores its file, but its claim was taken over meanwhile: its file is deleted
    and the row is left to the task holding it (no half-done archive is ever ready)."""
    archive = RoundArchive.objects.create(comparison=demo, run=run)
    real_save = default_storage.save

    def save_then_lose_the_claim(name, content):
        stored = real_save(name, content)
        RoundArchive.objects.filter(pk=archive.pk).update(token="another task's")
        return stored

    monkeypatch.setattr(default_storage, "save", save_then_lose_the_claim)
    assert archive_execute(archive_id=archive.pk) == "running"
    archive.refresh_from_db()
    assert not archive.file and archive.sha256 == "" and _archive_files(settings) == []


def test_a_large_round_is_built_by_the_task_and_a_lost_one_by_the_sweep(
    client, run, demo, settings, django_capture_on_commit_callbacks
):
    settings.ARCHIVE_INLINE_MAX_SCORES = 0  # every run is "large": built in the background
    login(client, "coordinator")
    with django_capture_on_commit_callbacks(execute=False) as sent:  # the message is lost
        client.post(C + "archive/", {"run": run.pk}, HTTP_HX_REQUEST="true")
    archive = RoundArchive.objects.get()
    assert archive.status == "pending" and len(sent) == 1
    status = client.get(C + "archive/status/").content.decode()
    assert "is queued" in status and f'hx-get="{C}archive/status/"' in status
    assert archives_sweep() == 0  # not silent yet
    long_ago = timezone.now() - dt.timedelta(seconds=settings.JOB_STALE_SECONDS + 60)
    RoundArchive.objects.filter(pk=archive.pk).update(created_at=long_ago)
    assert archives_sweep() == 1  # sent again; eager Celery builds it now
    archive.refresh_from_db()
    assert archive.status == "ready" and archive.attempts == 1
    status = client.get(C + "archive/status/").content.decode()
    assert f'href="{C}archive/run{run.pk}.zip"' in status and "hx-get" not in status
    assert archives_sweep() == 0
    with django_capture_on_commit_callbacks(execute=True):  # asked again: the ready one
        response = client.post(C + "archive/", {"run": run.pk}, HTTP_HX_REQUEST="true")
    assert response.status_code == 200 and b"Download everything (ZIP)" in response.content
    assert RoundArchive.objects.get().attempts == 1


@pytest.mark.django_db(transaction=True)
def test_two_requests_at_once_make_one_row_and_send_one_task(
    needs_postgres, run, demo, settings, monkeypatch
):
    """Two requests on two connections, released together: one row (the unique constraint
    and the row lock), one task sent."""
    settings.ARCHIVE_INLINE_MAX_SCORES = 0
    sent: list[int] = []
    monkeypatch.setattr("analysis.archive._send_pk", sent.append)
    barrier = threading.Barrier(2)
    out: list[object] = [None, None]

    def ask(i: int) -> None:
        try:
            barrier.wait(10)
            out[i] = archive_request(comparison=demo, run=run).pk
        except BaseException as exc:  # reported below, not lost in the thread
            out[i] = exc
        finally:
            connection.close()

    threads = [threading.Thread(target=ask, args=(i,)) for i in range(2)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(60)
    assert out[0] == out[1] == RoundArchive.objects.get().pk, out
    assert sent == [out[0]]


def _archive_peak(path: Path, n: int) -> int:
    """The peak of memory allocated while ``write_archive`` writes ``n`` score-like rows."""

    def rows():
        for i in range(n):
            yield {"lab": f"L{i % 50}", "frequency_hz": 5.0 + i, "en": 0.1234567 * i}

    def write(out):
        write_table_to(out, rows(), format="csv", columns=["lab", "frequency_hz", "en"])

    when = dt.datetime(2026, 1, 2, 3, 4, 6, tzinfo=dt.UTC)  # ZIP times: 2 s steps
    with open(path, "wb") as out:
        tracemalloc.start()
        try:
            write_archive(out, [Entry("scores.csv", "", write)], when)
            return tracemalloc.get_traced_memory()[1]
        finally:
            tracemalloc.stop()


def test_an_archive_is_written_as_a_stream_in_bounded_memory(tmp_path):
    """Five times the rows, the same memory: the members are streamed (the zlib window and
    a few buffers, under 1 MB), never held whole."""
    small = _archive_peak(tmp_path / "small.zip", 4_000)
    large = _archive_peak(tmp_path / "large.zip", 20_000)
    with zipfile.ZipFile(tmp_path / "large.zip") as z:
        (info,) = z.infolist()
        assert info.date_time == (2026, 1, 2, 3, 4, 6) and info.file_size > 500_000
        assert len(z.read("scores.csv").splitlines()) == 20_001
    assert large < 1.25 * small and large < 1_000_000, (small, large)


def test_a_participant_archive_needs_the_published_current_run(run, demo):
    participant = Participant.objects.filter(comparison=demo).order_by("code")[0]
    with pytest.raises(StateConflict, match="not published yet"):
        archive_request(comparison=demo, run=run, participant=participant)
    assert not RoundArchive.objects.exists()
