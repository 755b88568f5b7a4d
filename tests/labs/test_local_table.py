"""labs.importers.local: a local results table read column-wise, exactly as an upload reads
it (same values, same problems), without the upload's size and row limits."""

from pathlib import Path
from typing import TypedDict

import numpy as np
import pytest

from labs.importers import ImportErrors, parse_table, write_table
from labs.importers import local as local_module
from labs.importers.local import LocalTable, read_local_table

HEADER = "lab,device,axis,frequency_hz,bench,direction,sensitivity,expanded_uncertainty"


class Limits(TypedDict):
    max_bytes: int
    max_rows: int


NO_LIMIT: Limits = {"max_bytes": 2**40, "max_rows": 10**9}
FIELDS = ("row", "lab", "device", "axis", "frequency_hz", "bench", "direction", "sensitivity",
          "expanded_uncertainty", "coverage_factor")  # fmt: skip


def upload_columns(path: Path) -> dict[str, np.ndarray]:
    rows = parse_table(path.read_bytes(), filename=path.name, lab_column="required", **NO_LIMIT)
    out = {f: np.array([getattr(r, f) for r in rows]) for f in FIELDS}
    out["amplitude_m_s2"] = np.array(
        [np.nan if r.amplitude_m_s2 is None else r.amplitude_m_s2 for r in rows]
    )
    return out


def assert_same(table: LocalTable, expected: dict[str, np.ndarray]) -> None:
    for name, values in expected.items():
        got = getattr(table, name)
        assert got.dtype == values.dtype, name
        np.testing.assert_array_equal(got, values, err_msg=name)  # NaN == NaN here


def upload_errors(path: Path) -> ImportErrors:
    with pytest.raises(ImportErrors) as err:
        parse_table(path.read_bytes(), filename=path.name, lab_column="required", **NO_LIMIT)
    return err.value


@pytest.fixture
def plain_only(monkeypatch):
    """Fail if the streaming importer is asked: the plain way must read the file."""

    def refuse(*args, **kwargs):
        raise AssertionError("read by the streaming importer")

    monkeypatch.setattr(local_module, "_streamed", refuse)


@pytest.fixture
def streamed(monkeypatch):
    calls = []
    real = local_module._streamed

    def spy(*args, **kwargs):
        calls.append(args)
        return real(*args, **kwargs)

    monkeypatch.setattr(local_module, "_streamed", spy)
    return calls


VARIED = [
    "lab,device,axis,frequency_hz,bench,direction,amplitude_m_s2,sensitivity,unit,"
    "expanded_uncertainty,coverage_factor,dof,note",
    " A ,MEMS  1,x,10,LINEAR,,2,420,,4,,,first",
    "A,MEMS 1,Y,1e1,linear,vertical,2,+4.2e2,D/(m/s^2),1%,2,10,",
    "B,MEMS 1,X,10,linear,Vertical,,419.9999999999999,,4.000000000000001,1.96,inf,=1+1",
    "B,MEMS 1,Y,10.0,linear,vertical,,0.24,mg/LSB,0.001,,12.5,mg/LSB",
    "C,MEMS 1,X,1.5,curvilinear,tangential,,418,lsb/(m/s^2),2.5%,3,,",
    "C,MEMS 1,X,1.5,Curvilinear,RADIAL,,417,,5,,,ö ünïcode",
    "'-D,MEMS 1,X,10,linear,vertical,,421,, 6 ,,,",
]


def test_varied_plain_file_as_an_upload(tmp_path, plain_only):
    path = tmp_path / "varied.csv"
    path.write_text("\n".join(VARIED) + "\n", encoding="utf-8")
    assert_same(read_local_table(path), upload_columns(path))


