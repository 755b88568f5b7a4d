"""The measurement point's key and its label, written once (docs/domain.md §2).

A measurement point — a measurand of the round — is device × axis × frequency × bench ×
direction, with an optional excitation amplitude.  Everything that names a point (the
importers' row checks, the analysis groups, the records of downloads, messages, form
choices, report headings) takes its fields and its words from here.

Pure: the standard library only, so that the two pure cores (``analysis.core`` and
``labs.importers``) may use it as well as the apps (an import contract checks it).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any, Final, NamedTuple

#: The five fields that name a measurand, in the order of keys, records and downloads.
POINT_FIELDS: Final = ("device", "axis", "frequency_hz", "bench", "direction")
#: The same fields as ORM lookups from a result's or a point's measurement point.
POINT_LOOKUPS: Final = ("device__name", "axis", "frequency_hz", "bench", "direction")


class PointKey(NamedTuple):
    """One measurement point by value: the device's name and the point's levels."""

    device: str
    axis: str
    frequency_hz: float
    bench: str
    direction: str
    amplitude_m_s2: float | None = None

    @property
    def measurand(self) -> tuple[str, str, float, str, str]:
        """The five :data:`POINT_FIELDS` (the analysis groups by these)."""
        return (self.device, self.axis, self.frequency_hz, self.bench, self.direction)

    def label(self, sep: str = ", ") -> str:
        return point_label(self, sep=sep)


def format_number(value: float) -> str:
    """Short exact display of a number in messages and labels: ``-3`` rather than ``-3.0``,
    and every digit Python needs to give the number back (``1234.5678``, never rounded)."""
    if math.isfinite(value) and value == int(value) and abs(value) < 1e15:
        return str(int(value))
    return repr(value)


def point_label(point: Sequence[Any], *, sep: str = ", ", device: bool = True) -> str:
    """``MEMS 1, X, 5 Hz, linear vertical`` from a point's first five fields
    (:data:`POINT_FIELDS` order); ``sep`` joins the parts (``" · "`` in form choices, a
    space in run messages), ``device=False`` leaves the device out (report sections that
    are already headed by it)."""
    name, axis, frequency_hz, bench, direction = point[:5]
    parts = [str(axis), f"{format_number(float(frequency_hz))} Hz", f"{bench} {direction}"]
    return sep.join([str(name), *parts] if device else parts)
