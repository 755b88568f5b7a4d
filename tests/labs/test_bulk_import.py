"""A coordinator's streamed import of many participants' results."""

import io

import pytest
from auditlog.models import LogEntry
from django.core.management import CommandError, call_command

from common.errors import NotVisible, StateConflict
from labs.bulk_import import ImportRefused, results_import
from labs.importers import ImportErrors, parse_table, write_table
from labs.importers.stream import read_chunks
from labs.models import Result, Submission
from labs.selectors import current_submissions, table_context
from proficiency.services import measurement_points_generate
from tests.factories import (
    ComparisonFactory,
    DeviceFactory,
    MeasurementPointFactory,
    MembershipFactory,
    ParticipantFactory,
    ResultFactory,
    SubmissionFactory,
    UserFactory,
)

pytestmark = pytest.mark.django_db

ACCESS = LogEntry.Action.ACCESS
CODES = ("L01", "L02", "L03")
# MEMS 1: X and Y at 5 and 10 Hz; MEMS 2: X at 5 Hz only -> 5 points per participant
POINTS = [("MEMS 1", a, f) for a in ("X", "Y") for f in (5, 10)] + [("MEMS 2", "X", 5)]


@pytest.fixture
def round_(settings):
    settings.RESULTS_IMPORT_CHUNK_ROWS = 4  # several chunks even for these small files
    comparison = ComparisonFactory.create(status="open")
    mems1 = DeviceFactory.create(comparison=comparison, name="MEMS 1")
    mems2 = DeviceFactory.create(comparison=comparison, name="MEMS 2")
    measurement_points_generate(
        comparison=comparison, devices=[mems1], axes=["X", "Y"], frequencies_hz=[5, 10],
        benches=["linear"],
    )  # fmt: skip
    MeasurementPointFactory.create(device=mems2, axis="X", frequency_hz=5)
    participants = {c: ParticipantFactory.create(comparison=comparison, code=c) for c in CODES}
    coordinator = UserFactory.create(username="coordinator")
    comparison.coordinators.add(coordinator)
    return comparison, participants, coordinator


def value(code, i):
    """A distinct value per participant and point, not representable in few digits."""
    return 415 + CODES.index(code) + i / 7


def records(codes=CODES, **override):
    return [
        {"lab": code, "device": d, "axis": a, "frequency_hz": f, "bench": "linear",
         "sensitivity": value(code, i), "expanded_uncertainty": 8.4 + i / 3, **override}
        for code in codes for i, (d, a, f) in enumerate(POINTS)
    ]  # fmt: skip


COLUMNS = ["lab", "device", "axis", "frequency_hz", "bench", "sensitivity",
           "expanded_uncertainty", "coverage_factor", "note"]  # fmt: skip


def csv(rows, columns=COLUMNS, **options):
    return io.BytesIO(write_table(rows, columns=columns, **options))


def run(comparison, user, rows, **options):
    return results_import(comparison=comparison, file=csv(rows), user=user, **options)


def refused(comparison, user, data):
    with pytest.raises(ImportRefused) as err:
        results_import(comparison=comparison, file=io.BytesIO(data), user=user)
    return [str(e) for e in err.value.row_errors], err.value


def text(rows):
    return write_table(rows, columns=COLUMNS, bom=False)


# --- round trip ---------------------------------------------------------------------------------


def test_round_trip_stores_exact_values_one_submitted_version_each(round_):
    comparison, participants, coordinator = round_
    summary = run(comparison, coordinator, records())
    assert (summary.participants, summary.rows, summary.new_versions) == (3, 15, 3)
    assert Result.objects.count() == 15
    for code, participant in participants.items():
        (sub,) = Submission.objects.filter(participant=participant)
        assert (sub.version, sub.status, sub.source) == (1, "submitted", "file")
        assert sub.submitted_by == coordinator and sub.submitted_at is not None
        stored = {
            (r.measurement_point.device.name, r.measurement_point.axis,
             r.measurement_point.frequency_hz): (r.value, r.expanded_uncertainty, r.coverage_factor)
            for r in sub.results.select_related("measurement_point__device")
        }  # fmt: skip
        assert stored == {
            (d, a, float(f)): (value(code, i), 8.4 + i / 3, 2.0)
            for i, (d, a, f) in enumerate(POINTS)
        }
    # the audit trail a submission leaves, with the coordinator as actor
    created = LogEntry.objects.filter(content_type__model="submission", action=0)
    assert created.count() == 3 and set(created.values_list("actor", flat=True)) == {coordinator.pk}
    note = LogEntry.objects.get(content_type__model="comparison", action=ACCESS)
    assert note.actor == coordinator
    assert note.changes["results_imported"][1].startswith("15 results of 3 participants")


