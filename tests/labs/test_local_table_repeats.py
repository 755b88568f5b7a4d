"""repeat_sd and n_repeats read from a local table (pt_compare) as an upload reads them: the
plain way and the streaming importer give the upload's values and problems."""

from pathlib import Path

import numpy as np
import pytest

from labs.importers import ImportErrors
from labs.importers.local import read_local_table
from tests.labs.test_local_table import (
    assert_same,
    plain_only,
    streamed,
    upload_columns,
    upload_errors,
)

__all__ = ["plain_only", "streamed"]  # fixtures
HEADER = (
    "lab,device,axis,frequency_hz,bench,sensitivity,unit,expanded_uncertainty,repeat_sd,n_repeats"
)
ROWS = [
    "A,MEMS 1,X,10,linear,420,,4,0.3,5",
    "B,MEMS 1,X,10,linear,421,,4,,",
    "C,MEMS 1,X,10,linear,0.24,mg/LSB,0.001,0.0005,3.0",
    "A,MEMS 1,Y,10,linear,419,,4,1e-3,1000",
]


def write(tmp_path: Path, lines: list[str]) -> Path:
    path = tmp_path / "round.csv"
    path.write_text("\n".join(lines) + "\n")
    return path


def expected(path: Path) -> dict[str, np.ndarray]:
    from labs.importers import parse_table

    rows = parse_table(path.read_bytes(), lab_column="required")
    out = upload_columns(path)
    out["repeat_sd"] = np.array([np.nan if r.repeat_sd is None else r.repeat_sd for r in rows])
    out["n_repeats"] = np.array([r.n_repeats or 0 for r in rows], np.int64)
    return out


def test_plain_way_reads_the_repeats_as_an_upload(tmp_path, plain_only):
    path = write(tmp_path, [HEADER, *ROWS])
    table = read_local_table(path)
    assert_same(table, expected(path))
    assert table.n_repeats.tolist() == [5, 0, 3, 1000]
    assert table.repeat_sd[2] == pytest.approx(table.sensitivity[2] * 0.0005 / 0.24, rel=1e-14)


def test_streamed_way_reads_them_too(tmp_path, streamed):
    path = write(tmp_path, [HEADER.replace(",", ";"), *(r.replace(",", ";") for r in ROWS)])
    assert_same(read_local_table(path), expected(path))
    assert streamed


@pytest.mark.parametrize(
    "row",
    ["B,MEMS 1,Y,10,linear,421,,4,0.3,", "B,MEMS 1,Y,10,linear,421,,4,,4",
     "B,MEMS 1,Y,10,linear,421,,4,0.3,1", "B,MEMS 1,Y,10,linear,421,,4,-0.3,4"],
)  # fmt: skip
def test_problems_as_an_upload_lists_them(tmp_path, row):
    path = write(tmp_path, [HEADER, ROWS[0], row])
    with pytest.raises(ImportErrors) as err:
        read_local_table(path)
    want = upload_errors(path)
    assert [(e.row, e.field, e.message) for e in err.value.errors] == [
        (e.row, e.field, e.message) for e in want.errors
    ]
    assert want.errors and want.errors[0].field in ("repeat_sd", "n_repeats")
