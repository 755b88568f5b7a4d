"""The measurement point's key and its label, written once (docs/domain.md §2).

A measurement point — a measurand of the round — is device × axis × frequency × bench ×
direction × quantity kind (``common.quantities``), with an optional excitation amplitude.
Everything that names a point (the importers' row checks, the analysis groups, the records
of downloads, messages, form choices, report headings) takes its fields and its words from
here.

Pure: the standard library only, so that the two pure cores (``analysis.core`` and
``labs.importers``) may use it as well as the apps (an import contract checks it).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any, Final, NamedTuple

from common.quantities import DEFAULT as DEFAULT_QUANTITY
from common.quantities import label_shown, shown_group

#: The six fields that name a measurand, in the order of keys, records and downloads.
POINT_FIELDS: Final = ("device", "axis", "frequency_hz", "bench", "direction", "quantity")
#: The same fields as ORM lookups from a result's or a point's measurement point.
POINT_LOOKUPS: Final = ("device__name", "axis", "frequency_hz", "bench", "direction", "quantity")


class PointKey(NamedTuple):
    """One measurement point by value: the device's name and the point's levels.

    ``quantity`` comes last (after the amplitude) so that a key built positionally from
    the five levels and an amplitude, as every key was before kinds existed, still means
    a magnitude; build one from :data:`POINT_FIELDS` values with keywords or
    :meth:`from_fields`."""

    device: str
    axis: str
    frequency_hz: float
    bench: str
    direction: str
    amplitude_m_s2: float | None = None
    quantity: str = DEFAULT_QUANTITY

    @classmethod
    def from_fields(cls, fields: Sequence[Any], amplitude_m_s2: float | None = None) -> PointKey:
        """A key from the six :data:`POINT_FIELDS` values in their order, and the amplitude."""
        device, axis, frequency_hz, bench, direction, quantity = fields
        return cls(device, axis, frequency_hz, bench, direction, amplitude_m_s2,
                   quantity or DEFAULT_QUANTITY)  # fmt: skip

    @property
    def measurand(self) -> tuple[str, str, float, str, str, str]:
        """The six :data:`POINT_FIELDS` (the analysis groups by these)."""
        return (self.device, self.axis, self.frequency_hz, self.bench, self.direction,
                self.quantity)  # fmt: skip

    def label(self, sep: str = ", ") -> str:
        return point_label(self, sep=sep)


def format_number(value: float) -> str:
    """Short exact display of a number in messages and labels: ``-3`` rather than ``-3.0``,
    and every digit Python needs to give the number back (``1234.5678``, never rounded)."""
    if math.isfinite(value) and value == int(value) and abs(value) < 1e15:
        return str(int(value))
    return repr(value)


def point_quantity(point: Sequence[Any]) -> str:
    """The quantity kind of a :class:`PointKey` or of a :data:`POINT_FIELDS` tuple (its
    sixth value; a five-value tuple is a magnitude)."""
    if isinstance(point, PointKey):
        return point.quantity
    return str(point[5] or DEFAULT_QUANTITY) if len(point) > 5 else DEFAULT_QUANTITY


def point_label(point: Sequence[Any], *, sep: str = ", ", device: bool = True) -> str:
    """``MEMS 1, X, 5 Hz, linear vertical`` from a point's fields (:data:`POINT_FIELDS`
    order, or a :class:`PointKey`), with the quantity kind's label after them where it is
    not the magnitude (``MEMS 1, X, 80 Hz, curvilinear tangential, sensitivity phase``;
    ``common.quantities.label_shown``); ``sep`` joins the parts (``" · "`` in form choices,
    a space in run messages), ``device=False`` leaves the device out (report sections that
    are already headed by it)."""
    name, axis, frequency_hz, bench, direction = point[:5]
    parts = [str(axis), f"{format_number(float(frequency_hz))} Hz", f"{bench} {direction}"]
    kind = label_shown(point_quantity(point))
    if kind:
        parts.append(kind)
    return sep.join([str(name), *parts] if device else parts)


def group_text(group: Mapping[str, object], sep: str = " ") -> str:
    """A compatibility matrix's group in words (``device IMU 1, axis Z, sensitivity phase``;
    ``sep`` between a key and its value, ``=`` on the pages): the keys in
    :data:`POINT_FIELDS` order (a group read back from the database has them in another),
    the kind by its label and only where it is not the magnitude
    (``common.quantities.shown_group``); ``""`` for the whole round."""
    shown = shown_group(group)
    order = {k: i for i, k in enumerate(POINT_FIELDS)}
    parts = []
    for k in sorted(shown, key=lambda k: order.get(k, len(order))):
        v = shown[k]
        if k == "quantity":
            parts.append(label_shown(str(v)))
        else:
            parts.append(f"{k}{sep}{v:g}" if isinstance(v, float) else f"{k}{sep}{v}")
    return ", ".join(parts)
