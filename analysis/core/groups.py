"""Grouped (segmented) array operations: the shape every statistic in the core takes.

Results of a round are flat arrays (one entry per result) plus an integer group
index per result (the measurement point, or a compatibility level).  Statistics
are computed for all groups at once with ``np.bincount`` reductions or on a
padded 2-D view (groups x max group size) with NaN for the empty cells, never
with a Python loop over results.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.intp]
BoolArray = NDArray[np.bool_]


class CoreInputError(ValueError):
    """Bad numeric input to the core: says what was wrong and where (index or group)."""


@dataclass(frozen=True)
class Groups:
    """Assignment of n results to ``n_groups`` groups.

    ``index[i]`` is the group of result ``i`` (0 .. n_groups-1).  Built once per
    analysis and shared by every statistic; the permutation that sorts results by
    group and the padded layout are computed lazily and cached.
    """

    index: IntArray
    n_groups: int
    _cache: dict[str, np.ndarray] = field(default_factory=dict, repr=False, compare=False)

    @classmethod
    def from_index(cls, index: ArrayLike, n_groups: int | None = None) -> Groups:
        idx = np.asarray(index, dtype=np.intp)
        if idx.ndim != 1:
            raise CoreInputError("group index must be one-dimensional")
        if idx.size and idx.min() < 0:
            raise CoreInputError("group index must be >= 0")
        n = int(idx.max()) + 1 if idx.size else 0
        if n_groups is None:
            n_groups = n
        elif n > n_groups:
            raise CoreInputError(f"group index {n - 1} out of range for {n_groups} groups")
        return cls(index=idx, n_groups=int(n_groups))

    @classmethod
    def from_labels(cls, *keys: ArrayLike) -> tuple[Groups, list[tuple[object, ...]]]:
        """Group by one or more label columns; returns the groups and each group's key tuple."""
        if not keys:
            raise CoreInputError("at least one key column is needed")
        cols = [np.asarray(k) for k in keys]
        codes = []
        uniques = []
        for col in cols:
            u, inv = np.unique(col, return_inverse=True)
            uniques.append(u)
            codes.append(inv.reshape(-1))
        combined = (
            np.ravel_multi_index(codes, [len(u) for u in uniques])
            if codes[0].size
            else (np.zeros(0, dtype=np.intp))
        )
        present, index = np.unique(combined, return_inverse=True)
        parts = np.unravel_index(present, [len(u) for u in uniques])
        labels = [
            tuple(_scalar(uniques[j][parts[j][g]]) for j in range(len(cols)))
            for g in range(present.size)
        ]
        return cls(index=index.astype(np.intp), n_groups=int(present.size)), labels

    @property
    def size(self) -> int:
        return int(self.index.size)

    def counts(self) -> IntArray:
        if "counts" not in self._cache:
            self._cache["counts"] = np.bincount(self.index, minlength=self.n_groups)
        return self._cache["counts"]

    def sum(self, values: ArrayLike) -> FloatArray:
        """Sum of ``values`` per group (0 for an empty group)."""
        v = np.asarray(values, dtype=np.float64)
        # with weights, bincount returns float64 (numpy's stubs say int)
        return np.bincount(self.index, weights=v, minlength=self.n_groups).astype(
            np.float64, copy=False
        )

    def mean(self, values: ArrayLike) -> FloatArray:
        """Mean per group (NaN for an empty group: callers check ``counts()`` first)."""
        c = self.counts()
        with np.errstate(invalid="ignore", divide="ignore"):
            return self.sum(values) / c

    def broadcast(self, per_group: ArrayLike) -> FloatArray:
        """Expand one value per group back to one value per result."""
        return np.asarray(per_group, dtype=np.float64)[self.index]

    def order(self) -> IntArray:
        """Stable permutation that sorts results by group."""
        if "order" not in self._cache:
            self._cache["order"] = np.argsort(self.index, kind="stable")
        return self._cache["order"]

    def padded(self, values: ArrayLike, fill: float = np.nan) -> FloatArray:
        """Values laid out as a (n_groups, max_count) array, ``fill`` in unused cells."""
        v = np.asarray(values, dtype=np.float64)
        if self._is_rectangular():  # sorted by group, equal sizes: a plain reshape
            return v.reshape(self.n_groups, -1).copy()
        rows, cols = self._padded_positions()
        width = int(self.counts().max()) if self.n_groups else 0
        out = np.full((self.n_groups, width), fill, dtype=np.float64)
        out[rows, cols] = v[self.order()]
        return out

    def _is_rectangular(self) -> bool:
        """Results already sorted by group and every group the same size (the usual
        layout of a round loaded point by point): padding needs no scatter."""
        if "rectangular" not in self._cache:
            c = self.counts()
            flag = bool(
                self.n_groups > 0
                and c.min() == c.max()
                and (self.size < 2 or bool(np.all(self.index[1:] >= self.index[:-1])))
            )
            self._cache["rectangular"] = np.array(flag)
        return bool(self._cache["rectangular"])

    def unpad(self, padded: np.ndarray) -> np.ndarray:
        """Inverse of :meth:`padded`: back to one value per result, in input order."""
        if self._is_rectangular():
            return padded.reshape(-1).copy()
        rows, cols = self._padded_positions()
        out = np.empty(self.size, dtype=padded.dtype)
        out[self.order()] = padded[rows, cols]
        return out

    def _padded_positions(self) -> tuple[IntArray, IntArray]:
        if "rows" not in self._cache:
            order = self.order()
            rows = self.index[order]
            starts = np.concatenate(([0], np.cumsum(self.counts())[:-1]))
            cols = np.arange(self.size) - starts[rows]
            self._cache["rows"] = rows
            self._cache["cols"] = cols
        return self._cache["rows"], self._cache["cols"]


def _scalar(v: object) -> object:
    """A numpy scalar as the Python value (object arrays already hold Python values)."""
    return v.item() if isinstance(v, np.generic) else v


def as_finite(name: str, values: ArrayLike, *, positive: bool = False) -> FloatArray:
    """Validate a 1-D float array: finite (and > 0 when ``positive``), else CoreInputError
    naming the first bad index and value."""
    arr = np.asarray(values, dtype=np.float64).reshape(-1)
    bad = ~np.isfinite(arr)
    if positive:
        bad |= ~(arr > 0)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        need = "finite and > 0" if positive else "finite"
        raise CoreInputError(
            f"{name}[{i}] must be {need}, got {arr[i]!r} ({int(bad.sum())} bad value(s))"
        )
    return arr
