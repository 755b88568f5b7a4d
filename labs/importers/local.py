"""A results table from a local file, read into numpy columns without the upload's limits.

The web upload and the API hold a whole file in a server shared by everyone, so they
refuse one over :data:`~labs.importers.MAX_BYTES` or :data:`~labs.importers.MAX_ROWS`.
A file on one's own machine (``pt_compare``, docs/interfaces.md §4) may be a whole national
round: it is read here in blocks, into one numpy array per column (no Python object
per result outlives its block), with the upload's own checks and messages. No Django.

Two ways, one result:

* **plain CSV**, the usual machine-written file (comma-separated UTF-8, no quotes, every
  line with the header's number of cells, no blank line, LF or CRLF): each block of
  lines is split with ``str.split``; each distinct text cell (a round repeats its labs,
  devices, axes, benches and frequencies) goes once through the importer's own per-cell
  check (:func:`labs.importers.columns.field_checks`), numbers through ``float()`` as the
  importer's fast path does, then the row-level steps of
  :func:`labs.importers.columns.validate_columns` on whole arrays;
* **anything else** (XLSX, semicolons, quoted cells, blank or ragged lines, a
  ``quantity`` column, whose kinds have their own checks) and **every file with a
  problem** is read again by the streaming importer
  (:func:`labs.importers.stream.read_chunks`), so each message is the one an upload gives.
  Problems are listed up to :data:`~labs.importers.errors.MAX_LISTED_ERRORS`, with the
  count of the rest.
"""

from __future__ import annotations

import codecs
import os
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, fields
from typing import BinaryIO

import numpy as np

from common.numbers import percent_fraction
from common.quantities import DEFAULT as DEFAULT_QUANTITY

from .columns import Compute, _Validator, field_checks
from .errors import MAX_LISTED_ERRORS, ImportErrors, RowError
from .readers import sniff_delimiter
from .schema import COLUMNS, DEFAULT_COVERAGE_FACTOR, LabColumn, ResultRow
from .stream import read_chunks
from .table import _gc_paused
from .validate import _error_order, check_header
from .values import MAX_MAGNITUDE, MG_PER_LSB, MIN_MAGNITUDE
from .values import mg_per_lsb_to_canonical as _mg_per_lsb

__all__ = ["LocalTable", "read_local_table"]

BLOCK_BYTES = 8 * 2**20
DUPLICATE = (
    "duplicate of row {}: same lab, device, axis, frequency_hz, bench, direction and amplitude_m_s2"
)


@dataclass(frozen=True)
class LocalTable:
    """The validated results, one entry per result in every array, in file order.

    Text columns are numpy ``str_`` arrays (as ``np.array([...], dtype=np.str_)`` of the
    rows' values); ``amplitude_m_s2`` and ``repeat_sd`` are NaN, ``n_repeats`` 0, where
    none was given. ``sensitivity``, ``expanded_uncertainty`` and ``repeat_sd`` are after
    the conversions of an upload (``%``, ``mg/LSB``).
    """

    row: np.ndarray
    lab: np.ndarray
    device: np.ndarray
    axis: np.ndarray
    frequency_hz: np.ndarray
    bench: np.ndarray
    direction: np.ndarray
    quantity: np.ndarray
    amplitude_m_s2: np.ndarray
    sensitivity: np.ndarray
    expanded_uncertainty: np.ndarray
    coverage_factor: np.ndarray
    repeat_sd: np.ndarray
    n_repeats: np.ndarray

    def __len__(self) -> int:
        return int(self.row.size)


_FIELDS = [f.name for f in fields(LocalTable)]
_TEXT_FIELDS = ("lab", "device", "axis", "bench", "direction", "quantity")


class _NotPlain(Exception):
    """The file is not a plain CSV, or has a problem: the streaming importer reads it."""


def read_local_table(
    path: str | os.PathLike[str],
    *,
    lab_column: LabColumn = "required",
    block_bytes: int = BLOCK_BYTES,
) -> LocalTable:
    """Read and check a CSV or XLSX results table (docs/interfaces.md §1) from a local file.

    Raises :class:`ImportErrors` with the first problems in row order and the count of
    all of them, exactly as an upload of the same file would list them.
    """
    if lab_column != "required":
        raise ValueError("a local table is read with its lab column (lab_column='required')")
    with _gc_paused():  # millions of cells alive at once, none in a cycle
        try:
            with open(path, "rb") as stream:
                return _Plain(stream, lab_column, block_bytes).read()
        except _NotPlain:
            pass
        with open(path, "rb") as stream:
            return _streamed(stream, os.fspath(path), lab_column)


