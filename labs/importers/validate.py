"""The one validation of results rows, shared by CSV, XLSX and JSON input
(docs/interfaces.md §1)."""

from __future__ import annotations

import datetime as dt
import math
from collections.abc import Callable, Iterable, Mapping, Sequence
from typing import TypeVar

from common import quantities
from common.numbers import percent_fraction
from common.points import point_label

from .errors import ImportErrors, RowError
from .schema import (
    AXES,
    BENCHES,
    COLUMNS,
    DEFAULT_COVERAGE_FACTOR,
    DIRECTIONS,
    ENTERED_MAX_CHARS,
    MAX_REPEATS,
    NOTE_MAX_CHARS,
    REQUIRED_COLUMNS,
    LabColumn,
    ResultRow,
    TableContext,
)
from .values import (
    CANONICAL_UNIT,
    MG_PER_LSB,
    RANGE_TEXT,
    ValueProblem,
    cell_text,
    control_problem,
    display,
    format_number,
    in_range,
    is_blank,
    magnitude_problem,
    mg_per_lsb_to_canonical,
    normalise_unit,
    parse_date,
    parse_number,
)

_ALLOWED = ", ".join(COLUMNS)
T = TypeVar("T")


def normalise_name(name: object) -> str:
    return cell_text(name).lower()


def check_header(names: Sequence[object], *, lab_column: LabColumn, row: int) -> list[str]:
    """Column name per position ('' for a blank header cell), or every header problem."""
    columns = [normalise_name(name) for name in names]
    errors: list[RowError] = []
    unknown = [c for c in columns if c and c not in COLUMNS]
    if unknown:
        hint = " (tab-separated files are not supported)" if any("\t" in c for c in unknown) else ""
        errors.append(
            RowError(
                row,
                None,
                f"unknown {_columns(unknown)} {', '.join(map(repr, unknown))}"
                f"{hint}; the allowed columns are: {_ALLOWED}",
            )
        )
    for name in dict.fromkeys(c for c in columns if c):
        positions = [str(i + 1) for i, c in enumerate(columns) if c == name]
        if len(positions) > 1:
            errors.append(
                RowError(row, name, f"appears more than once (columns {', '.join(positions)})")
            )
    required = REQUIRED_COLUMNS + (("lab",) if lab_column == "required" else ())
    missing = [c for c in required if c not in columns]
    if missing:
        names = ", ".join(missing)
        errors.append(RowError(row, None, f"missing required {_columns(missing)}: {names}"))
    if errors:
        raise ImportErrors(errors)
    return columns


def cells_to_record(
    columns: Sequence[str], cells: Sequence[object], row: int
) -> tuple[dict[str, object], list[RowError]]:
    """Pair a row's cells with the header; a value under no header is an error."""
    record: dict[str, object] = {}
    errors = []
    for index, value in enumerate(cells):
        name = columns[index] if index < len(columns) else ""
        if name:
            record[name] = value
        elif not is_blank(value):
            errors.append(
                RowError(
                    row,
                    None,
                    f"value {display(value)!r} in column {index + 1}, which has no header",
                )
            )
    return record, errors


class Refused(Exception):
    """A cell that no check may read further (a control character); its error is recorded."""