def test_rows_in_any_order_and_a_subset_of_participants(round_):
    comparison, participants, coordinator = round_
    rows = records(("L03", "L01"))[::-1]  # interleaved order does not matter
    summary = run(comparison, coordinator, rows)
    assert (summary.participants, summary.rows) == (2, 10)
    assert not Submission.objects.filter(participant=participants["L02"]).exists()


def test_new_version_supersedes_and_decided_versions_stay(round_):
    comparison, participants, coordinator = round_
    accepted = SubmissionFactory.create(
        participant=participants["L01"], version=1, status="accepted"
    )
    first_point = comparison.measurement_points.first()
    kept = ResultFactory.create(submission=accepted, measurement_point=first_point)
    draft = SubmissionFactory.create(participant=participants["L02"], version=1, status="draft")
    ResultFactory.create(submission=draft, measurement_point=comparison.measurement_points.first(),
                  value=999.0)  # fmt: skip
    SubmissionFactory.create(participant=participants["L03"], version=1, status="rejected")
    SubmissionFactory.create(participant=participants["L03"], version=2, status="submitted")
    summary = run(comparison, coordinator, records())
    assert (summary.new_versions, summary.drafts_submitted) == (2, 1)
    versions = {
        code: list(Submission.objects.filter(participant=p).order_by("version")
                   .values_list("version", "status"))
        for code, p in participants.items()
    }  # fmt: skip
    assert versions == {
        "L01": [(1, "accepted"), (2, "submitted")],
        "L02": [(1, "submitted")],  # the open draft is replaced and submitted, as by the lab
        "L03": [(1, "rejected"), (2, "submitted"), (3, "submitted")],
    }
    kept.refresh_from_db()
    assert kept.value == 420.0 and accepted.results.count() == 1
    draft.refresh_from_db()
    assert sorted(draft.results.values_list("value", flat=True)) == [
        value("L02", i) for i in range(5)
    ]
    current = current_submissions(comparison, ("submitted", "accepted"))
    assert sorted(current.values_list("participant__code", "version")) == [
        ("L01", 2), ("L02", 1), ("L03", 3),
    ]  # fmt: skip
    updated = LogEntry.objects.get(content_type__model="submission", action=1)
    assert updated.object_id == draft.pk and updated.changes == {"status": ["draft", "submitted"]}


def test_same_file_twice_gives_a_second_version_not_duplicates(round_):
    comparison, participants, coordinator = round_
    run(comparison, coordinator, records())
    run(comparison, coordinator, records())
    for participant in participants.values():
        subs = Submission.objects.filter(participant=participant).order_by("version")
        assert [s.version for s in subs] == [1, 2]
        assert [s.results.count() for s in subs] == [5, 5]
    assert Result.objects.count() == 30


def test_xlsx_semicolon_and_bom_files(round_):
    comparison, _, coordinator = round_
    xlsx = write_table(records(("L01",)), columns=COLUMNS, format="xlsx")
    results_import(comparison=comparison, file=io.BytesIO(xlsx), user=coordinator)
    semicolon = text(records(("L02",))).decode().replace(",", ";").replace(".", ",")
    results_import(comparison=comparison, file=io.BytesIO(semicolon.encode()), user=coordinator)
    r = Result.objects.get(submission__participant__code="L02",
                           measurement_point__device__name="MEMS 2")  # fmt: skip
    assert r.value == value("L02", 4)
    assert Result.objects.count() == 10


def test_stream_reads_what_parse_table_reads(round_):
    comparison, _, _ = round_
    data = text(records()[::-1])
    context = table_context(comparison)
    whole = parse_table(data, lab_column="required", context=context)
    chunks = list(read_chunks(io.BytesIO(data), context=context, chunk_rows=4))
    assert [c.n_rows for c in chunks] == [4, 4, 4, 3]
    assert [r for c in chunks for r in c.rows] == whole


# --- errors -------------------------------------------------------------------------------------


def _nothing_stored():
    logged = LogEntry.objects.filter(content_type__model="submission").count()
    logged += LogEntry.objects.filter(content_type__model="comparison", action=ACCESS).count()
    return Submission.objects.count(), Result.objects.count(), logged


def test_unknown_participant_and_unknown_point(round_):
    comparison, _, coordinator = round_
    rows = records()
    rows[1]["lab"] = "L99"
    rows[7].update(device="MEMS 2", axis="Y")  # MEMS 2 has no Y axis point
    rows[12]["frequency_hz"] = 7
    errors, err = refused(comparison, coordinator, text(rows))
    assert errors[:3] == [
        f"row 3, column lab: unknown participant code 'L99' in {comparison.code}; the codes "
        "are listed on the comparison's participants page",
        "row 9: no measurement point MEMS 2 / Y / 5 Hz / linear / vertical in this comparison",
        "row 14, column frequency_hz: 7 Hz is not a frequency of this comparison; expected one "
        "of: 5, 10",
    ]
    assert err.total == len(errors) == 3  # completeness is checked once every row is valid
    assert _nothing_stored() == (0, 0, 0)


