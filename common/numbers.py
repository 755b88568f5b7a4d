"""Numbers as a metrologist writes them: one rounding rule, written once (docs/domain.md §3.1).

The uncertainty is given to two significant digits and the value is rounded to the same
decimal place (GUM, JCGM 100:2008, 7.2.6): ``value_with_uncertainty(419.4712, 0.1349)``
is ``("419.47", "0.13")``.  Scores are given to a fixed number of decimals, as the PDF
reports do (``fixed(en, 2)``).

Rounding is to the nearest digit, ties to even, of the stored binary number taken exactly:
the same as Python's ``format`` (which the PDF's ``num`` uses), so a page and a report
never round one number two ways; ``0.125`` (exact in binary) becomes ``0.12``, and ``2.675``
(stored as 2.67499999…) ``2.67``.  The text never uses an exponent (``419.47``, never
``4.1947e2``) and never shows binary noise (``3.4160160000000004`` is ``3.416016`` where it
is not rounded by an uncertainty).

Pure: the standard library only, so that the importers may use it (an import contract
checks it).
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from decimal import ROUND_HALF_EVEN, Decimal, getcontext
from typing import Final

#: Significant digits of an uncertainty (GUM 7.2.6: "at most two significant digits").
UNCERTAINTY_DIGITS: Final = 2
#: Significant digits of a number shown without an uncertainty: enough for every number
#: typed or measured, few enough to drop the last binary digit of arithmetic.
PLAIN_DIGITS: Final = 15
NOT_A_NUMBER: Final = "NaN"


def _special(x: float) -> str:
    """The text of a non-finite number."""
    if math.isnan(x):
        return NOT_A_NUMBER
    return "∞" if x > 0 else "−∞"


def _text(d: Decimal) -> str:
    """A decimal in positional notation (``12000``, ``0.00035``), no ``-0``."""
    if d.is_zero():
        d = abs(d)
    return format(d, "f")


def _quantize(x: float, exponent: int) -> Decimal:
    """``x`` rounded to a multiple of 10**exponent (to nearest, ties to even)."""
    return Decimal(x).quantize(Decimal(1).scaleb(exponent), rounding=ROUND_HALF_EVEN)


def uncertainty_exponent(u: float, digits: int = UNCERTAINTY_DIGITS) -> int:
    """The decimal place (a power of ten) of the last of ``digits`` significant digits of
    ``u`` once rounded: ``-2`` for 0.1349 (0.13), ``0`` for 9.96 (10, not 10.0)."""
    exact = Decimal(abs(u))
    exponent = exact.adjusted() - (digits - 1)
    if exact.quantize(Decimal(1).scaleb(exponent), rounding=ROUND_HALF_EVEN).adjusted() > (
        exact.adjusted()
    ):
        exponent += 1  # 9.96 -> 10: the carry made a new leading digit
    return exponent


def plain(x: float | None, digits: int = PLAIN_DIGITS) -> str:
    """``x`` to ``digits`` significant digits, trailing zeros dropped, without an exponent:
    ``3.416016`` for 3.4160160000000004, ``420`` for 420.0; ``""`` for None."""
    if x is None:
        return ""
    x = float(x)
    if not math.isfinite(x):
        return _special(x)
    if x == 0:
        return "0"
    exponent = Decimal(x).adjusted() - (digits - 1)
    d = _quantize(x, exponent)
    return _text(d.normalize())


def significant(x: float | None, digits: int, *, sign: bool = False) -> str:
    """``x`` to ``digits`` significant digits without an exponent, trailing zeros dropped
    (as ``format(x, ".4g")`` but ``0.00001234`` rather than ``1.234e-05``); ``sign`` puts
    ``+`` before a positive number (the PDF's ``+.4g`` of D)."""
    if x is None:
        return ""
    text = plain(x, digits)
    if sign and math.isfinite(float(x)) and float(x) > 0:
        return "+" + text
    return text


def fixed(x: float | None, places: int) -> str:
    """``x`` with ``places`` decimals, as ``format(x, f".{places}f")`` (the PDF's En, ζ, z:
    ``fixed(0.125, 2) == "0.12"``); ``""`` for None."""
    if x is None:
        return ""
    x = float(x)
    if not math.isfinite(x):
        return _special(x)
    return format(x, f".{places}f")


def uncertainty(u: float | None, digits: int = UNCERTAINTY_DIGITS) -> str:
    """An uncertainty to two significant digits (``0.13``, ``0.00035``, ``12000``); ``0``
    for zero; ``""`` for None.  A negative number is shown by its size."""
    if u is None:
        return ""
    u = abs(float(u))
    if not math.isfinite(u):
        return _special(u)
    if u == 0:
        return "0"
    return _text(_quantize(u, uncertainty_exponent(u, digits)))


def value_with_uncertainty(
    x: float | None, u: float | None, digits: int = UNCERTAINTY_DIGITS
) -> tuple[str, str]:
    """The value and its (expanded or standard) uncertainty as written (GUM 7.2.6): ``u`` to
    ``digits`` significant digits, ``x`` to the same decimal place.

    ``(419.4712, 0.1349)`` → ``("419.47", "0.13")``; ``(100.02147, 0.00035)`` →
    ``("100.02147", "0.00035")``.  Without a usable uncertainty (None, zero, NaN or
    infinite) the value is shown by :func:`plain` and the uncertainty as it is (``""``,
    ``"0"``, ``"NaN"``, ``"∞"``).
    """
    if x is None:
        return "", uncertainty(u, digits)
    x = float(x)
    u_text = uncertainty(u, digits)
    if u is None or not math.isfinite(x) or not math.isfinite(float(u)) or float(u) == 0:
        return plain(x), u_text
    exponent = uncertainty_exponent(float(u), digits)
    if x != 0 and Decimal(x).adjusted() - exponent >= getcontext().prec:
        # the uncertainty's place lies further below the value's first digit than decimal
        # rounding reaches (1e308 ± 1e-300 would need some 600 digits the value does not
        # have): the value as it is
        return plain(x), u_text
    return _text(_quantize(x, exponent)), u_text


def round_to_uncertainty(
    x: float | None, u: float | None, digits: int = UNCERTAINTY_DIGITS, *, sign: bool = False
) -> str:
    """``x`` rounded to the decimal place of ``u``'s last significant digit: a column of
    values (or of D, a median) beside a column of their uncertainties.  ``sign`` puts
    ``+`` before a positive number that does not round to zero (D: ``+1.468``)."""
    text = value_with_uncertainty(x, u, digits)[0]
    if sign and x is not None and float(x) > 0 and text.strip("0.") not in ("", "∞"):
        return "+" + text
    return text


def column_places(values: Iterable[float | None], digits: int = 6) -> int:
    """The number of decimals that writes the largest finite ``|value|`` of a column to
    ``digits`` significant digits (at least 0): one rule for a whole column of values
    that have no uncertainty of their own, so that ``422`` and ``419.468`` are written
    ``422.000`` and ``419.468``.  0 for a column without a non-zero finite value."""
    sizes = [abs(float(v)) for v in values if v is not None and math.isfinite(float(v))]
    largest = max(sizes, default=0.0)
    if largest == 0:
        return 0
    return max(0, digits - 1 - Decimal(largest).adjusted())


def percent_fraction(percent: float) -> float:
    """The fraction a percentage stands for, from its decimal text: ``1.2`` → 0.012 exactly
    (``1.2 / 100`` is 0.012 too, but ``0.7 / 100`` is 0.006999999999999999), so that a
    relative U of ``p %`` is stored as ``sensitivity × (p/100)`` with one rounding."""
    return float(Decimal(repr(float(percent))) / 100)