class _RowCheck:
    """Reads one record's fields, collecting a :class:`RowError` per bad column."""

    def __init__(self, record: Mapping[str, object], row: int, decimal_comma: bool) -> None:
        self.record = record
        self.row = row
        self.decimal_comma = decimal_comma
        self.errors: list[RowError] = []

    def fail(self, field: str | None, message: str) -> None:
        self.errors.append(RowError(self.row, field, message))

    def raw(self, field: str) -> object:
        """The cell as given; a control character records its error and raises :class:`Refused`."""
        raw = self.record.get(field)
        if type(raw) is str and not raw.isprintable():
            problem = control_problem(raw)
            if problem is not None:
                self.fail(field, problem)
                raise Refused(field)
        return raw

    def text(self, field: str) -> str:
        return cell_text(self.raw(field))

    def number(
        self, field: str, *, required: bool = False, allow_inf: bool = False
    ) -> float | None:
        raw = self.raw(field)
        if is_blank(raw):
            if required:
                self.fail(field, "is required")
            return None
        try:
            value = parse_number(raw, decimal_comma=self.decimal_comma, allow_inf=allow_inf)
        except ValueProblem as problem:
            self.fail(field, str(problem))
            return None
        if not value > 0:
            self.fail(field, f"must be > 0, got {display(raw)}")
            return None
        if not (allow_inf and value == math.inf) and (issue := magnitude_problem(value)):
            self.fail(field, issue)
            return None
        return value

    def run(self, compute: Callable[..., T], *args: object) -> T | None:
        """``compute(self, *args)``; ``None`` when a cell was refused outright."""
        try:
            return compute(self, *args)
        except Refused:
            return None

    def choice(
        self, field: str, allowed: Sequence[str], universe: Sequence[str], what: str = ""
    ) -> str | None:
        """One of ``allowed`` (case-insensitive); ``universe`` tells a typo from a value
        that exists but is not part of this comparison (or bench)."""
        given = self.text(field)
        if not given:
            self.fail(field, "is required")
            return None
        found = _pick(given, allowed)
        if found is not None:
            return found
        if _pick(given, universe) is None:
            self.fail(field, f"must be one of {', '.join(universe)}, got {given!r}")
            return None
        where = what or "in this comparison"
        self.fail(field, f"{given!r} is not allowed {where}; expected one of: {', '.join(allowed)}")
        return None


def _pick(given: str, options: Iterable[str]) -> str | None:
    for option in options:
        if option.casefold() == given.casefold():
            return option
    return None


def _device(check: _RowCheck, context: TableContext | None) -> str | None:
    device = " ".join(check.text("device").split())
    if not device:
        check.fail("device", "is required")
        return None
    if context is None:
        return device
    known = context.canonical_device(device)
    if known is None:
        expected = ", ".join(context.device_units or ())
        check.fail(
            "device", f"unknown device {device!r} for this comparison; expected one of: {expected}"
        )
    return known


def _frequency(check: _RowCheck, context: TableContext | None) -> float | None:
    frequency = check.number("frequency_hz", required=True)
    if frequency is None or context is None:
        return frequency
    known = context.canonical_frequency(frequency)
    if known is None:
        expected = ", ".join(format_number(f) for f in context.frequencies_hz or ())
        check.fail(
            "frequency_hz",
            f"{format_number(frequency)} Hz is not a frequency of this "
            f"comparison; expected one of: {expected}",
        )
    return known


def _direction(check: _RowCheck, bench: str | None, context: TableContext | None) -> str | None:
    """Vertical goes with the linear bench, tangential and radial with the curvilinear one."""
    if bench is None:
        return None
    allowed = (context or TableContext()).directions_for(bench)
    if not check.text("direction"):
        if len(allowed) == 1:
            return allowed[0]
        check.fail("direction", f"is required on the {bench} bench: one of {', '.join(allowed)}")
        return None
    universe = tuple(dict.fromkeys((*DIRECTIONS, *allowed)))
    return check.choice("direction", allowed, universe, f"on the {bench} bench")


def _quantity(check: _RowCheck) -> str | None:
    """The point's quantity kind (``common.quantities``); a blank cell or no column is
    the magnitude (docs/interfaces.md §1)."""
    try:
        return quantities.parse(check.text("quantity"))
    except ValueError as problem:
        check.fail("quantity", str(problem))
        return None


