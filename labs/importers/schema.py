"""The results table's columns, its row type and the comparison context (docs/interfaces.md §1)."""

from __future__ import annotations

import datetime as dt
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from functools import cached_property
from typing import Literal

from common.points import PointKey as PointKey  # re-exported: the importers' key type
from common.quantities import DEFAULT as DEFAULT_QUANTITY

from .matching import FrequencyIndex, close
from .values import CANONICAL_UNIT

LabColumn = Literal["forbidden", "required", "optional"]

#: Every column of the results table, in the order downloads use.
COLUMNS = (
    "lab",
    "device",
    "axis",
    "frequency_hz",
    "bench",
    "direction",
    "quantity",
    "amplitude_m_s2",
    "sensitivity",
    "unit",
    "expanded_uncertainty",
    "coverage_factor",
    "dof",
    "repeat_sd",
    "n_repeats",
    "measured_on",
    "note",
)
REQUIRED_COLUMNS = (
    "device",
    "axis",
    "frequency_hz",
    "bench",
    "sensitivity",
    "expanded_uncertainty",
)
AXES = ("X", "Y", "Z")
BENCHES = ("linear", "curvilinear")
DIRECTIONS = ("vertical", "tangential", "radial")
DIRECTIONS_BY_BENCH: Mapping[str, tuple[str, ...]] = {
    "linear": ("vertical",),
    "curvilinear": ("tangential", "radial"),
}
NOTE_MAX_CHARS = 500
#: The longest relative U kept as written (``1.2%``, docs/domain.md §3.1).
ENTERED_MAX_CHARS = 40
#: The most repeats ``n_repeats`` may count (a whole number, stored as a 32-bit integer).
MAX_REPEATS = 1_000_000_000
DEFAULT_COVERAGE_FACTOR = 2.0


@dataclass(frozen=True, kw_only=True, slots=True)
class ResultRow:
    """One validated result; ``sensitivity``, ``expanded_uncertainty`` and ``repeat_sd``
    are in ``unit``.  ``quantity`` is the point's kind (``common.quantities``): for a
    phase, ``sensitivity`` is the phase in degrees, wrapped into (−180°, 180°].

    ``original_unit`` is the unit the lab wrote when it was converted (``mg/LSB``).
    ``repeat_sd`` and ``n_repeats`` (both or neither) are the within-laboratory standard
    deviation of the repeats behind ``sensitivity`` (their mean) and their number.
    ``expanded_uncertainty_entered`` is U as the lab wrote it when it gave it in per cent
    (``1.2%``), blank when it gave the absolute number (docs/domain.md §3.1).
    ``measured_on`` is the date the lab states it measured the result, None when it does
    not say (docs/interfaces.md §1; a kit's drift is taken at it, docs/domain.md §13).
    """

    row: int
    device: str
    axis: str
    frequency_hz: float
    bench: str
    direction: str = "vertical"
    quantity: str = DEFAULT_QUANTITY
    amplitude_m_s2: float | None = None
    sensitivity: float
    unit: str = CANONICAL_UNIT
    expanded_uncertainty: float
    coverage_factor: float = DEFAULT_COVERAGE_FACTOR
    dof: float | None = None
    lab: str | None = None
    note: str = ""
    original_unit: str | None = None
    repeat_sd: float | None = None
    n_repeats: int | None = None
    expanded_uncertainty_entered: str = ""
    measured_on: dt.date | None = None

    @property
    def standard_uncertainty(self) -> float:
        """u = U / k (docs/domain.md §3)."""
        return self.expanded_uncertainty / self.coverage_factor

    @property
    def relative_expanded_uncertainty(self) -> float:
        return self.expanded_uncertainty / self.sensitivity

    @property
    def point(self) -> PointKey:
        return PointKey(
            self.device,
            self.axis,
            self.frequency_hz,
            self.bench,
            self.direction,
            self.amplitude_m_s2,
            self.quantity,
        )

    def as_record(self) -> dict[str, object]:
        """The row as table columns (``original_unit`` and ``row`` left out)."""
        return {column: getattr(self, column) for column in COLUMNS}


def _norm_device(name: str) -> str:
    return " ".join(name.split()).casefold()


