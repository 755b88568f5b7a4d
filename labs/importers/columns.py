"""Column-wise validation: the fast path of :func:`labs.importers.validate.validate_records`.

Same rows, same errors, same order; only faster. Each column is converted once:
numbers through ``float()`` when the text is plainly a positive finite number,
every other cell through the precise per-cell check of :mod:`.validate`, whose
answer is remembered per distinct cell value (a table repeats its devices, axes,
benches and frequencies thousands of times). Only the checks that join columns
(the measurement point, duplicates) run once per row.
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Callable, Iterable, Mapping, Sequence

from common import quantities

from .errors import MAX_LISTED_ERRORS, ImportErrors, RowError
from .schema import (
    AXES,
    BENCHES,
    COLUMNS,
    DEFAULT_COVERAGE_FACTOR,
    LabColumn,
    ResultRow,
    TableContext,
)
from .validate import (
    Refused,
    _check_point,
    _device,
    _direction,
    _error_order,
    _frequency,
    _lab,
    _measured_on,
    _n_repeats,
    _note,
    _quantity,
    _RowCheck,
    _sensitivity,
    _uncertainty,
    _unit,
    cells_to_record,
    convert_units,
    find_duplicates,
    magnitude_problems,
    relative_to_absolute,
    repeat_problems,
)
from .values import MAX_MAGNITUDE, MIN_MAGNITUDE

Cell = tuple[object, tuple[tuple[str | None, str], ...]]
Compute = Callable[..., object]  # (check) or, for a dependent column, (check, dependency)

_MIN, _MAX = MIN_MAGNITUDE, MAX_MAGNITUDE
_NEW = object.__new__
#: The slot setters of ResultRow in field order: building 100,000 rows through them
#: skips the frozen dataclass ``__init__`` and takes about half the time.
_ROW_SETTERS = tuple(ResultRow.__dict__[f.name].__set__ for f in dataclasses.fields(ResultRow))
#: The plain number columns: (required, infinity allowed).
_NUMBERS: dict[str, tuple[bool, bool]] = {
    "amplitude_m_s2": (False, False),
    "sensitivity": (True, False),
    "coverage_factor": (False, False),
    "dof": (False, True),
    "repeat_sd": (False, False),
}


class _Validator:
    """The columns of one table and every problem found in them so far."""

    def __init__(
        self,
        columns: Mapping[str, Sequence[object]],
        numbers: Sequence[int],
        decimal_comma: bool,
        cap: int | None = None,
    ) -> None:
        self.columns = columns
        self.numbers = numbers
        self.decimal_comma = decimal_comma
        self.bad = bytearray(len(numbers))
        self.errors: list[RowError] = []
        #: Each pass over a column meets the rows in order: past ``cap`` problems in a
        #: pass, the rest are only counted (``dropped``). The first ``cap`` problems of
        #: the whole table in row order are still all kept (a pass keeps its last row whole).
        self.cap = cap
        self.dropped = 0
        self._kept = 0
        self._last_row: int | None = None

    def new_pass(self) -> None:
        self._kept, self._last_row = 0, None

    def raw(self, field: str) -> Sequence[object]:
        return self.columns.get(field) or [None] * len(self.numbers)

    def absent(self, field: str, compute: Compute) -> list[object] | None:
        """A column the table lacks: one check of a blank cell stands for every row."""
        if field in self.columns:
            return None
        value, problems = self.precise(field, None, compute)
        if problems:
            for i, number in enumerate(self.numbers):
                self.fail(i, number, problems)
        return [value] * len(self.numbers)

    def precise(self, field: str, raw: object, compute: Compute) -> Cell:
        """The per-cell check of :mod:`.validate` on one value: (value, problems)."""
        check = _RowCheck({field: raw}, 0, self.decimal_comma)
        try:
            value = compute(check)
        except Refused:  # a control character: its error is recorded
            value = None
        return value, tuple((e.field, e.message) for e in check.errors)

    def column(
        self, field: str, compute: Compute, depends: Sequence[object] | None = None
    ) -> list[object]:
        """``compute`` on every cell of ``field``, once per distinct (dependency, value)."""
        self.new_pass()
        if depends is None and (broadcast := self.absent(field, compute)) is not None:
            return broadcast
        memo: dict[object, Cell] = {}
        out: list[object] = []
        numbers, append = self.numbers, out.append
        for i, raw in enumerate(self.raw(field)):
            key: object = raw if type(raw) is str else (type(raw), raw)
            if depends is not None:
                key = (depends[i], key)
            try:
                value, problems = memo[key]
            except KeyError:
                value, problems = memo[key] = self.precise(field, raw, _bind(compute, depends, i))
            except TypeError:  # an unhashable cell is checked on its own
                value, problems = self.precise(field, raw, _bind(compute, depends, i))
            if problems:
                self.fail(i, numbers[i], problems)
            append(value)
        return out

    def number_column(self, field: str, compute: Compute) -> list[object]:
        """Plain positive finite numbers through ``float()``; the rest as :meth:`column`."""
        self.new_pass()
        if (broadcast := self.absent(field, compute)) is not None:
            return broadcast
        raws = self.raw(field)
        out: list[object] = [_fast_number(raw, self.decimal_comma) for raw in raws]
        slow = [i for i, value in enumerate(out) if value is None]
        if slow:
            memo: dict[object, Cell] = {}
            for i in slow:
                raw = raws[i]
                key: object = raw if type(raw) is str else (type(raw), raw)
                if key not in memo:
                    memo[key] = self.precise(field, raw, compute)
                value, problems = memo[key]
                if problems:
                    self.fail(i, self.numbers[i], problems)
                out[i] = value
        return out

    def fail(self, index: int, row: int, problems: Sequence[tuple[str | None, str]]) -> None:
        self.bad[index] = 1
        self.note(row, problems)

    def note(self, row: int, problems: Sequence[tuple[str | None, str]]) -> None:
        if self.cap is None or self._kept < self.cap or row == self._last_row:
            self.errors.extend(RowError(row, field, message) for field, message in problems)
            self._kept += len(problems)
            self._last_row = row
        else:
            self.dropped += len(problems)


def _bind(compute: Compute, depends: Sequence[object] | None, i: int) -> Compute:
    if depends is None:
        return compute
    dependency = depends[i]
    return lambda check: compute(check, dependency)


def _fast_number(raw: object, decimal_comma: bool) -> float | None:
    """``raw`` as a float when it is plainly a number within the safe range, else ``None``.

    Printable ASCII without ``_``, once a single decimal comma is made a point, text
    that ``float()`` reads as a finite number is exactly what the precise parser's
    pattern accepts (``float`` strips the same whitespace); anything else (blanks,
    other digits than ASCII, control characters) goes to the precise check.
    """
    kind = type(raw)
    if kind is float:
        return raw if _MIN <= raw <= _MAX else None  # type: ignore[operator,return-value]
    # ``type(raw) is`` narrows nothing for mypy, and isinstance would let subclasses in
    if kind is not str or "_" in raw or not (raw.isascii() and raw.isprintable()):  # type: ignore[operator,attr-defined]
        return None
    text: str = raw  # type: ignore[assignment]
    if "," in text:
        if not decimal_comma or text.count(",") != 1 or "." in text:
            return None
        text = text.replace(",", ".")
    try:
        value = float(text)
    except ValueError:
        return None
    return value if _MIN <= value <= _MAX else None


#: How a column is read: ``text`` (each distinct cell checked once), ``number`` (plain
#: numbers through ``float()``, the rest checked once per distinct cell) or ``depends``
#: (checked once per distinct pair of the cell and another column's value).
FieldCheck = tuple[str, str, Compute, str | None]


def field_checks(context: TableContext | None, lab_column: LabColumn) -> list[FieldCheck]:
    """``(field, kind, check, dependency)`` for every column, in the order they are read:
    the one table of per-cell checks, shared with :mod:`labs.importers.local`."""
    axes = context.axes if context else AXES
    benches = context.benches if context else BENCHES
    bench_universe = tuple(dict.fromkeys((*BENCHES, *benches)))
    checks: list[FieldCheck] = [
        ("device", "text", lambda c: _device(c, context), None),
        ("axis", "text", lambda c: c.choice("axis", axes, AXES), None),
        ("frequency_hz", "text", lambda c: _frequency(c, context), None),
        ("bench", "text", lambda c: c.choice("bench", benches, bench_universe), None),
        ("quantity", "text", _quantity, None),
        ("expanded_uncertainty", "number", _uncertainty, None),
        ("lab", "text", lambda c: _lab(c, lab_column), None),
        ("note", "text", _note, None),
        ("n_repeats", "text", _n_repeats, None),
        ("measured_on", "text", lambda c: _measured_on(c, context), None),
    ]
    for field, (required, allow_inf) in _NUMBERS.items():
        check = functools.partial(_number, field=field, required=required, allow_inf=allow_inf)
        checks.append((field, "number", check, None))
    checks.append(("direction", "depends", functools.partial(_direction, context=context), "bench"))
    checks.append(("unit", "depends", functools.partial(_unit, context=context), "device"))
    return checks


def _field_values(v: _Validator, context: TableContext | None, lab_column: LabColumn) -> dict:
    """Every column converted; failing cells are ``None`` and their rows marked bad.

    A table with a quantity kind other than the magnitude reads its value, U and unit
    once per distinct (kind, cell) through the kind's checks (a phase may be negative, its
    U is never a percentage); a table of magnitudes keeps the fast number path."""
    out: dict[str, list[object]] = {}
    by_kind: dict[str, Compute] = {}
    for field, kind, check, dependency in field_checks(context, lab_column):
        if field in by_kind:
            depends = out["quantity"]
            if field == "unit":
                depends = list(zip(out["device"], out["quantity"], strict=True))
            out[field] = v.column(field, by_kind[field], depends)
        elif kind == "number":
            out[field] = v.number_column(field, check)
        else:
            out[field] = v.column(field, check, out[dependency] if dependency else None)
        if field == "quantity" and any(q not in (None, quantities.DEFAULT) for q in out[field]):
            by_kind = _kind_checks(context)
    return out


def _kind_checks(context: TableContext | None) -> dict[str, Compute]:
    """The checks that depend on a row's quantity kind (and the unit on its device too)."""
    return {
        "sensitivity": _sensitivity,
        "expanded_uncertainty": _uncertainty,
        "unit": lambda c, dq: _unit(c, dq[0], context, dq[1]),
    }