def test_duplicates_within_a_chunk_and_across_chunks(round_):
    comparison, _, coordinator = round_
    rows = records()
    rows.insert(3, dict(rows[2]))  # row 5 repeats row 4, same chunk
    rows.append(dict(rows[0], sensitivity=1.0))  # last row repeats row 2, chunks apart
    other = dict(rows[0], lab="L02")  # the same point for another participant is fine
    rows.remove(next(r for r in rows if r["lab"] == "L02" and r["axis"] == "X"
                     and r["frequency_hz"] == 5 and r["device"] == "MEMS 1"))  # fmt: skip
    rows.insert(8, other)
    errors, _ = refused(comparison, coordinator, text(rows))
    tail = ": same lab, device, axis, frequency_hz, bench, direction and amplitude_m_s2"
    assert errors == [f"row 5: duplicate of row 4{tail}", f"row 18: duplicate of row 2{tail}"]
    assert _nothing_stored() == (0, 0, 0)


def test_table_rules_give_the_upload_messages(round_):
    comparison, _, coordinator = round_
    rows = records()
    rows[0]["expanded_uncertainty"] = -3
    rows[4]["sensitivity"] = ""
    rows[6]["axis"] = "W"
    rows[9]["coverage_factor"] = "nan"
    rows[13]["note"] = "x" * 501
    rows[14]["lab"] = ""
    data = text(rows)
    with pytest.raises(ImportErrors) as upload:
        parse_table(data, lab_column="required", context=table_context(comparison))
    expected = [str(e) for e in upload.value.errors]
    assert "row 2, column expanded_uncertainty: must be > 0, got -3" in expected
    errors, _ = refused(comparison, coordinator, data)
    assert errors[: len(expected)] == expected
    assert len(errors) == len(expected)  # completeness is checked once every row is valid
    assert _nothing_stored() == (0, 0, 0)


@pytest.mark.parametrize(
    ("data", "message"),
    [
        (b"device,axis,frequency_hz,bench,sensitivity,expanded_uncertainty\n",
         "row 1: missing required column: lab"),
        (b"lab,device,axis,frequency_hz,bench,sensitivity,expanded_uncertainty\n",
         "the table has no data rows"),
        (b"", "the table is empty; the first row must be the header: lab, device, axis, "
              "frequency_hz, bench, direction, quantity, amplitude_m_s2, sensitivity, unit, "
              "expanded_uncertainty, coverage_factor, dof, repeat_sd, n_repeats, measured_on, "
              "note"),
        (b"lab,device,axis,frequency_hz,bench,sensitivity,expanded_uncertainty\n"
         b"L01,MEMS 1,X,5,linear,\xff,1\n",
         "row 2: the file is not UTF-8 text: byte 0xff at offset 90 (line 2); save it as "
         "'CSV UTF-8' or as .xlsx"),
    ],
)  # fmt: skip
def test_unreadable_files(round_, data, message):
    comparison, _, coordinator = round_
    errors, _ = refused(comparison, coordinator, data)
    assert errors == [message]
    assert _nothing_stored() == (0, 0, 0)
    if message.startswith("row 2: the file is not UTF-8"):  # the upload says the same
        with pytest.raises(ImportErrors) as upload:
            parse_table(data, lab_column="required")
        assert [str(e) for e in upload.value.errors] == [message]


def test_missing_points_refuse_the_participant(round_):
    comparison, _, coordinator = round_
    rows = [r for r in records() if not (r["lab"] == "L02" and r["device"] == "MEMS 2")]
    errors, err = refused(comparison, coordinator, text(rows))
    assert errors == [
        "column lab: L02: missing result for MEMS 2, X, 5 Hz, linear vertical; a submission "
        "needs a result for every measurement point"
    ]
    assert err.message == "The results were not stored: 1 problem found."


def test_error_in_the_last_chunk_stores_nothing(round_, settings):
    comparison, participants, coordinator = round_
    settings.RESULTS_IMPORT_CHUNK_ROWS = 2  # 8 chunks; the bad row is alone in the last one
    SubmissionFactory.create(participant=participants["L01"], version=1, status="draft")
    before = list(Submission.objects.values_list("pk", "version", "status"))
    rows = records()
    rows[-1]["expanded_uncertainty"] = "0"
    errors, _ = refused(comparison, coordinator, text(rows))
    assert errors == ["row 16, column expanded_uncertainty: must be > 0, got 0"]
    assert list(Submission.objects.values_list("pk", "version", "status")) == before
    assert Result.objects.count() == 0
    assert not LogEntry.objects.filter(content_type__model="comparison", action=ACCESS).exists()