def _sensitivity(check: _RowCheck, quantity: str | None) -> float | None:
    """The value: > 0 for a kind that must be positive; for another (a phase) any finite
    number in the safe range, stored as its kind stores it (wrapped, docs/domain.md §12)."""
    if quantity is None:
        return None
    if quantities.kind(quantity).positive:
        return check.number("sensitivity", required=True)
    raw = check.raw("sensitivity")
    if is_blank(raw):
        check.fail("sensitivity", "is required")
        return None
    try:
        value = parse_number(raw, decimal_comma=check.decimal_comma)
    except ValueProblem as problem:
        check.fail("sensitivity", str(problem))
        return None
    if value != 0 and not in_range(abs(value)):  # the signed value, as typed, in the message
        check.fail("sensitivity", f"must be 0 or of a size {RANGE_TEXT} (the range the "
                                  f"statistics can carry), got {display(raw)}")  # fmt: skip
        return None
    return quantities.stored_value(quantity, value)


def _uncertainty(
    check: _RowCheck, quantity: str | None = quantities.DEFAULT
) -> tuple[float, bool, str] | None:
    """Expanded uncertainty, whether it was given in % of the sensitivity, and then the text
    as written, kept with the result (docs/domain.md §3.1): its number as typed and one space
    before the per-cent sign, as SI writes it (``1.2%`` and ``1.2 %`` are ``1.2 %``).  A kind
    without a relative U (a phase: a per cent of an angle means nothing) refuses the %."""
    raw = check.raw("expanded_uncertainty")
    if isinstance(raw, str) and raw.strip().endswith("%"):
        shown = " ".join(raw.split())
        if quantity is None:
            return None
        if not quantities.kind(quantity).relative_u:
            unit = quantities.kind(quantity).default_unit
            check.fail(
                "expanded_uncertainty",
                f"a {quantity}'s U is given in {unit}, not as a percentage, got {shown!r}",
            )
            return None
        try:
            value = parse_number(shown[:-1], decimal_comma=check.decimal_comma)
        except ValueProblem:
            check.fail("expanded_uncertainty", f"must be a number or a percentage, got {shown!r}")
            return None
        if not value > 0:
            check.fail("expanded_uncertainty", f"must be > 0, got {shown}")
            return None
        entered = shown[:-1].strip() + " %"
        if len(entered) > ENTERED_MAX_CHARS:
            check.fail(
                "expanded_uncertainty",
                f"a percentage is kept as written: at most {ENTERED_MAX_CHARS} characters, got "
                f"{len(entered)}",
            )
            return None
        return value, True, entered
    absolute = check.number("expanded_uncertainty", required=True)
    return None if absolute is None else (absolute, False, "")


def relative_to_absolute(sensitivity: float, percent: float) -> float:
    """U of a relative U of ``percent`` % (docs/domain.md §3.1): sensitivity × (p/100), the
    fraction taken from the percentage's decimal text (1.2 % of s is exactly s × 0.012)."""
    return sensitivity * percent_fraction(percent)


def _unit(
    check: _RowCheck,
    device: str | None,
    context: TableContext | None,
    quantity: str | None = quantities.DEFAULT,
) -> str | None:
    """The device's unit for a magnitude; a kind with its own units (a phase in degrees,
    an angular rate per °/s or rad/s) takes one of them, as written (the assembly converts
    it with :func:`convert_units`)."""
    if quantity is None:
        return None
    if quantities.kind(quantity).units:
        text = check.text("unit")
        try:
            quantities.own_unit(quantity, text)
        except ValueError as problem:
            check.fail("unit", str(problem))
            return None
        return text.strip() or quantities.kind(quantity).default_unit
    given = check.text("unit")
    extra = tuple((context.device_units or {}).values()) if context else ()
    if not given:
        return context.unit_for_device(device or "") if context else CANONICAL_UNIT
    try:
        unit = normalise_unit(given, extra)
    except ValueProblem as problem:
        check.fail("unit", str(problem))
        return None
    resulting = CANONICAL_UNIT if unit == MG_PER_LSB else unit
    if context and device and context.has_unit_for(device):
        expected = context.unit_for_device(device)
        if resulting != expected:
            check.fail(
                "unit",
                f"{given!r} does not fit {device}, whose unit in this comparison is {expected}",
            )
    return unit