def _number(
    check: _RowCheck, field: str, required: bool = False, allow_inf: bool = False
) -> object:
    return check.number(field, required=required, allow_inf=allow_inf)


def validate_columns(
    columns: Mapping[str, Sequence[object]],
    numbers: Sequence[int],
    *,
    decimal_comma: bool = False,
    lab_column: LabColumn = "optional",
    context: TableContext | None = None,
    errors: Iterable[RowError] = (),
    dropped: int = 0,
) -> list[ResultRow]:
    """Validate a table given as columns (field -> cells, aligned with ``numbers``).

    Same contract as :func:`labs.importers.validate.validate_records`; ``dropped``
    counts problems found before (with ``errors``) but not listed. At most
    MAX_LISTED_ERRORS problems are listed, the first in row order.
    """
    found = list(errors)
    v = _Validator(columns, numbers, decimal_comma, cap=MAX_LISTED_ERRORS)
    rows = _assemble(v, _field_values(v, context, lab_column), context)
    found.extend(v.errors)
    found.extend(find_duplicates(rows))
    if not rows and not found and not dropped:
        found.append(RowError(None, None, "the table has no data rows"))
    if found or dropped:
        raise ImportErrors(sorted(found, key=_error_order), total=len(found) + v.dropped + dropped)
    return rows