# --- the plain CSV -----------------------------------------------------------------------------


class _Codes:
    """The distinct cells of one column, in order of appearance, and each cell's code."""

    def __init__(self) -> None:
        self.index: dict[object, int] = {}
        self.codes: list[np.ndarray] = []

    def add(self, cells: Sequence[object]) -> None:
        index = self.index
        for cell in dict.fromkeys(cells):
            index.setdefault(cell, len(index))
        self.codes.append(np.fromiter(map(index.__getitem__, cells), np.int64, len(cells)))

    def all_codes(self) -> np.ndarray:
        return np.concatenate(self.codes) if self.codes else np.zeros(0, np.int64)


#: Text columns of the measurement point (and the unit, which goes with the device): a
#: round repeats few combinations of them, so each row's combination is looked up once.
_POINT_TEXT = ("device", "axis", "frequency_hz", "bench", "direction", "unit")
#: Other columns checked once per distinct cell (``n_repeats``: a whole number, few values;
#: ``measured_on``: a date, checked and not kept, ``pt_compare`` knows no kits).
_CODED = ("lab", "note", "n_repeats", "measured_on")


class _Plain:
    """The plain-CSV reading; raises :class:`_NotPlain` as soon as the file is anything else."""

    def __init__(self, stream: BinaryIO, lab_column: LabColumn, block_bytes: int) -> None:
        self.stream, self.lab_column, self.block_bytes = stream, lab_column, block_bytes
        self.checks = {
            f: (kind, check, dep) for f, kind, check, dep in field_checks(None, lab_column)
        }
        self.validator = _Validator({}, [], False)  # its per-cell check, on one cell at a time
        self.memo: dict[tuple[str, object, object], object] = {}
        self.names: list[str] = []
        self.point_names: list[str] = []
        self.points = _Codes()  # of the rows' point columns, as tuples
        self.texts: dict[str, _Codes] = {}  # lab, note, n_repeats, measured_on
        self.numbers: dict[str, list[np.ndarray]] = {}
        self.relative: list[np.ndarray] = []  # expanded_uncertainty given in %
        self.n_rows = 0

    def read(self) -> LocalTable:
        for text, n_lines in self._blocks():
            self._take(text, n_lines)
        if not self.n_rows:
            raise _NotPlain  # the importer says what is missing
        return self._assemble()

    def _blocks(self) -> Iterator[tuple[str, int]]:
        """Decoded blocks of whole data lines, each line ending in ``\\n``, and their count."""
        rest = self.stream.read(self.block_bytes)
        if rest.startswith(codecs.BOM_UTF8):
            rest = rest[3:]
        first = True
        while rest:
            more = self.stream.read(self.block_bytes)
            if more:
                cut = rest.rfind(b"\n")
                if cut < 0:
                    rest += more  # a block holds at least one whole line
                    continue
                block, rest = rest[: cut + 1], rest[cut + 1 :] + more
            else:
                block, rest = rest if rest.endswith(b"\n") else rest + b"\n", b""
            block = _plain_bytes(block)
            if first:
                end = block.index(b"\n") + 1
                self._header(block[:end])
                block, first = block[end:], False
            if block:
                yield self._decoded(block)

    def _header(self, line: bytes) -> None:
        text = _decode(line).rstrip("\n")
        if not text.strip() or sniff_delimiter(text) != ",":
            raise _NotPlain
        cells = text.split(",")
        if len(cells) > len(COLUMNS) or any(not c.strip() for c in cells):
            raise _NotPlain
        try:
            self.names = check_header(cells, lab_column=self.lab_column, row=1)
        except ImportErrors:
            raise _NotPlain from None
        if "quantity" in self.names:  # kinds have their own checks: the importer's own way
            raise _NotPlain
        self.point_names = [n for n in self.names if n in _POINT_TEXT]
        self.texts = {n: _Codes() for n in self.names if n in _CODED}
        self.numbers = {n: [] for n in self.names if self.checks[n][0] == "number"}

    def _decoded(self, block: bytes) -> tuple[str, int]:
        """The block as text, once every line is seen to hold exactly the header's cells."""
        width = len(self.names)
        codes = np.frombuffer(block, np.uint8)
        seps = np.flatnonzero((codes == 44) | (codes == 10))  # "," and "\n"
        n_lines = int(np.count_nonzero(codes[seps] == 10))
        if seps.size != n_lines * width or not (codes[seps[width - 1 :: width]] == 10).all():
            raise _NotPlain
        return _decode(block), n_lines

    def _take(self, text: str, n_lines: int) -> None:
        cells = text.replace("\n", ",").split(",")
        cells.pop()  # after the last "\n"
        width = len(self.names)
        first_row = 2 + self.n_rows
        columns = {name: cells[j::width] for j, name in enumerate(self.names)}
        del cells
        self.points.add(list(zip(*(columns[n] for n in self.point_names), strict=True)))
        for name, codes in self.texts.items():
            codes.add(columns[name])
        for name in self.numbers:
            self._number_column(name, columns[name], first_row)
        self.n_rows += n_lines

    def _number_column(self, name: str, cells: list[str], first_row: int) -> None:
        """Plain numbers as ``_fast_number`` reads them; any other cell by the importer's
        own column pass (``_Validator.number_column``): a problem sends the file there."""
        values = _plain_floats(cells)
        relative = None
        if values is None:
            numbers = range(first_row, first_row + len(cells))
            v = _Validator({name: cells}, numbers, False)
            out = v.number_column(name, self.checks[name][1])
            if v.errors:
                raise _NotPlain
            if name == "expanded_uncertainty":
                relative = np.array([type(x) is tuple and x[1] for x in out], bool)
                out = [x[0] if type(x) is tuple else x for x in out]
            values = np.array([np.nan if x is None else x for x in out], np.float64)
        self.numbers[name].append(values)
        if name == "expanded_uncertainty":
            self.relative.append(np.zeros(len(cells), bool) if relative is None else relative)

    # --- whole columns ---------------------------------------------------------------------

    def _checked(
        self, name: str, raws: Sequence[object], depends: Sequence[object] | None = None
    ) -> list[object]:
        """Each cell (with its dependency's value) through the importer's check, once."""
        check, memo = self.checks[name][1], self.memo
        out = []
        for i, raw in enumerate(raws):
            dependency = None if depends is None else depends[i]
            key = (name, raw, dependency)
            if key not in memo:
                compute = check if depends is None else _bound(check, dependency)
                value, problems = self.validator.precise(name, raw, compute)
                if problems:
                    raise _NotPlain
                memo[key] = value
            out.append(memo[key])
        return out

    def _point_values(self) -> dict[str, list[object]]:
        """Each distinct combination of the point columns, checked column by column (an
        absent column as a blank cell)."""
        combos = list(self.points.index)
        raw: dict[str, list[object]] = {n: [None] * len(combos) for n in _POINT_TEXT}
        for j, name in enumerate(self.point_names):
            raw[name] = [c[j] for c in combos]  # type: ignore[index]
        out = {n: self._checked(n, raw[n]) for n in ("device", "axis", "frequency_hz", "bench")}
        out["direction"] = self._checked("direction", raw["direction"], out["bench"])
        out["unit"] = self._checked("unit", raw["unit"], out["device"])
        return out

    def _text(self, name: str) -> tuple[list[object], np.ndarray]:
        """Lab, note, n_repeats or measured_on: checked values per distinct cell and each
        row's code."""
        codes = self.texts.get(name)
        if codes is None:  # an absent column: one blank cell stands for every row
            return self._checked(name, [None]), np.zeros(self.n_rows, np.int64)
        return self._checked(name, list(codes.index)), codes.all_codes()

    def _number(self, name: str) -> np.ndarray:
        if name in self.numbers:
            return np.concatenate(self.numbers[name])
        (value,) = self._checked(name, [None])
        return np.full(self.n_rows, np.nan if value is None else value)

    def _repeats(self) -> tuple[np.ndarray, np.ndarray]:
        """repeat_sd (NaN where none) and n_repeats (0 where none); a row with one and not
        the other sends the file to the importer, which names the missing column."""
        repeat_sd = self._number("repeat_sd")
        values, codes = self._text("n_repeats")
        n_repeats = np.array([0 if v is None else v for v in values], np.int64)[codes]
        if not np.array_equal(np.isnan(repeat_sd), n_repeats == 0):
            raise _NotPlain
        return repeat_sd, n_repeats

    def _assemble(self) -> LocalTable:
        """The row-level steps of ``validate_columns`` on whole columns."""
        point, at = self._point_values(), self.points.all_codes()
        labs, lab_codes = self._text("lab")
        self._text("note")
        self._text("measured_on")
        sensitivity = self._number("sensitivity")
        expanded = self._number("expanded_uncertainty")
        if "expanded_uncertainty" in self.numbers:
            relative = np.concatenate(self.relative)
            fraction = np.array([percent_fraction(p) for p in expanded[relative].tolist()])
            expanded[relative] = sensitivity[relative] * fraction  # as relative_to_absolute
        repeat_sd, n_repeats = self._repeats()
        mg = np.array([u == MG_PER_LSB for u in point["unit"]], bool)[at]
        if mg.any():  # as an upload: the relative uncertainty is kept through the inversion
            converted = _mg_per_lsb(sensitivity[mg])  # the same arithmetic on an array
            expanded[mg] = converted * expanded[mg] / sensitivity[mg]
            repeat_sd[mg] = converted * repeat_sd[mg] / sensitivity[mg]
            sensitivity[mg] = converted
        k = self._number("coverage_factor")
        k = np.where(np.isnan(k), DEFAULT_COVERAGE_FACTOR, k)
        if not (_in_range(sensitivity) & _in_range(expanded) & _in_range(expanded / k)).all():
            raise _NotPlain
        if not _in_range(repeat_sd[n_repeats > 0]).all():
            raise _NotPlain
        table = LocalTable(
            row=np.arange(2, 2 + self.n_rows, dtype=np.int64),
            lab=np.array(labs, np.str_)[lab_codes],
            **{
                n: np.array(point[n], np.str_)[at] for n in ("device", "axis", "bench", "direction")
            },
            frequency_hz=np.array(point["frequency_hz"], np.float64)[at],
            quantity=np.full(self.n_rows, DEFAULT_QUANTITY),  # dtype from the text: U9
            amplitude_m_s2=self._number("amplitude_m_s2"),
            sensitivity=sensitivity,
            expanded_uncertainty=expanded,
            coverage_factor=k,
            repeat_sd=repeat_sd,
            n_repeats=n_repeats,
        )
        names = ("device", "axis", "bench", "direction")
        keys = [  # what validate._duplicate_key takes of the point, per combination
            (*(point[n][i] for n in names), _rounded_key(point["frequency_hz"][i]))  # type: ignore[arg-type]
            for i in range(len(point["device"]))
        ]
        duplicates, total = _duplicates(
            table.row, [_value_codes(labs, lab_codes), _value_codes(keys, at),
                        _float_codes(table.amplitude_m_s2)],
        )  # fmt: skip
        if total:
            raise ImportErrors(duplicates, total)
        return table