def convert_units(
    quantity: str, sensitivity: float, expanded: float, unit: str
) -> tuple[float, float, str, str | None]:
    """``(sensitivity, U, unit, original unit)`` in the unit the analysis uses: mg/LSB
    inverted (docs/domain.md §2), an angular rate per rad/s made per °/s; either keeps the
    relative uncertainty.  The original unit is ``None`` where nothing was converted."""
    own = quantities.own_unit(quantity, unit)
    if own is not None:
        canonical, factor = own
        if factor == 1.0:
            return sensitivity, expanded, canonical, None
        return sensitivity * factor, expanded * factor, canonical, unit
    if unit == MG_PER_LSB:
        # The relative uncertainty is kept through the inversion (docs/domain.md §2).
        converted = mg_per_lsb_to_canonical(sensitivity)
        return converted, converted * expanded / sensitivity, CANONICAL_UNIT, MG_PER_LSB
    return sensitivity, expanded, unit, None


def _lab(check: _RowCheck, lab_column: LabColumn) -> str | None:
    lab = check.text("lab")
    if lab and lab_column == "forbidden":
        check.fail(
            "lab",
            "is not allowed here: results are filed under your own laboratory; "
            "remove the lab column",
        )
    elif not lab and lab_column == "required":
        check.fail("lab", "is required")
    return lab or None


def _note(check: _RowCheck) -> str:
    note = check.text("note")
    if len(note) > NOTE_MAX_CHARS:
        check.fail("note", f"must be at most {NOTE_MAX_CHARS} characters, got {len(note)}")
    return note


def _measured_on(check: _RowCheck, context: TableContext | None = None) -> dt.date | None:
    """The date the lab states it measured the result, or None (a blank cell, no column):
    a calendar date, neither before the comparison's first day nor after today anywhere on
    Earth where the context bounds it (docs/interfaces.md §1)."""
    raw = check.raw("measured_on")
    if is_blank(raw):
        return None
    try:
        day = parse_date(raw)
    except ValueProblem as problem:
        check.fail("measured_on", str(problem))
        return None
    first = context.measured_from if context else None
    last = context.measured_until if context else None
    if last is not None and day > last:
        check.fail(
            "measured_on",
            f"{day} is in the future: a measurement date is at the latest {last} (today "
            "anywhere on Earth)",
        )
        return None
    if first is not None and day < first:
        check.fail("measured_on", f"{day} is before the comparison opened on {first}")
        return None
    return day


def _number(
    check: _RowCheck, field: str, required: bool = False, allow_inf: bool = False
) -> float | None:
    return check.number(field, required=required, allow_inf=allow_inf)


def _n_repeats(check: _RowCheck) -> int | None:
    """The number of repeats behind ``repeat_sd``: a whole number from 2 to MAX_REPEATS
    (read as the other numbers are: ASCII digits, finite, > 0)."""
    value = check.number("n_repeats")
    if value is None:
        return None
    if value != int(value) or not 2 <= value <= MAX_REPEATS:
        check.fail(
            "n_repeats",
            f"must be a whole number from 2 to {MAX_REPEATS:,} (the repeats behind "
            f"repeat_sd), got {display(check.raw('n_repeats'))}",
        )
        return None
    return int(value)


