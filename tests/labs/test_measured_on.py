"""The optional ``measured_on`` of a result (docs/interfaces.md §1): read by the importer
and the grid, written by downloads, counted in the checksum only when stated; a bad date
named by row and column, one before the comparison opened or in the future refused (the
API and the coordinator's commands: tests/labs/api/test_measured_on.py)."""

from __future__ import annotations

import datetime as dt
import hashlib

import pytest
from django.urls import reverse

from labs import services
from labs.importers import ImportErrors, TableContext, parse_table, write_table
from labs.importers.local import read_local_table
from labs.kits import SlotPlan, circulation_set, kit_create
from labs.models import Submission
from tests.labs.test_local_table import assert_same, plain_only, streamed, upload_columns
from tests.labs.test_web import visible
from tests.labs.test_web_grid import GRID, grid_rows, participant, post_data, staff

__all__ = ["participant", "plain_only", "staff", "streamed"]  # fixtures

OPENED = dt.date(2026, 1, 10)

# --- the importer alone ------------------------------------------------------------------------

HEADER = b"device,axis,frequency_hz,bench,sensitivity,expanded_uncertainty,measured_on\n"
BOUNDED = TableContext().with_dates(dt.date(2026, 1, 10), dt.date(2026, 6, 2))


def _problems(cells: list[bytes]) -> list[str]:
    data = HEADER + b"".join(b"MEMS 1,X,%d,linear,420,8,%s\n" % (5 + i, c) for i, c in
                             enumerate(cells))  # fmt: skip
    with pytest.raises(ImportErrors) as caught:
        parse_table(data, filename="r.csv", context=BOUNDED)
    return [str(e) for e in caught.value.errors]


def test_the_importer_reads_dates_and_leaves_a_blank_unstated():
    data = HEADER + b"MEMS 1,X,5,linear,420,8,2026-03-14\nMEMS 1,X,10,linear,420,8,\n"
    found = parse_table(data, filename="r.csv", context=BOUNDED)
    assert [r.measured_on for r in found] == [dt.date(2026, 3, 14), None]
    edges = HEADER + b"MEMS 1,X,5,linear,420,8,2026-01-10\nMEMS 1,X,10,linear,420,8,20260602\n"
    assert [r.measured_on for r in parse_table(edges, filename="r.csv", context=BOUNDED)] == [
        OPENED, dt.date(2026, 6, 2)
    ]  # fmt: skip


def test_the_importer_names_each_bad_date():
    assert _problems([b"14/03/2026", b"2026-02-30", b"2026-01-09", b"2026-06-03", b"45000"]) == [
        "row 2, column measured_on: must be a date YYYY-MM-DD, got '14/03/2026'",
        "row 3, column measured_on: must be a date YYYY-MM-DD, got '2026-02-30' (no such day)",
        "row 4, column measured_on: 2026-01-09 is before the comparison opened on 2026-01-10",
        "row 5, column measured_on: 2026-06-03 is in the future: a measurement date is at the "
        "latest 2026-06-02 (today anywhere on Earth)",
        "row 6, column measured_on: must be a date YYYY-MM-DD, got '45000'",
    ]


def test_a_download_writes_the_date_and_reads_back_the_same():
    data = HEADER + b"MEMS 1,X,5,linear,420,8,2026-03-14\n"
    found = parse_table(data, filename="r.csv", context=BOUNDED)
    for fmt, name in (("csv", "r.csv"), ("xlsx", "r.xlsx")):
        written = write_table(found, format=fmt)  # type: ignore[arg-type]
        assert parse_table(written, filename=name, context=BOUNDED) == found
    header = write_table(found).decode("utf-8-sig").splitlines()[0]
    assert header.endswith(",dof,measured_on,note")


LOCAL = ["lab,device,axis,frequency_hz,bench,sensitivity,expanded_uncertainty,measured_on",
         "A,MEMS 1,X,10,linear,420,4,2025-03-14", "B,MEMS 1,X,10,linear,421,4,"]  # fmt: skip


def test_a_local_table_reads_as_without_the_date(tmp_path, plain_only):
    """pt_compare knows no comparison: the date's form is checked, its value not used."""
    dated, plain = tmp_path / "dated.csv", tmp_path / "plain.csv"
    dated.write_text("\n".join(LOCAL) + "\n")
    plain.write_text("\n".join(line.rsplit(",", 1)[0] for line in LOCAL) + "\n")
    assert_same(read_local_table(dated), upload_columns(plain))


def test_a_local_table_names_a_bad_date(tmp_path, streamed):
    path = tmp_path / "dated.csv"
    path.write_text("\n".join([*LOCAL, "C,MEMS 1,X,10,linear,419,4,2025-14-03"]) + "\n")
    with pytest.raises(ImportErrors) as caught:
        read_local_table(path)
    assert [str(e) for e in caught.value.errors] == [
        "row 4, column measured_on: must be a date YYYY-MM-DD, got '2025-14-03' (no such day)"
    ]
    assert streamed  # the upload's own reading gives the message


# --- the idempotency checksum ------------------------------------------------------------------


def test_the_checksum_of_a_result_without_a_date_is_the_one_stored_before():
    values = [(7, 419.5, "mV/(m/s²)", 5.034, 2.0, None, "", None, None, "", None)]
    old = hashlib.sha256(repr((7, 419.5, "mV/(m/s²)", 5.034, 2.0, None, "", None, None)).encode())
    old.update(b"\n")
    assert services._content_sha256(values) == old.hexdigest()
    dated = [(*values[0][:-1], dt.date(2026, 3, 14))]
    assert services._content_sha256(dated) != old.hexdigest()


# --- the grid ----------------------------------------------------------------------------------


@pytest.mark.django_db
def test_the_grid_of_a_round_without_kits_asks_no_date(client, staff, participant):
    body = visible(client.get(GRID))
    assert "r0-measured_on" not in body and ">Date</abbr>" not in body


@pytest.mark.django_db
def test_the_grid_of_a_kit_round_stores_prefills_and_refuses_dates(client, staff, participant):
    comparison = participant.comparison
    device = comparison.devices.first()
    kit = kit_create(comparison_id=comparison.pk, name="Kit A", serials={device: "S1"})
    today = dt.date.today()
    circulation_set(kit=kit, plan=[SlotPlan(participant, today - dt.timedelta(days=30), today)])
    on = (today - dt.timedelta(days=3)).isoformat()
    data = post_data({0: {"sensitivity": "421", "expanded_uncertainty": "8", "measured_on": on},
                      1: {"sensitivity": "420", "expanded_uncertainty": "8"}})  # fmt: skip
    assert client.post(GRID, data).status_code == 302
    submission = Submission.objects.get(participant=participant)
    points = grid_rows(participant)
    assert submission.results.get(measurement_point=points[0]).measured_on == dt.date.fromisoformat(
        on
    )
    assert submission.results.get(measurement_point=points[1]).measured_on is None
    body = visible(client.get(GRID))
    assert f'name="r0-measured_on" id="id_r0-measured_on" value="{on}"' in body
    page = visible(client.get(reverse("labs:submission", args=["CMP-G", 1])))
    assert f'<td data-label="Date measured">{on}</td>' in page
    bad = post_data({0: {"sensitivity": "421", "expanded_uncertainty": "8",
                         "measured_on": "yesterday"}})  # fmt: skip
    body = visible(client.post(GRID, bad))
    assert (
        '<div id="id_r0-measured_on-error" class="invalid-feedback">must be a date YYYY-MM-DD, '
        "got &#x27;yesterday&#x27;"
    ) in body
    assert submission.results.count() == 2  # the draft stands as it was
