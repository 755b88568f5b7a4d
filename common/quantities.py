"""The quantity kinds a measurement point can have, as one table (docs/domain.md §2, §12).

A measurand is device × axis × frequency × bench × direction *and a quantity kind*: the
magnitude of an accelerometer's sensitivity (every round before kinds existed), the phase
of that sensitivity (degrees, on the circle), or a gyroscope's angular-rate sensitivity.
Every layer — the importers' checks, the model's choices, the analysis' statistics, the
labels and the numbers on the pages — asks this table instead of naming a kind: adding a
kind is one more :class:`QuantityKind` in :data:`KINDS`.

Pure: the standard library only, so that the two pure cores (``analysis.core`` and
``labs.importers``) may use it as well as the apps (an import contract checks it).
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Final

MAGNITUDE: Final = "magnitude"
PHASE: Final = "phase"
ANGULAR_RATE: Final = "angular_rate"
#: The kind of a table without the ``quantity`` column, or of an empty cell
#: (docs/interfaces.md §1): every file written before kinds existed keeps its meaning.
DEFAULT: Final = MAGNITUDE


@dataclass(frozen=True)
class QuantityKind:
    """What one kind of measurand allows and how its statistics run.

    ``positive``: a value must be > 0 (a magnitude); otherwise any finite number.
    ``circular``: values are angles in degrees on the circle (docs/domain.md §12): stored
    wrapped into (−180°, 180°], consensus on values unwrapped about the circular mean,
    differences wrapped.  ``relative_u``: U may be given as a percentage of the value.
    ``fixed_unit``: the one unit every value of this kind is in (``None``: the device's
    unit, checked by the importers as before kinds existed).  ``units``: the spellings a
    results table may write for a kind with its own units, each with the factor that
    takes a value to ``default_unit`` (a blank unit is ``default_unit``).
    """

    name: str
    label: str
    default_unit: str
    positive: bool = True
    circular: bool = False
    relative_u: bool = True
    fixed_unit: str | None = None
    units: tuple[tuple[str, float], ...] = ()


_DEG = re.compile(r"\bdeg\b")  # the degree in a unit as written: deg, D/(deg/s)
_POWER = re.compile(r"\^(-?\d+)")  # a power as typed: m/s^2
_SUPERSCRIPT = str.maketrans("0123456789-", "⁰¹²³⁴⁵⁶⁷⁸⁹⁻")
_PER_RAD_S = math.pi / 180.0  # digits per rad/s × π/180 = digits per °/s
_DEGREES = (("deg", 1.0), ("°", 1.0), ("degree", 1.0), ("degrees", 1.0))
_RATE_UNITS = tuple(
    (f"{digits}/({per}/s)", factor)
    for per, factor in (("deg", 1.0), ("°", 1.0), ("rad", _PER_RAD_S))
    for digits in ("D", "LSB", "digits")
)

KINDS: Final[tuple[QuantityKind, ...]] = (
    QuantityKind(MAGNITUDE, "sensitivity magnitude", "D/(m/s^2)"),
    QuantityKind(
        PHASE,
        "sensitivity phase",
        "deg",
        positive=False,
        circular=True,
        relative_u=False,
        fixed_unit="deg",
        units=_DEGREES,
    ),
    QuantityKind(ANGULAR_RATE, "angular-rate sensitivity", "D/(deg/s)", units=_RATE_UNITS),
)
BY_NAME: Final = {k.name: k for k in KINDS}
NAMES: Final = tuple(BY_NAME)
CIRCULAR: Final = frozenset(k.name for k in KINDS if k.circular)


def kind(name: str | None) -> QuantityKind:
    """The kind named ``name`` (blank or ``None``: :data:`DEFAULT`); KeyError otherwise."""
    return BY_NAME[name or DEFAULT]


def parse(text: object) -> str:
    """A cell's kind: blank means :data:`DEFAULT`, any case and surrounding spaces accepted;
    ValueError naming the allowed kinds otherwise (``must be one of magnitude, phase,
    angular_rate, got 'foo'``)."""
    given = "" if text is None else str(text).strip()
    if not given:
        return DEFAULT
    found = BY_NAME.get(given.casefold())
    if found is None:
        raise ValueError(f"must be one of {', '.join(NAMES)}, got {given!r}")
    return found.name


def _unit_key(text: str) -> str:
    return "".join(text.split()).casefold().replace("²", "^2")


def own_unit(name: str | None, text: str) -> tuple[str, float] | None:
    """For a kind with its own units: (its default unit, the factor to it) of the unit
    ``text`` a table wrote (blank: the default unit, factor 1); ValueError naming the
    allowed units for another.  ``None`` for a kind measured in its device's unit."""
    k = kind(name)
    if not k.units:
        return None
    if not text.strip():
        return k.default_unit, 1.0
    found = {_unit_key(spelling): factor for spelling, factor in k.units}.get(_unit_key(text))
    if found is None:
        allowed = ", ".join(spelling for spelling, _ in k.units)
        raise ValueError(f"a {k.label} is in {allowed}; got {text.strip()!r}")
    return k.default_unit, found