def _bound(check: Compute, dependency: object) -> Compute:
    return lambda c: check(c, dependency)


def _in_range(values: np.ndarray) -> np.ndarray:
    return (values >= MIN_MAGNITUDE) & (values <= MAX_MAGNITUDE)


def _plain_bytes(block: bytes) -> bytes:
    """The block with CRLF as LF; a quote, a lone CR or a NUL leaves the plain way."""
    if b"\r" in block:
        block = block.replace(b"\r\n", b"\n")
        if b"\r" in block:
            raise _NotPlain
    if b'"' in block or b"\x00" in block:
        raise _NotPlain
    return block


def _decode(block: bytes) -> str:
    try:
        return block.decode("utf-8")
    except UnicodeDecodeError:
        raise _NotPlain from None


def _plain_floats(cells: list[str]) -> np.ndarray | None:
    """The cells as floats when every one is what :func:`~labs.importers.columns._fast_number`
    takes (printable ASCII without ``_`` that ``float()`` reads, within the safe range);
    ``np.array(cells, float)`` reads each cell with ``float()``."""
    joined = "".join(cells)
    if "_" in joined or not (joined.isascii() and joined.isprintable()):
        return None
    try:
        values = np.array(cells, dtype=np.float64)
    except ValueError:
        return None
    return values if _in_range(values).all() else None


