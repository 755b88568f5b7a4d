"""Real CSV and XLSX files through the upload service (docs/interfaces.md §1): all or none
stored."""

from __future__ import annotations

import csv
import io
import zipfile
from collections.abc import Mapping, Sequence

import openpyxl
import pytest

from common.errors import ValidationFailed
from labs.models import Result, Submission
from labs.services import submission_from_file, submission_from_records
from proficiency.services import measurement_points_generate
from tests.factories import ComparisonFactory, DeviceFactory, ParticipantFactory, UserFactory

pytestmark = pytest.mark.django_db

HEADER = ["device", "axis", "frequency_hz", "bench", "direction", "sensitivity",
          "expanded_uncertainty"]  # fmt: skip
FREQUENCIES = [float(f) for f in range(1, 41)]
CURVILINEAR = ("tangential", "radial")


@pytest.fixture
def grid():
    """An open comparison: 10 devices × 3 axes × 40 frequencies × 3 bench directions."""
    comparison = ComparisonFactory.create(status="open")
    devices = [DeviceFactory.create(comparison=comparison, name=f"MEMS {i}") for i in range(1, 11)]
    measurement_points_generate(
        comparison=comparison, devices=devices, axes=["X", "Y", "Z"],
        frequencies_hz=FREQUENCIES, benches=["linear", "curvilinear"],
    )  # fmt: skip
    return ParticipantFactory.create(comparison=comparison), UserFactory.create()


def records() -> list[dict[str, str]]:
    """A complete result set for :func:`grid`, values as text."""
    out = []
    for i, (bench, direction) in enumerate(
        [("linear", "vertical"), *(("curvilinear", d) for d in CURVILINEAR)]
    ):
        for d in range(1, 11):
            for axis in "XYZ":
                for f in FREQUENCIES:
                    value = 400 + d + f / 100 + i
                    cells = [f"MEMS {d}", axis, f"{f:g}", bench, direction, repr(value)]
                    out.append(dict(zip(HEADER, [*cells, repr(value / 50)], strict=True)))
    return out


def csv_file(rows: Sequence[Mapping[str, object]], *, sep: str = ",", bom: bool = False) -> bytes:
    names = list(dict.fromkeys(name for row in rows for name in row))
    buffer = io.StringIO()
    writer = csv.writer(buffer, delimiter=sep, lineterminator="\r\n")
    writer.writerow(names)
    writer.writerows([[row.get(n, "") for n in names] for row in rows])
    return ("\ufeff" if bom else "").encode() + buffer.getvalue().encode()


def xlsx_file(rows: list[dict[str, str]], *, formula: str | None = None) -> bytes:
    """A workbook as a spreadsheet program writes it: numbers as numbers."""
    book = openpyxl.Workbook()
    sheet = book.active
    sheet.title = "results"
    sheet.append(HEADER)
    for row in rows:
        cells = [row[n] for n in HEADER]
        sheet.append([float(c) if n in (2, 5, 6) else c for n, c in enumerate(cells)])
    if formula:
        sheet["G3"] = formula
    buffer = io.BytesIO()
    book.save(buffer)
    return buffer.getvalue()


def upload(grid, data: bytes, filename: str = "results.csv", submit: bool = True) -> Submission:
    participant, user = grid
    return submission_from_file(
        participant=participant, data=data, filename=filename, user=user, submit=submit
    )


def refused(
    grid, data: bytes, filename: str = "results.csv"
) -> list[tuple[int | None, str | None, str]]:
    with pytest.raises(ValidationFailed) as caught:
        upload(grid, data, filename)
    assert Submission.objects.count() == 0 and Result.objects.count() == 0
    return [(e["row"], e["field"], e["message"]) for e in caught.value.errors]


# --- good files -----------------------------------------------------------------------------


def stored(submission: Submission) -> dict[tuple[object, ...], tuple[float, ...]]:
    values = submission.results.values_list(
        "measurement_point__device__name", "measurement_point__axis",
        "measurement_point__frequency_hz", "measurement_point__bench",
        "measurement_point__direction", "value", "expanded_uncertainty", "coverage_factor",
    )  # fmt: skip
    return {tuple(v[:5]): tuple(v[5:]) for v in values}


def test_good_csv_stores_every_row(grid) -> None:
    submission = upload(grid, csv_file(records()))
    assert (submission.status, submission.source) == ("submitted", "file")
    results = stored(submission)
    assert len(results) == 3600 == Result.objects.count()
    value = 400 + 7 + 12 / 100 + 2
    assert results[("MEMS 7", "Y", 12.0, "curvilinear", "radial")] == (value, value / 50, 2.0)