@pytest.mark.parametrize("block", [16, 64, 2**20])
def test_blocks_of_any_size(tmp_path, plain_only, block):
    path = tmp_path / "blocks.csv"
    lines = [HEADER] + [
        f"L{i % 7},MEMS {i % 3},{'XYZ'[i % 3]},{10 * (1 + i // 21)},linear,vertical,"
        f"{418 + i / 7!r},{4 + i / 100!r}"
        for i in range(300)
    ]
    path.write_bytes(("\r\n".join(lines) + "\r\n").encode())
    assert_same(read_local_table(path, block_bytes=block), upload_columns(path))


def test_bom_and_no_final_line_break(tmp_path, plain_only):
    path = tmp_path / "bom.csv"
    path.write_bytes(b"\xef\xbb\xbf" + (HEADER + "\nA,MEMS 1,X,10,linear,,420,4").encode())
    assert_same(read_local_table(path), upload_columns(path))


@pytest.mark.parametrize(
    "name,content",
    [
        ("quoted.csv", HEADER + '\n"A, the first",MEMS 1,X,10,linear,vertical,420,4\n'),
        ("semicolon.csv", HEADER.replace(",", ";") + "\nA;MEMS 1;X;10;linear;vertical;420,5;4\n"),
        ("blank-lines.csv", "\n" + HEADER + "\n\nA,MEMS 1,X,10,linear,vertical,420,4\n\n"),
        ("short-row.csv", HEADER + ",note\nA,MEMS 1,X,10,linear,vertical,420,4\n"),
        ("lone-cr.csv", HEADER + "\rA,MEMS 1,X,10,linear,vertical,420,4\r"),
        ("blank-header.csv", HEADER + ",\nA,MEMS 1,X,10,linear,vertical,420,4,\n"),
    ],
)
def test_other_files_read_by_the_streaming_importer(tmp_path, streamed, name, content):
    path = tmp_path / name
    path.write_text(content, encoding="utf-8", newline="")
    assert_same(read_local_table(path), upload_columns(path))
    assert streamed


def test_xlsx(tmp_path, streamed):
    rows = [
        {"lab": "A", "device": "MEMS 1", "axis": "X", "frequency_hz": 10.0, "bench": "linear",
         "sensitivity": 420.0 + i, "expanded_uncertainty": 4.0}
        for i in range(3)
    ]  # fmt: skip
    rows[1]["lab"], rows[2]["lab"] = "B", "C"
    path = tmp_path / "results.xlsx"
    path.write_bytes(write_table(rows, format="xlsx"))
    assert_same(read_local_table(path), upload_columns(path))
    assert streamed


@pytest.mark.parametrize(
    "line",
    [
        "B,MEMS 1,W,10,linear,vertical,420,4",  # unknown axis
        "B,MEMS 1,X,10,linear,vertical,-3,4",  # sensitivity <= 0
        "B,MEMS 1,X,10,linear,vertical,420,-3",
        "B,MEMS 1,X,10,linear,vertical,1e31,4",  # out of range
        "B,MEMS 1,X,10,linear,vertical,420,1e-31",
        "B,MEMS 1,X,10,linear,vertical,nan,4",
        "B,MEMS 1,X,10,linear,vertical,1_0,4",
        "B,MEMS 1,X,10,linear,tangential,420,4",  # wrong direction for the bench
        ",MEMS 1,X,10,linear,vertical,420,4",  # no lab
        "B,MEMS 1,X,10,linear,vertical,420,4,extra",
        "B,MEMS 1,X,10,linear,vertical,420\x00,4",
        "A,MEMS 1,X,10,linear,vertical,421,4",  # duplicate of row 2
        "A,MEMS 1,X,10.0000000000001,linear,vertical,421,4",  # also (12 digits)
    ],
)
def test_problems_as_an_upload_lists_them(tmp_path, line):
    path = tmp_path / "bad.csv"
    path.write_text(f"{HEADER}\nA,MEMS 1,X,10,linear,vertical,420,4\n{line}\n", encoding="utf-8")
    with pytest.raises(ImportErrors) as err:
        read_local_table(path)
    expected = upload_errors(path)
    assert str(err.value) == str(expected)
    assert err.value.total == expected.total