def test_error_list_is_capped_with_a_count(round_, settings):
    comparison, _, coordinator = round_
    settings.RESULTS_IMPORT_MAX_ERRORS = 3
    errors, err = refused(comparison, coordinator, text(records(axis="W")))
    assert len(errors) == 3 and err.total == 15
    assert errors[0].startswith("row 2, column axis: must be one of X, Y, Z, got 'W'")
    assert err.message == "The results were not stored: 15 problems found (the first 3 are listed)."


# --- who and when -------------------------------------------------------------------------------


def test_only_a_coordinator_of_the_comparison_may_import(round_):
    comparison, participants, _ = round_
    other_coordinator = UserFactory.create()
    ComparisonFactory.create().coordinators.add(other_coordinator)
    lab_member = MembershipFactory.create(laboratory=participants["L01"].laboratory).user
    for user in (UserFactory.create(), other_coordinator, lab_member):
        with pytest.raises(NotVisible):
            run(comparison, user, records())
    assert _nothing_stored() == (0, 0, 0)
    admin = UserFactory.create(is_superuser=True)
    assert run(comparison, admin, records()).rows == 15


@pytest.mark.parametrize(("status", "allowed"),
                         [("draft", False), ("open", True), ("closed", True),
                          ("analysed", False), ("published", False)])  # fmt: skip
def test_comparison_status(round_, status, allowed):
    comparison, _, coordinator = round_
    comparison.status = status
    comparison.save()
    if allowed:
        assert run(comparison, coordinator, records()).rows == 15
    else:
        with pytest.raises(StateConflict, match=f"is {status}: results can be imported"):
            run(comparison, coordinator, records())
        assert _nothing_stored() == (0, 0, 0)


# --- the command --------------------------------------------------------------------------------


def test_command_prints_a_summary(round_, tmp_path):
    comparison, _, coordinator = round_
    path = tmp_path / "round.csv"
    path.write_bytes(text(records()))
    out = io.StringIO()
    call_command("import_results", comparison.code, str(path), user="coordinator", stdout=out)
    assert out.getvalue().startswith(f"{comparison.code}: 15 results of 3 participants imported")
    assert set(Submission.objects.values_list("submitted_by", flat=True)) == {coordinator.pk}


def test_command_lists_errors_with_exit_status_2(round_, tmp_path):
    comparison, _, _ = round_
    rows = records()
    rows[3]["sensitivity"] = -1
    path = tmp_path / "round.csv"
    path.write_bytes(text(rows))
    err = io.StringIO()
    with pytest.raises(CommandError) as exc:
        call_command("import_results", comparison.code, str(path), stderr=err)
    assert exc.value.returncode == 2
    assert "row 5, column sensitivity: must be > 0, got -1" in err.getvalue()
    assert Result.objects.count() == 0
    with pytest.raises(CommandError, match="No user 'nobody'") as exc:
        call_command("import_results", comparison.code, str(path), user="nobody")
    assert exc.value.returncode == 2


def test_a_failing_write_rolls_everything_back(round_, monkeypatch):
    """A failure while a chunk is written (in the COPY thread on PostgreSQL) reaches the
    caller, and the chunks written before it are rolled back."""
    from labs import bulk_import

    comparison, _, coordinator = round_
    calls = []

    def flaky(real):
        def call(*args):
            calls.append(1)
            if len(calls) == 3:
                raise RuntimeError("the disk is full")
            return real(*args)

        return call

    monkeypatch.setattr(
        bulk_import._Writer, "_copy", staticmethod(flaky(bulk_import._Writer._copy))
    )
    monkeypatch.setattr(bulk_import, "results_insert", flaky(bulk_import.results_insert))
    with pytest.raises(RuntimeError, match="the disk is full"):
        run(comparison, coordinator, records())
    assert len(calls) == 3
    assert _nothing_stored() == (0, 0, 0)


def test_seen_keys_against_a_dict():
    """The sorted-array duplicate check gives what a dict of first rows gives."""
    import numpy as np

    from labs.bulk_import import _Seen

    first: dict[int, int] = {}
    rng, seen, row = np.random.default_rng(0), _Seen(), 2
    for _ in range(30):
        keys, rows = rng.integers(0, 3000, 500), np.arange(row, row + 500)
        row += 500
        expected = []
        for k, r in zip(keys.tolist(), rows.tolist(), strict=True):
            if k in first:
                expected.append((r, first[k]))
            else:
                first[k] = r
        repeated, earlier = seen.add(keys, rows)
        assert sorted(zip(repeated.tolist(), earlier.tolist(), strict=True)) == expected
    assert dict(zip(seen.keys.tolist(), seen.rows.tolist(), strict=True)) == first
    assert (np.diff(seen.keys) > 0).all()
