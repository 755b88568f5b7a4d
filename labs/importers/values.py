"""Cell values to typed values: numbers, text, units, formula escaping.

Cells arrive as text (CSV, XLSX text cells, JSON strings) or as numbers (XLSX
numeric cells, JSON numbers). Units follow docs/domain.md §2.
"""

from __future__ import annotations

import datetime as dt
import functools
import math
import re
from collections.abc import Iterable

from common.points import format_number
from common.sizes import human_size as human_size  # re-exported for the importers' callers

#: A text cell starting with one of these (after spaces) is executed by some spreadsheets
#: (OWASP CSV injection), the full-width forms by East Asian editions of Excel.
FORMULA_TRIGGERS = ("=", "+", "-", "@", "\t", "\r", "\n", "\uff1d", "\uff0b", "\uff0d", "\uff20")

#: ASCII digits only: ``\d`` and ``float()`` would also take "٤٢٠" or "４２０" as 420.
NUMBER_RE = re.compile(r"[+-]?(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][+-]?\d+)?", re.ASCII)
#: The shape of a date as YYYY-MM-DD (whether that day exists is for the calendar to say).
_DATE_RE = re.compile(r"\d{4}-\d{2}-\d{2}", re.ASCII)
#: Characters no cell may hold: control characters other than tab, line feed and carriage
#: return (PostgreSQL cannot store NUL, XML none of them), and lone UTF-16 surrogates
#: (not encodable as UTF-8), which JSON can carry.
CONTROL_RE = re.compile("[\x00-\x08\x0b\x0c\x0e-\x1f\x7f-\x9f\ud800-\udfff]")

#: Every number of a result, and u = U/k, must lie within [MIN_MAGNITUDE, MAX_MAGNITUDE]
#: (README, "Results tables"): the statistics form at most fourth powers of u and squares of
#: ratios such as x/u over up to a million results, (1e30/1e-30)**4 = 1e240 with room to
#: spare for sums and a factor 1/dof, all well inside double precision (2.2e-308, 1.8e308).
MIN_MAGNITUDE = 1e-30
MAX_MAGNITUDE = 1e30
RANGE_TEXT = "between 1e-30 and 1e30"

_INFINITY = {"inf", "+inf", "infinity", "+infinity"}
_NON_FINITE = {"nan", "+nan", "-nan", "-inf", "-infinity", *_INFINITY}

#: Standard acceleration of gravity, m/s² (CGPM 1901), for mg/LSB conversion.
STANDARD_GRAVITY = 9.80665
CANONICAL_UNIT = "D/(m/s^2)"
MG_PER_LSB = "mg/LSB"
KNOWN_UNITS = (CANONICAL_UNIT, "mV/(m/s^2)", "pC/(m/s^2)", MG_PER_LSB)
_UNIT_SYNONYMS = {"lsb/(m/s^2)": CANONICAL_UNIT, "digits/(m/s^2)": CANONICAL_UNIT}


class ValueProblem(ValueError):
    """A cell value that does not fit; the message follows the column name."""


def _formula_like(text: str) -> bool:
    return text[:1] in FORMULA_TRIGGERS or text.lstrip(" ")[:1] in FORMULA_TRIGGERS


def _escaped_follower(text: str) -> bool:
    """What may follow the quote :func:`escape_text` puts in front."""
    return bool(text) and (_formula_like(text) or text[:1] == "'")


def escape_text(text: str) -> str:
    """Text safe in a spreadsheet cell (OWASP CSV injection).

    Control characters (:data:`CONTROL_RE`) are removed first, then formula-like
    text (a leading ``=``, ``+``, ``-``, ``@``, tab, CR, LF or a full-width form, also
    after spaces) is prefixed with a single quote. A leading quote that
    :func:`unescape_text` would strip is escaped too, so that
    ``unescape_text(escape_text(s)) == s`` for every string without control characters.
    """
    text = CONTROL_RE.sub("", text)
    if _formula_like(text) or (text[:1] == "'" and _escaped_follower(text[1:])):
        return "'" + text
    return text


def unescape_text(text: str) -> str:
    """Undo :func:`escape_text`: drop a quote put before formula-like text."""
    if text[:1] == "'" and _escaped_follower(text[1:]):
        return text[1:]
    return text


def control_problem(text: str) -> str | None:
    """Why ``text`` cannot be stored (a control character or a lone surrogate), or ``None``."""
    found = CONTROL_RE.search(text)
    if found is None:
        return None
    code = ord(found.group())
    return (
        f"contains the control character U+{code:04X} at position {found.start() + 1}; "
        "remove it (NUL and other control characters cannot be stored)"
    )


def in_range(value: float) -> bool:
    """Whether a number > 0 is within the range the statistics can carry."""
    return MIN_MAGNITUDE <= value <= MAX_MAGNITUDE


def magnitude_problem(value: float) -> str | None:
    """Why a finite number > 0 is outside the range the statistics can carry, or ``None``."""
    if in_range(value):
        return None
    # the shortest repr: 1e-320 as typed, not its 6 digits 9.99989e-321
    return f"must be {RANGE_TEXT} (the range the statistics can carry), got {float(value)!r}"


def is_blank(raw: object) -> bool:
    return raw is None or (isinstance(raw, str) and not raw.strip())