def check_columns(
    columns: Mapping[str, Sequence[object]],
    numbers: Sequence[int],
    *,
    decimal_comma: bool = False,
    lab_column: LabColumn = "optional",
    context: TableContext | None = None,
) -> tuple[list[ResultRow], list[RowError]]:
    """The good rows and the problems of the others, unsorted, without raising.

    :func:`validate_columns` without its whole-table steps (the duplicate check, the
    empty-table error): a streamed import checks a chunk at a time with it.
    """
    v = _Validator(columns, numbers, decimal_comma)
    values = _field_values(v, context, lab_column)
    rows = _assemble(v, values, context)
    return rows, v.errors


def _assemble(
    v: _Validator, values: Mapping[str, list[object]], context: TableContext | None
) -> list[ResultRow]:
    """A :class:`ResultRow` per good row, with the measurement-point check."""
    # measured_on first: it goes into the row as it was checked
    fields = ("measured_on", "device", "axis", "frequency_hz", "bench", "direction", "quantity",
              "amplitude_m_s2", "sensitivity", "unit", "expanded_uncertainty", "coverage_factor",
              "dof", "lab", "note", "repeat_sd", "n_repeats")  # fmt: skip
    table = zip(v.numbers, v.bad, *(values[f] for f in fields), strict=True)
    check_points = context is not None and context.points is not None
    rows = []
    v.new_pass()
    for number, bad, on, *cells in table:
        if bad:
            continue
        device, axis, freq, bench, direction, q, amp, sens, unit, u, k, dof, lab, note, sd, n = (
            cells
        )
        expanded, entered = u, ""
        if type(u) is tuple:  # from the precise check: (value, given in %, text if in %)
            expanded = relative_to_absolute(sens, u[0]) if u[1] else u[0]
            entered = u[2]
        given = sens
        sens, expanded, unit, original_unit = convert_units(q, sens, expanded, unit)
        k = DEFAULT_COVERAGE_FACTOR if k is None else k
        paired: list[tuple[str, str]] = []
        if sd is not None or n is not None:
            sd, paired = repeat_problems(sd, n, sens, given, original_unit)
        signed = q != quantities.DEFAULT and not quantities.kind(q).positive
        if paired or not (
            (signed or _MIN <= sens <= _MAX)
            and _MIN <= expanded <= _MAX
            and _MIN <= expanded / k <= _MAX
        ):
            v.note(number, magnitude_problems(sens, expanded, k, original_unit, q) + paired)
            continue
        row = _result_row(number, device, axis, freq, bench, direction, q, amp, sens, unit,
                          expanded, k, dof, lab, note, original_unit, sd, n, entered,
                          on)  # fmt: skip
        if check_points and not _one_point_in_scope(context, row):  # type: ignore[arg-type]
            check = _RowCheck({}, number, v.decimal_comma)
            _check_point(check, row, context)
            v.note(number, [(e.field, e.message) for e in check.errors])
            continue
        rows.append(row)
    return rows