# --- the streaming importer ------------------------------------------------------------------


def _streamed(stream: BinaryIO, name: str, lab_column: LabColumn) -> LocalTable:
    """The file read by the streaming importer, chunk by chunk, each chunk's good rows kept
    as columns; problems listed as an upload lists them (the first in row order, and the
    count of all, duplicates among the good rows included)."""
    listed: list[RowError] = []
    total = 0
    parts: list[dict[str, np.ndarray]] = []
    try:
        for chunk in read_chunks(stream, filename=name, lab_column=lab_column, limits=False):
            total += len(chunk.errors)
            listed.extend(chunk.errors[: max(0, MAX_LISTED_ERRORS - len(listed))])
            parts.append(_row_columns(chunk.rows))
    except ImportErrors as exc:  # the file cannot be read on (header, encoding, a huge row)
        raise ImportErrors([*listed, *exc.errors][:MAX_LISTED_ERRORS], total + exc.total) from None
    table = LocalTable(**{f: _concat(parts, f) for f in _FIELDS})
    duplicates, more = find_duplicates(table)
    if total or more:
        found = sorted([*listed, *duplicates], key=_error_order)[:MAX_LISTED_ERRORS]
        raise ImportErrors(found, total + more)
    if not len(table):
        raise ImportErrors([RowError(None, None, "the table has no data rows")])
    return table