@pytest.mark.parametrize(
    ("kind", "data"),
    [
        ("xlsx", lambda: xlsx_file(records())),
        ("bom", lambda: csv_file(records(), bom=True)),
        ("semicolon", lambda: csv_file(records(), sep=";")),
        ("decimal comma", lambda: csv_file(
            [{**r, "sensitivity": r["sensitivity"].replace(".", ",")} for r in records()],
            sep=";")),
    ],
)  # fmt: skip
def test_every_accepted_form_stores_the_same_results(grid, kind: str, data) -> None:
    expected = stored(upload(grid, csv_file(records())))
    Submission.objects.all().delete()
    assert stored(upload(grid, data(), "results.xlsx" if kind == "xlsx" else "r.csv")) == expected


# --- bad files: every problem listed, nothing stored -----------------------------------------


def changed(index: int, **changes: str) -> bytes:
    rows = records()
    rows[index].update(changes)
    return csv_file(rows)


BAD_ROWS = [
    ("bad number", changed(3, sensitivity="4x18"), 5, "sensitivity",
     "must be a number, got '4x18'"),
    ("U = 0", changed(6, expanded_uncertainty="0"), 8, "expanded_uncertainty",
     "must be > 0, got 0"),
    ("U < 0", changed(6, expanded_uncertainty="-3"), 8, "expanded_uncertainty",
     "must be > 0, got -3"),
    ("device", changed(9, device="MEMS 99"), 11, "device",
     "unknown device 'MEMS 99' for this comparison; expected one of: MEMS 1, MEMS 10, MEMS 2, "
     "MEMS 3, MEMS 4, MEMS 5, MEMS 6, MEMS 7, MEMS 8, MEMS 9"),
    ("axis", changed(0, axis="W"), 2, "axis", "must be one of X, Y, Z, got 'W'"),
    ("frequency", changed(1, frequency_hz="41.5"), 3, "frequency_hz",
     "41.5 Hz is not a frequency of this comparison; expected one of: "
     + ", ".join(f"{f:g}" for f in FREQUENCIES)),
    ("bench", changed(2, bench="rotary"), 4, "bench",
     "must be one of linear, curvilinear, got 'rotary'"),
    ("direction", changed(2, direction="radial"), 4, "direction",
     "'radial' is not allowed on the linear bench; expected one of: vertical"),
    ("duplicate", csv_file([*records(), records()[0]]), 3602, None,
     "duplicate of row 2: same lab, device, axis, frequency_hz, bench, direction and "
     "amplitude_m_s2"),
    ("lab column", changed(4, lab="L01"), 6, "lab",
     "is not allowed here: results are filed under your own laboratory; remove the lab column"),
]  # fmt: skip


@pytest.mark.parametrize(
    ("case", "data", "row", "field", "message"), BAD_ROWS, ids=[case[0] for case in BAD_ROWS]
)
def test_bad_row_is_named_and_nothing_stored(grid, case, data, row, field, message) -> None:
    assert refused(grid, data) == [(row, field, message)]


def test_every_bad_row_is_listed(grid) -> None:
    rows = records()
    rows[10]["sensitivity"] = "-1"
    rows[500]["axis"] = "Q"
    rows[3000]["expanded_uncertainty"] = "x%"
    assert [(r, f) for r, f, _ in refused(grid, csv_file(rows))] == [
        (12, "sensitivity"), (502, "axis"), (3002, "expanded_uncertainty"),
    ]  # fmt: skip


def test_non_utf8_is_refused(grid) -> None:
    data = changed(1, direction="vértical").decode().encode("latin-1")
    offset = data.index(b"\xe9")
    assert refused(grid, data) == [
        (3, None, f"the file is not UTF-8 text: byte 0xe9 at offset {offset} (line 3); save it "
                  "as 'CSV UTF-8' or as .xlsx"),
    ]  # fmt: skip


def test_formula_in_xlsx_is_refused(grid) -> None:
    assert refused(grid, xlsx_file(records(), formula="=F3/50"), "results.xlsx") == [
        (3, "expanded_uncertainty", "cell G3 contains a formula (=F3/50); formulas are "
                                    "refused, paste the values instead"),
    ]  # fmt: skip