def repeat_problems(
    repeat_sd: float | None,
    n_repeats: int | None,
    sensitivity: float,
    given_sensitivity: float,
    original_unit: str | None,
) -> tuple[float | None, list[tuple[str, str]]]:
    """``repeat_sd`` in the row's unit and the problems of the pair: both or neither is
    given; converted from mg/LSB it keeps its relative size (as U does) and must still be
    within the range the statistics can carry."""
    if (repeat_sd is None) != (n_repeats is None):
        missing, given = (
            ("n_repeats", "repeat_sd") if n_repeats is None else ("repeat_sd", "n_repeats")
        )
        return None, [
            (
                missing,
                f"is required when {given} is given: the within-laboratory "
                "standard deviation and its number of repeats go together",
            )
        ]
    if repeat_sd is None:
        return None, []
    if original_unit:
        repeat_sd = sensitivity * repeat_sd / given_sensitivity
        if not in_range(repeat_sd):
            return None, [
                (
                    "repeat_sd",
                    f"is {repeat_sd:.6g} after the conversion from "
                    f"{original_unit}; it must be {RANGE_TEXT} (the range "
                    "the statistics can carry)",
                )
            ]
    return repeat_sd, []


def magnitude_problems(
    sensitivity: float,
    expanded: float,
    k: float,
    original_unit: str | None,
    quantity: str = quantities.DEFAULT,
) -> list[tuple[str, str]]:
    """The derived values the statistics use, checked like the cells (README, "Results
    tables"): U once made absolute, u = U/k, and both after a conversion from mg/LSB.  A
    kind that is not positive (a phase, wrapped) has no lower bound on its value."""
    problems = []
    after = f" after the conversion from {original_unit}" if original_unit else ""
    bounds = f"must be {RANGE_TEXT} (the range the statistics can carry)"
    signed = not quantities.kind(quantity).positive
    if not (signed or in_range(sensitivity)):
        problems.append(("sensitivity", f"is {sensitivity:.6g}{after}; it {bounds}"))
    if not in_range(expanded):
        problems.append(("expanded_uncertainty", f"U is {expanded:.6g}{after}; it {bounds}"))
    elif not in_range(expanded / k):
        problems.append(("expanded_uncertainty", f"gives u = U/k = {expanded / k:.6g}; u {bounds}"))
    return problems


def _check_point(check: _RowCheck, row: ResultRow, context: TableContext | None) -> None:
    if context is None or context.points is None:
        return
    found = context.matching_points(row)
    if not found:
        check.fail(
            None,
            f"no measurement point {row.device} / {row.axis} / "
            f"{format_number(row.frequency_hz)} Hz / {row.bench} / {row.direction}"
            f"{'' if row.quantity == quantities.DEFAULT else ' / ' + row.quantity}"
            " in this comparison",
        )
    elif len(found) == 1:
        if not context.in_scope(found[0]):
            check.fail(None, f"{point_label(found[0])} is not in your scope ({context.scope_text})")
    else:
        options = ", ".join(
            "none" if p.amplitude_m_s2 is None else format_number(p.amplitude_m_s2) for p in found
        )
        check.fail(
            "amplitude_m_s2", f"is needed to tell the measurement points apart: one of {options}"
        )