@dataclass(frozen=True, kw_only=True)
class TableContext:
    """What one comparison allows; every field left as ``None`` allows anything.

    ``device_units`` maps each device to its unit; device names match
    case-insensitively with whitespace collapsed, and rows take the context's
    spelling. Frequencies match within ``frequency_rel_tol`` and rows take the
    context's value. ``directions`` maps each bench to its directions; a bench
    missing from it allows every direction. ``points``, when given, is the
    exact list of measurement points; build it with :meth:`from_points`.

    ``scope``, when given, is the subset of ``points`` one participant measures
    (docs/domain.md §10), described for people by ``scope_text``: a row on a point
    outside it is refused, and a complete table needs only its points. ``None``
    means every point (build it with :meth:`with_scope`).

    ``measured_from`` and ``measured_until``, when given, bound a stated ``measured_on``
    (the comparison's first day, the latest date anywhere on Earth): build them with
    :meth:`with_dates`.
    """

    device_units: Mapping[str, str] | None = None
    axes: tuple[str, ...] = AXES
    frequencies_hz: tuple[float, ...] | None = None
    benches: tuple[str, ...] = BENCHES
    directions: Mapping[str, tuple[str, ...]] = field(
        default_factory=lambda: dict(DIRECTIONS_BY_BENCH)
    )
    points: tuple[PointKey, ...] | None = None
    default_unit: str = CANONICAL_UNIT
    frequency_rel_tol: float = 1e-9
    scope: frozenset[PointKey] | None = None
    scope_text: str = ""
    measured_from: dt.date | None = None
    measured_until: dt.date | None = None

    def with_dates(self, first: dt.date | None, last: dt.date | None) -> TableContext:
        """This context with a stated ``measured_on`` allowed from ``first`` to ``last``."""
        return replace(self, measured_from=first, measured_until=last)

    def with_scope(self, points: Iterable[PointKey] | None, text: str = "") -> TableContext:
        """This context limited to ``points`` (``None``: every point), described by ``text``."""
        scope = None if points is None else frozenset(points)
        return replace(self, scope=scope, scope_text=text)

    def in_scope(self, point: PointKey) -> bool:
        """Whether ``point`` (one of ``points``) is in the scope; always without one."""
        return self.scope is None or point in self.scope

    @classmethod
    def from_points(
        cls,
        points: Iterable[PointKey | Sequence[object]],
        *,
        device_units: Mapping[str, str] | None = None,
        default_unit: str = CANONICAL_UNIT,
        frequency_rel_tol: float = 1e-9,
    ) -> TableContext:
        """A context allowing exactly ``points`` (and the values they use)."""
        keys = tuple(PointKey(*p) for p in points)
        units = dict(device_units or {})
        devices = {p.device: units.get(p.device, default_unit) for p in keys}
        directions: dict[str, tuple[str, ...]] = {}
        for p in keys:
            if p.direction not in directions.setdefault(p.bench, ()):
                directions[p.bench] += (p.direction,)
        return cls(
            device_units=devices,
            axes=tuple(dict.fromkeys(p.axis for p in keys)),
            frequencies_hz=tuple(dict.fromkeys(p.frequency_hz for p in keys)),
            benches=tuple(directions),
            directions=directions,
            points=keys,
            default_unit=default_unit,
            frequency_rel_tol=frequency_rel_tol,
        )

    def unit_for_device(self, device: str) -> str:
        units = self.device_units or {}
        return units.get(self.canonical_device(device) or device, self.default_unit)

    def has_unit_for(self, device: str) -> bool:
        return self.device_units is not None and self.canonical_device(device) is not None

    @cached_property
    def _devices(self) -> dict[str, str]:
        return {_norm_device(name): name for name in self.device_units or {}}

    def canonical_device(self, device: str) -> str | None:
        """The context's spelling of ``device``; ``None`` if unknown (any device without a list)."""
        if self.device_units is None:
            return device
        return self._devices.get(_norm_device(device))

    @cached_property
    def _frequency_index(self) -> FrequencyIndex[float]:
        allowed = self.frequencies_hz or ()
        return FrequencyIndex(((f, f) for f in allowed), self.frequency_rel_tol)

    def canonical_frequency(self, frequency_hz: float) -> float | None:
        """The first of ``frequencies_hz`` within the tolerance of ``frequency_hz``."""
        if self.frequencies_hz is None:
            return frequency_hz
        found = self._frequency_index.find(frequency_hz)
        return found[0] if found else None

    def directions_for(self, bench: str) -> tuple[str, ...]:
        return tuple(self.directions.get(bench, DIRECTIONS))

    @cached_property
    def _point_index(self) -> dict[tuple[str, str, str, str, str], FrequencyIndex[PointKey]]:
        groups: dict[tuple[str, str, str, str, str], list[tuple[float, PointKey]]] = {}
        for p in self.points or ():
            groups.setdefault((p.device, p.axis, p.bench, p.direction, p.quantity), []).append(
                (p.frequency_hz, p)
            )
        tol = self.frequency_rel_tol
        return {key: FrequencyIndex(items, tol) for key, items in groups.items()}

    def matching_points(self, row: ResultRow | PointKey) -> list[PointKey]:
        """The context's points a row fits; an unset amplitude on either side matches any."""
        key = (row.device, row.axis, row.bench, row.direction, row.quantity)
        index = self._point_index.get(key)
        if index is None:
            return []
        b, tol = row.amplitude_m_s2, self.frequency_rel_tol
        return [
            p
            for p in index.find(row.frequency_hz)
            if p.amplitude_m_s2 is None or b is None or close(p.amplitude_m_s2, b, tol)
        ]

    def expected_points(self) -> tuple[PointKey, ...]:
        """``points`` (those of the scope, when there is one), or else every device × axis ×
        frequency × (bench, direction)."""
        if self.points is not None:
            if self.scope is not None:
                return tuple(p for p in self.points if p in self.scope)
            return self.points
        if self.device_units is None or self.frequencies_hz is None:
            raise ValueError("the context lists neither its points nor its devices and frequencies")
        return tuple(
            PointKey(device, axis, frequency, bench, direction)
            for device in self.device_units
            for axis in self.axes
            for frequency in self.frequencies_hz
            for bench in self.benches
            for direction in self.directions_for(bench)
        )


def missing_points(rows: Iterable[ResultRow], context: TableContext) -> list[PointKey]:
    """The context's measurement points no row covers, in the context's order; with a
    scope, only the scope's points.

    For a coordinator's table with several labs, call it with one lab's rows.
    """
    expected = context.expected_points()
    # Matching reads only the points and the tolerance: a context with points is its own probe.
    probe = context
    if context.points is None:
        probe = TableContext.from_points(expected, frequency_rel_tol=context.frequency_rel_tol)
    covered: set[PointKey] = set()
    for row in rows:
        covered.update(probe.matching_points(row))
    return [p for p in expected if p not in covered]