def _one_point_in_scope(context: TableContext, row: ResultRow) -> bool:
    found = context.matching_points(row)
    return len(found) == 1 and context.in_scope(found[0])


def _result_row(*values: object) -> ResultRow:
    """``ResultRow`` from its field values in declaration order, without ``__init__``."""
    row = _NEW(ResultRow)
    for setter, value in zip(_ROW_SETTERS, values, strict=True):
        setter(row, value)
    return row


# --- tables and records to columns ----------------------------------------------------------


def sheet_columns(
    names: Sequence[str], rows: Sequence[tuple[int, list[object]]]
) -> tuple[dict[str, Sequence[object]], list[int], list[RowError]]:
    """Transpose a sheet's rows under its header; a value under no header is an error."""
    numbers = [number for number, _ in rows]
    cells = [row for _, row in rows]
    width = len(names)
    errors: list[RowError] = []
    if "" in names or any(len(row) > width for row in cells):
        for number, row in rows:
            errors.extend(cells_to_record(names, row, number)[1])
    if all(len(row) == width for row in cells):
        transposed: list[Sequence[object]] = list(zip(*cells, strict=True)) if cells else []
    else:
        transposed = [[row[j] if j < len(row) else None for row in cells] for j in range(width)]
    columns = {name: transposed[j] if cells else () for j, name in enumerate(names) if name}
    return columns, numbers, errors


def record_columns(
    records: Iterable[tuple[int, Mapping[str, object]]],
) -> tuple[dict[str, Sequence[object]], list[int]]:
    """Records (row number, column name -> value) as columns; absent keys are blank."""
    pairs = list(records)
    numbers = [number for number, _ in pairs]
    present = {name for _, record in pairs for name in record}
    columns: dict[str, Sequence[object]] = {
        name: [record.get(name) for _, record in pairs] for name in COLUMNS if name in present
    }
    return columns, numbers


def validate_records_fast(
    records: Iterable[tuple[int, Mapping[str, object]]], **options: object
) -> list[ResultRow]:
    """:func:`~labs.importers.validate.validate_records`, column-wise (same arguments)."""
    columns, numbers = record_columns(records)
    return validate_columns(columns, numbers, **options)  # type: ignore[arg-type]