def _row_columns(rows: list[ResultRow]) -> dict[str, np.ndarray]:
    def col(name: str, dtype: type) -> np.ndarray:
        return np.array([getattr(r, name) for r in rows], dtype=dtype)

    amplitude = [np.nan if r.amplitude_m_s2 is None else r.amplitude_m_s2 for r in rows]
    return {
        "row": col("row", np.int64),
        **{n: col(n, np.str_) for n in _TEXT_FIELDS},
        "frequency_hz": col("frequency_hz", np.float64),
        "amplitude_m_s2": np.array(amplitude, np.float64),
        "sensitivity": col("sensitivity", np.float64),
        "expanded_uncertainty": col("expanded_uncertainty", np.float64),
        "coverage_factor": col("coverage_factor", np.float64),
        "repeat_sd": np.array([r.repeat_sd or np.nan for r in rows], np.float64),
        "n_repeats": np.array([r.n_repeats or 0 for r in rows], np.int64),
    }


def _concat(parts: list[dict[str, np.ndarray]], name: str) -> np.ndarray:
    if not parts:
        kind = np.str_ if name in _TEXT_FIELDS else np.int64 if name == "n_repeats" else np.float64
        return np.array([], dtype=kind)
    return np.concatenate([p[name] for p in parts])


# --- duplicates ------------------------------------------------------------------------------


def find_duplicates(table: LocalTable) -> tuple[list[RowError], int]:
    """:func:`labs.importers.validate.find_duplicates` on columns: an error on every row
    repeating the lab and measurement point of an earlier row (frequency and amplitude
    compared to 12 significant digits), naming the first such row. The first
    :data:`MAX_LISTED_ERRORS` of them, and how many there are."""
    columns = [table.lab, table.device, table.axis, table.bench, table.direction, table.quantity]
    codes = [(np.unique(c, return_inverse=True)[1].reshape(-1), len(c)) for c in columns]
    codes += [_float_codes(table.frequency_hz), _float_codes(table.amplitude_m_s2)]
    return _duplicates(table.row, codes)


def _duplicates(
    rows: np.ndarray, codes: list[tuple[np.ndarray, int]]
) -> tuple[list[RowError], int]:
    """Rows whose codes all equal an earlier row's (``codes``: per column, each row's code
    and an upper bound of the codes)."""
    n = rows.size
    key, size = np.zeros(n, np.int64), 1
    for column, bound in codes:
        if size * max(bound, 1) >= 2**62:
            key = np.unique(key, return_inverse=True)[1].reshape(-1)
            size = n
        key, size = key * max(bound, 1) + column, size * max(bound, 1)
    order = np.argsort(key, kind="stable")
    first = np.ones(n, bool)
    first[1:] = key[order][1:] != key[order][:-1]
    if first.all():
        return [], 0
    earlier = np.empty(n, np.int64)  # per row: the first row with its key
    earlier[order] = order[np.maximum.accumulate(np.where(first, np.arange(n), 0))]
    repeats = np.sort(order[~first])
    listed = [
        RowError(int(rows[i]), None, DUPLICATE.format(int(rows[earlier[i]])))
        for i in repeats[:MAX_LISTED_ERRORS].tolist()
    ]
    return listed, int(repeats.size)


def _value_codes(values: Sequence[object], codes: np.ndarray) -> tuple[np.ndarray, int]:
    """Codes of the distinct checked values (two cells may check to the same value)."""
    ids: dict[object, int] = {}
    remap = np.array([ids.setdefault(v, len(ids)) for v in values], np.int64)
    return (remap[codes] if codes.size else codes), len(ids)


def _rounded_key(value: float) -> float:
    return float(f"{value:.12g}")


def _float_codes(values: np.ndarray) -> tuple[np.ndarray, int]:
    """Codes of ``float(f"{v:.12g}")`` per value (NaN, for none, is one code)."""
    uniques, codes = np.unique(values, return_inverse=True)
    rounded = [_rounded_key(v) for v in uniques.tolist()]
    return _value_codes(rounded, codes.reshape(-1))