def test_header_problem(tmp_path):
    path = tmp_path / "header.csv"
    path.write_text("lab,device,axis,frequency,bench\nA,MEMS 1,X,10,linear\n")
    with pytest.raises(ImportErrors) as err:
        read_local_table(path)
    assert str(err.value) == str(upload_errors(path))


def test_more_than_1000_problems_listed_with_a_count(tmp_path):
    """1,500 bad rows (and 30 duplicates among the good ones): the first 1,000 in row
    order, then the count of the rest, as an upload gives them."""
    lines = [HEADER]
    for i in range(3000):
        u = "-3" if i % 2 else "4"
        lab = f"L{i}" if i < 2940 else "L0"
        lines.append(f"{lab},MEMS 1,X,10,linear,vertical,420,{u}")
    path = tmp_path / "many.csv"
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(ImportErrors) as err:
        read_local_table(path)
    expected = upload_errors(path)
    assert err.value.total == expected.total == 1500 + 30
    assert len(err.value.errors) == 1000
    assert str(err.value) == str(expected)
    assert str(err.value).endswith("... and 530 more problems")


def test_only_duplicates_from_the_plain_way(tmp_path, plain_only):
    path = tmp_path / "dups.csv"
    body = [f"L{i % 5},MEMS 1,X,10,linear,vertical,420,4" for i in range(12)]
    path.write_text("\n".join([HEADER, *body]) + "\n")
    with pytest.raises(ImportErrors) as err:
        read_local_table(path, block_bytes=100)
    assert str(err.value) == str(upload_errors(path))
    assert err.value.total == 7


def test_empty_table(tmp_path):
    path = tmp_path / "empty.csv"
    path.write_text(HEADER + "\n")
    with pytest.raises(ImportErrors) as err:
        read_local_table(path)
    assert str(err.value) == str(upload_errors(path)) == "the table has no data rows"


def test_no_upload_limit(tmp_path, plain_only):
    """A file the upload refuses (here: with its limits at 1 kB and 20 rows) is read whole."""
    path = tmp_path / "round.csv"
    lines = [HEADER] + [f"L{i},MEMS 1,X,10,linear,vertical,{420 + i / 10!r},4" for i in range(50)]
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(ImportErrors, match="the limit is 1 kB"):
        parse_table(path.read_bytes(), lab_column="required", max_bytes=1024)
    with pytest.raises(ImportErrors, match="more than 20 data rows"):
        parse_table(path.read_bytes(), lab_column="required", max_rows=20)
    assert len(read_local_table(path)) == 50


def test_streaming_importer_reads_a_file_that_starts_with_blank_lines():
    """The 4 bytes it reads first to tell XLSX from CSV may hold whole lines."""
    import io

    from labs.importers.stream import read_chunks

    data = ("\n\n" + HEADER + "\nA,MEMS 1,X,10,linear,vertical,420,4\n").encode()
    (chunk,) = read_chunks(io.BytesIO(data), filename="x.csv")
    assert not chunk.errors and [r.row for r in chunk.rows] == [4]


def test_xlsx_without_the_uploads_size_limits(tmp_path, monkeypatch):
    """A workbook over the upload's unpacked-size limit (lowered here to 1 kB) is read; a
    macro-enabled one is still refused."""
    from labs.importers import readers

    rows = [
        {"lab": f"L{i}", "device": "MEMS 1", "axis": "X", "frequency_hz": 10.0,
         "bench": "linear", "sensitivity": 420.0 + i, "expanded_uncertainty": 4.0}
        for i in range(40)
    ]  # fmt: skip
    path = tmp_path / "round.xlsx"
    path.write_bytes(write_table(rows, format="xlsx"))
    monkeypatch.setattr(readers, "MAX_UNCOMPRESSED_BYTES", 1024)
    with pytest.raises(ImportErrors, match="unpacks to"):
        parse_table(path.read_bytes(), filename=path.name, lab_column="required")
    assert len(read_local_table(path)) == 40