def display(raw: object) -> str:
    """How a cell value is quoted back to the user in a message."""
    if isinstance(raw, str):
        return raw.strip()
    if isinstance(raw, float | int) and not isinstance(raw, bool):
        return format_number(float(raw))
    return str(raw)


def cell_text(raw: object) -> str:
    """A cell as trimmed text; numeric cells (XLSX, JSON) in their short form."""
    if raw is None:
        return ""
    if isinstance(raw, bool):
        return str(raw).upper()
    if isinstance(raw, float | int):
        return format_number(float(raw))
    return unescape_text(str(raw).strip())


def parse_number(raw: object, *, decimal_comma: bool, allow_inf: bool = False) -> float:
    """A finite float from a numeric cell or from text.

    Text accepts a decimal point, or a decimal comma when ``decimal_comma``
    (semicolon-separated CSV); no thousands separators. ``nan`` and ``inf``
    are refused, except ``inf`` when ``allow_inf`` (degrees of freedom).
    """
    if isinstance(raw, bool):
        raise ValueProblem(f"must be a number, got {raw}")
    if isinstance(raw, int | float):
        try:
            value = float(raw)
        except OverflowError:
            raise ValueProblem(f"must be a finite number, got {raw}") from None
        return _finite(value, display(raw), allow_inf)
    if isinstance(raw, dt.date | dt.time | dt.datetime):
        raise ValueProblem(f"must be a number, got a date or time ({raw})")
    if not isinstance(raw, str):
        raise ValueProblem(f"must be a number, got {type(raw).__name__}")
    return _parse_number_text(unescape_text(raw.strip()), decimal_comma, allow_inf)


def _finite(value: float, shown: str, allow_inf: bool) -> float:
    if math.isnan(value) or (math.isinf(value) and not (allow_inf and value > 0)):
        raise ValueProblem(f"must be a finite number, got {shown}")
    return value


def _parse_number_text(text: str, decimal_comma: bool, allow_inf: bool) -> float:
    lowered = text.lower()
    if allow_inf and lowered in _INFINITY:
        return math.inf
    if lowered in _NON_FINITE:
        raise ValueProblem(f"must be a finite number, got {text!r}")
    if "," in text:
        if not decimal_comma:
            raise ValueProblem(
                f"must be a number with a decimal point, got {text!r} (a decimal comma "
                "is accepted only in semicolon-separated files)"
            )
        if text.count(",") > 1 or "." in text:
            raise ValueProblem(f"must be a number without thousands separators, got {text!r}")
        text_for_float = text.replace(",", ".")
    else:
        text_for_float = text
    if not NUMBER_RE.fullmatch(text_for_float):
        raise ValueProblem(f"must be a number, got {text!r}")
    return _finite(float(text_for_float), repr(text), allow_inf)


def parse_date(raw: object) -> dt.date:
    """A calendar date from a text cell (ISO 8601 as ``datetime.date.fromisoformat`` reads
    it: ``2025-03-14``, also ``20250314`` and ``2025-W11-5``, as the pilot's ``measured_on``
    of a kit, docs/domain.md §15) or from an XLSX date cell (a date at midnight)."""
    if isinstance(raw, dt.datetime):
        if raw.time() != dt.time(0) or raw.tzinfo is not None:
            shown = raw.isoformat(" ")
            raise ValueProblem(f"must be a date YYYY-MM-DD without a time, got {shown}")
        return raw.date()
    if isinstance(raw, dt.date):
        return raw
    text = unescape_text(raw.strip()) if isinstance(raw, str) else display(raw)
    try:
        if not isinstance(raw, str) or not text.isascii():
            raise ValueError(text)
        return dt.date.fromisoformat(text)
    except ValueError:
        nonexistent = " (no such day)" if _DATE_RE.fullmatch(text) else ""
        raise ValueProblem(f"must be a date YYYY-MM-DD, got {text!r}{nonexistent}") from None


def _unit_key(text: str) -> str:
    return text.strip().replace(" ", "").replace("²", "^2").replace("s2)", "s^2)").lower()


@functools.lru_cache(maxsize=64)
def _unit_table(extra_units: tuple[str, ...]) -> dict[str, str]:
    known = {_unit_key(unit): unit for unit in (*KNOWN_UNITS, *extra_units)}
    return {**known, **_UNIT_SYNONYMS}


def normalise_unit(text: str, extra_units: Iterable[str] = ()) -> str:
    """The canonical spelling of a sensitivity unit, or :class:`ValueProblem`.

    ``LSB/(m/s^2)`` is a synonym of ``D/(m/s^2)``; ``mg/LSB`` is returned as is
    and converted by :func:`mg_per_lsb_to_canonical`.
    """
    extra = tuple(extra_units)
    try:
        return _unit_table(extra)[_unit_key(text)]
    except KeyError:
        allowed = ", ".join(sorted({*KNOWN_UNITS, *extra, "LSB/(m/s^2)"}))
        raise ValueProblem(f"unknown unit {text.strip()!r}; allowed: {allowed}") from None


def mg_per_lsb_to_canonical(value: float) -> float:
    """Invert a datasheet sensitivity: S = 1 / (v · 1e-3 · g) in D/(m/s²) (docs/domain.md §2)."""
    return 1.0 / (value * 1e-3 * STANDARD_GRAVITY)