def point_unit(name: str | None, device_unit: str) -> str:
    """The unit of a point's values: its device's for a kind without units of its own (a
    magnitude), else the kind's (``deg`` for a phase, ``D/(deg/s)`` for an angular rate)."""
    k = kind(name)
    return k.default_unit if k.units else device_unit


def unit_text(unit: str) -> str:
    """``unit`` as a person reads it on a page, in a report or on a chart's axis
    (docs/domain.md §3.1): degrees as ``°`` (``deg`` → ``°``, ``D/(deg/s)`` → ``D/(°/s)``),
    powers as superscripts (``D/(m/s^2)`` → ``D/(m/s²)``).  Stored values, downloads and
    the API keep the unit as written (``deg``, ``m/s^2``), and every spelling of
    :data:`KINDS` stays accepted on input."""
    return _POWER.sub(lambda m: m.group(1).translate(_SUPERSCRIPT), _DEG.sub("°", unit))


def with_unit(number: str, unit: str) -> str:
    """``number`` and its unit as written (docs/domain.md §3.1): no space before the degree
    sign (``-1.92°``), one before any other unit (``418.2 D/(m/s²)``); the number alone
    without a unit."""
    shown = unit_text(unit)
    if not shown:
        return number
    return f"{number}{shown}" if shown == "°" else f"{number} {shown}"


def per_day(unit: str) -> str:
    """The unit of a change per day of values in ``unit`` (a drift's slope, docs/domain.md
    §13), as stored units are written (``unit_text`` shows it): ``deg/d``, a compound unit
    bracketed so that one solidus is not followed by another (``(D/(m/s^2))/d``); ``""``
    for no unit."""
    if not unit:
        return ""
    return f"({unit})/d" if "/" in unit else f"{unit}/d"


def label_shown(name: str | None) -> str:
    """The kind as words where a point's label names it (``common.points.point_label``, the
    pages): the registry's label (``angular-rate sensitivity``), or ``""`` for the
    magnitude, so a round of magnitudes reads as before kinds existed."""
    return "" if (name or DEFAULT) == DEFAULT else kind(name).label


def with_kind(text: str, name: str | None) -> str:
    """``text`` followed by the kind's label where it is not the magnitude (``tangential,
    sensitivity phase``), as a point's label names it; ``text`` alone for a magnitude."""
    shown = label_shown(name)
    return f"{text}, {shown}" if shown else text


def shown_group(group: Mapping[str, object]) -> dict[str, object]:
    """A matrix's group keys as people read them: ``quantity`` only where it is not the
    magnitude, so a round of magnitudes reads as before kinds existed."""
    return {k: v for k, v in group.items() if not (k == "quantity" and v == DEFAULT)}


def wrap_degrees(angle: float) -> float:
    """``angle`` wrapped into (−180°, 180°] (docs/domain.md §12): ``wrap(-180) = 180``,
    ``wrap(190) = -170``.  The scalar twin of ``analysis.core.phase.wrap``."""
    r = math.fmod(angle, 360.0)  # exact, as is one turn more or less (see ``wrap``)
    if r > 180.0:
        r -= 360.0
    elif r <= -180.0:
        r += 360.0
    return r + 0.0  # −0 is 0


def stored_value(name: str | None, value: float) -> float:
    """A value as stored for its kind: a circular kind wrapped, any other unchanged."""
    return wrap_degrees(value) if kind(name).circular else value


def is_circular(name: str | None) -> bool:
    return kind(name).circular