def validate_record(
    record: Mapping[str, object],
    row: int,
    *,
    decimal_comma: bool = False,
    lab_column: LabColumn = "optional",
    context: TableContext | None = None,
) -> ResultRow | list[RowError]:
    """One record (column name -> cell value) to a :class:`ResultRow` or its errors."""
    check = _RowCheck(record, row, decimal_comma)
    run = check.run
    device = run(_device, context)
    axis = run(_RowCheck.choice, "axis", context.axes if context else AXES, AXES)
    frequency = run(_frequency, context)
    benches = context.benches if context else BENCHES
    bench = run(_RowCheck.choice, "bench", benches, tuple(dict.fromkeys((*BENCHES, *benches))))
    direction = run(_direction, bench, context)
    quantity = run(_quantity)
    amplitude = run(_number, "amplitude_m_s2")
    sensitivity = run(_sensitivity, quantity)
    unit = run(_unit, device, context, quantity)
    uncertainty = run(_uncertainty, quantity)
    coverage = run(_number, "coverage_factor")
    dof = run(_number, "dof", False, True)
    repeat_sd = run(_number, "repeat_sd")
    n_repeats = run(_n_repeats)
    measured_on = run(_measured_on, context)
    lab = run(_lab, lab_column)
    note = run(_note)
    if check.errors:
        return check.errors
    assert device and axis and frequency and bench and direction and unit and quantity
    assert sensitivity is not None and uncertainty is not None and note is not None
    value, relative, entered = uncertainty
    expanded = relative_to_absolute(sensitivity, value) if relative else value
    given_sensitivity = sensitivity
    sensitivity, expanded, unit, original_unit = convert_units(quantity, sensitivity, expanded,
                                                               unit)  # fmt: skip
    k = DEFAULT_COVERAGE_FACTOR if coverage is None else coverage
    sd, paired = repeat_problems(repeat_sd, n_repeats, sensitivity, given_sensitivity,
                                 original_unit)  # fmt: skip
    problems = magnitude_problems(sensitivity, expanded, k, original_unit, quantity)
    for field, message in problems + paired:
        check.fail(field, message)
    if check.errors:
        return check.errors
    result = ResultRow(
        row=row, device=device, axis=axis, frequency_hz=frequency, bench=bench,
        direction=direction, quantity=quantity, amplitude_m_s2=amplitude,
        sensitivity=sensitivity, unit=unit,
        expanded_uncertainty=expanded,
        coverage_factor=k,
        dof=dof, lab=lab, note=note, original_unit=original_unit,
        repeat_sd=sd, n_repeats=n_repeats, expanded_uncertainty_entered=entered,
        measured_on=measured_on,
    )  # fmt: skip
    _check_point(check, result, context)
    return check.errors or result


def _duplicate_key(row: ResultRow) -> tuple[object, ...]:
    amplitude = None if row.amplitude_m_s2 is None else float(f"{row.amplitude_m_s2:.12g}")
    frequency = float(f"{row.frequency_hz:.12g}")
    return (row.lab, row.device, row.axis, frequency, row.bench, row.direction, row.quantity,
            amplitude)  # fmt: skip


def find_duplicates(rows: Iterable[ResultRow]) -> list[RowError]:
    """An error on every row that repeats the measurement point of an earlier row."""
    first: dict[tuple[object, ...], int] = {}
    errors = []
    for row in rows:
        earlier = first.setdefault(_duplicate_key(row), row.row)
        if earlier != row.row:
            errors.append(
                RowError(
                    row.row,
                    None,
                    f"duplicate of row {earlier}: same lab, device, "
                    "axis, frequency_hz, bench, direction and "
                    "amplitude_m_s2",
                )
            )
    return errors


def validate_records(
    records: Iterable[tuple[int, Mapping[str, object]]],
    *,
    decimal_comma: bool = False,
    lab_column: LabColumn = "optional",
    context: TableContext | None = None,
    errors: Iterable[RowError] = (),
) -> list[ResultRow]:
    """Validate every record and raise :class:`ImportErrors` listing all problems."""
    found = list(errors)
    rows: list[ResultRow] = []
    for row_number, record in records:
        result = validate_record(record, row_number, decimal_comma=decimal_comma,
                                 lab_column=lab_column, context=context)  # fmt: skip
        if isinstance(result, ResultRow):
            rows.append(result)
        else:
            found.extend(result)
    found.extend(find_duplicates(rows))
    if not rows and not found:
        found.append(RowError(None, None, "the table has no data rows"))
    if found:
        raise ImportErrors(sorted(found, key=_error_order))
    return rows


_COLUMN_ORDER = {name: index for index, name in enumerate(COLUMNS)}


def _error_order(error: RowError) -> tuple[int, int]:
    return (error.row or 0, _COLUMN_ORDER.get(error.field or "", len(COLUMNS)))


def _columns(names: Sequence[object]) -> str:
    return "column" if len(names) == 1 else "columns"