def test_macro_enabled_workbook_is_refused(grid) -> None:
    data = xlsx_file(records()[:3])
    assert refused(grid, data, "results.xlsm") == [
        (None, None, "macro-enabled workbooks are refused; save the file as .xlsx or CSV"),
    ]
    with_vba = io.BytesIO(data)
    with zipfile.ZipFile(with_vba, "a") as archive:
        archive.writestr("xl/vbaProject.bin", b"\x00" * 100)
    assert refused(grid, with_vba.getvalue(), "results.xlsx") == [
        (None, None, "the workbook contains macros (xl/vbaProject.bin); save it as .xlsx "
                     "without macros"),
    ]  # fmt: skip


def test_zip_bomb_is_refused(grid) -> None:
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w", compression=zipfile.ZIP_DEFLATED) as archive:
        archive.writestr("xl/worksheets/sheet1.xml", b"\x00" * 20 * 2**20)
    [(row, field, message)] = refused(grid, buffer.getvalue(), "results.xlsx")
    assert (row, field) == (None, None)
    assert message.endswith(":1, the mark of a ZIP bomb; the limit is 100:1")


def test_file_over_5_mb_is_refused(grid) -> None:
    data = csv_file(records())
    data += b"\r\n" * ((int(5.3 * 2**20) - len(data)) // 2)
    assert refused(grid, data) == [(None, None, "the file is 5.3 MB; the limit is 5 MB")]


def test_too_many_rows_is_refused(grid) -> None:
    line = b"MEMS 1,X,1,linear,vertical,1,1\r\n"
    data = ",".join(HEADER).encode() + b"\r\n" + line * 100_001
    assert refused(grid, data) == [
        (None, None, "the table has more than 100000 data rows, the limit; split it"),
    ]


# --- the JSON path and the file path store the same thing ------------------------------------


def test_json_and_file_store_identical_rows(grid) -> None:
    participant, user = grid
    rows = records()
    for i, row in enumerate(rows):
        row["coverage_factor"] = ["2", "2.5", "1.96"][i % 3]
        if i % 4 == 1:
            row["expanded_uncertainty"] = "1.5%"
    other = ParticipantFactory.create(comparison=participant.comparison)
    json_rows = [
        {k: float(v) if k in ("frequency_hz", "sensitivity", "coverage_factor") else v
         for k, v in row.items()}
        for row in rows
    ]  # fmt: skip
    by_json = submission_from_records(
        participant=other, records=json_rows, source="api", user=user, submit=True
    )
    by_file = upload(grid, csv_file(rows))
    fields = ("measurement_point_id", "value", "expanded_uncertainty", "coverage_factor", "dof")
    assert list(by_json.results.order_by("measurement_point_id").values_list(*fields)) == list(
        by_file.results.order_by("measurement_point_id").values_list(*fields)
    )
    assert by_file.results.count() == 3600


# --- size -------------------------------------------------------------------------------------


@pytest.fixture
def big_grid():
    """An open comparison with exactly 100,000 points: 25 devices × 2 axes × 2000 frequencies."""
    comparison = ComparisonFactory.create(status="open")
    devices = [DeviceFactory.create(comparison=comparison, name=f"MEMS {i}") for i in range(1, 26)]
    frequencies = [1 + 0.5 * i for i in range(2000)]
    measurement_points_generate(
        comparison=comparison, devices=devices, axes=["X", "Y"], frequencies_hz=frequencies,
        benches=["linear"],
    )  # fmt: skip
    lines = [
        f"MEMS {d},{axis},{f:g},linear,{418 + f / 1000:.4f},1%"
        for d in range(1, 26)
        for axis in "XY"
        for f in frequencies
    ]
    data = ("device,axis,frequency_hz,bench,sensitivity,expanded_uncertainty\n"
            + "\n".join(lines)).encode()  # fmt: skip
    return ParticipantFactory.create(comparison=comparison), UserFactory.create(), data


def test_100k_row_csv_is_stored_completely(big_grid) -> None:
    participant, user, data = big_grid
    assert len(data) < 5 * 2**20
    submission = submission_from_file(
        participant=participant, data=data, filename="big.csv", user=user, submit=True
    )
    assert submission.status == "submitted"
    assert Result.objects.filter(submission=submission).count() == 100_000
    last = submission.results.get(
        measurement_point__device__name="MEMS 25", measurement_point__axis="Y",
        measurement_point__frequency_hz=1000.5,
    )  # fmt: skip
    assert (last.value, last.expanded_uncertainty) == (419.0005, pytest.approx(4.190005))
