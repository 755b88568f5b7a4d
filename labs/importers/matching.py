"""Finding values within a relative tolerance of a frequency in O(log n) instead of a scan."""

from __future__ import annotations

import math
from bisect import bisect_left, bisect_right
from collections.abc import Iterable
from typing import Generic, TypeVar

T = TypeVar("T")

#: Above this tolerance the window bound below no longer holds; such indexes scan.
_MAX_INDEXED_TOL = 0.5


def close(a: float, b: float, rel_tol: float) -> bool:
    return math.isclose(a, b, rel_tol=rel_tol, abs_tol=0.0)


class FrequencyIndex(Generic[T]):
    """Items keyed by a frequency; :meth:`find` returns those within ``rel_tol``.

    ``isclose(a, b)`` means ``|a - b| <= tol * max(|a|, |b|)``, which implies
    ``|a - b| <= tol * |b| / (1 - tol) <= 2 * tol * |b|`` for ``tol <= 0.5``; the
    sorted keys inside twice that window are the only candidates, and each is
    still confirmed with :func:`math.isclose`, so the answer is exactly what a
    scan over every item would give, in the items' original order. A frequency
    with no other one inside its window is answered by one dict look-up.
    """

    __slots__ = ("_exact", "_items", "_keys", "_linear", "_ranked", "_rel_tol")

    def __init__(self, items: Iterable[tuple[float, T]], rel_tol: float) -> None:
        self._items = list(items)
        self._rel_tol = rel_tol
        keys = [float(f) for f, _ in self._items]
        self._linear = not (0 <= rel_tol <= _MAX_INDEXED_TOL) or not all(map(math.isfinite, keys))
        order = [] if self._linear else sorted(range(len(keys)), key=keys.__getitem__)
        self._keys = [keys[i] for i in order]
        self._ranked = order
        self._exact = {} if self._linear else self._isolated()

    def _isolated(self) -> dict[float, list[T]]:
        """Items by frequency, for the frequencies whose window holds no other frequency."""
        exact: dict[float, list[T]] = {}
        for f, i in zip(self._keys, self._ranked, strict=True):
            exact.setdefault(f, []).append(self._items[i][1])
        distinct = list(exact)  # ascending, as the keys are
        for n, f in enumerate(distinct):
            span = 4 * self._rel_tol * abs(f)
            crowded_below = n > 0 and f - distinct[n - 1] <= span
            if crowded_below or (n + 1 < len(distinct) and distinct[n + 1] - f <= span):
                del exact[f]
        return exact

    def find(self, frequency: float) -> list[T]:
        """Every item whose frequency is close to ``frequency``, in insertion order.

        The list returned for an isolated frequency is shared: do not change it.
        """
        hit = self._exact.get(frequency)
        if hit is not None:
            return hit
        tol, items = self._rel_tol, self._items
        if self._linear:
            return [item for f, item in items if close(f, frequency, tol)]
        span = 4 * tol * abs(frequency)
        lo = bisect_left(self._keys, frequency - span)
        hi = bisect_right(self._keys, frequency + span)
        if hi - lo == 1:  # the usual case: one candidate
            f, item = items[self._ranked[lo]]
            return [item] if close(f, frequency, tol) else []
        found = sorted(i for i in self._ranked[lo:hi] if close(items[i][0], frequency, tol))
        return [items[i][1] for i in found]
