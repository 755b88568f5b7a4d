"""Robust estimators of location and scale, ISO 13528:2022 Annex C.

Every statistic works on many groups (measurement points) at once.  The results of
each group are sorted once (one ``np.sort`` of the padded 2-D view); medians and
quartiles are then read by index, and the fixed-point iterations (Algorithm A,
Algorithm S) only need per-group counts and partial sums found by a vectorised
binary search on the sorted rows, so an iteration costs O(groups * log n), not O(n).

Algorithm A runs on the results centred on the median and scaled by the largest
deviation, and keeps the sum and sum of squares of the results inside its clipping
limits up to date as the limits move (only the results that cross a limit are added
or subtracted), so far outliers never enter a sum (no cancellation) and an
iteration touches a handful of results per group.
"""

from __future__ import annotations

from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from functools import cached_property
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike

from analysis.core.groups import (
    BoolArray,
    CoreInputError,
    FloatArray,
    Groups,
    IntArray,
    as_finite,
)
from analysis.core.lazy import stats  # scipy.stats on first use: 0.5 s of start-up
from analysis.core.qhampel import hampel_location, q_method_scale
from analysis.core.types import AssignedValues

MADE_FACTOR = 1.483  # ISO 13528:2022 C.2.2
NIQR_FACTOR = 0.7413  # ISO 13528:2022 C.2.3
ALG_A_FACTOR = 1.134  # ISO 13528:2022 C.3.1, Formula (C.10)
ALG_A_DELTA = 1.5  # ISO 13528:2022 C.3.1, Formula (C.7)
U_FACTOR = 1.25  # ISO 13528:2022 7.7.3, u(x_pt) = 1.25 s*/sqrt(p)
_EPS = 8 * np.finfo(np.float64).eps  # floor of the relative stopping rule (rounding noise)
_COLLAPSE = 1e-9  # s* below this fraction of its start value is reported as 0
# In the scaled units of the iteration (largest deviation = 1) an s* this small lives in
# subnormal arithmetic, where the update can stall without converging: a collapse too.
_SUBNORMAL = np.finfo(np.float64).tiny * 2.0**53
# A window's sums are recomputed directly when its centred sum of squares falls below
# this fraction of the squares that passed through it (see _Window).
_RESUM = 1e-3
_PARALLEL_SORT_MIN = 200_000  # below this, starting a thread costs more than it saves


@dataclass(frozen=True)
class PooledDeviation:
    """Result of Algorithm S (ISO 13528:2022 C.4), one entry per group.

    ``value`` is the robust pooled standard deviation (or range) w*; ``eta`` and
    ``xi`` are the limit and adjustment factors used (Table C.1, from chi-square).
    """

    value: FloatArray
    iterations: IntArray
    converged: BoolArray
    degenerate: BoolArray
    n: IntArray
    eta: FloatArray
    xi: FloatArray


@dataclass(frozen=True)
class _Sorted:
    """Results of every group sorted in a (n_groups, max_n) array, NaN after the n-th.

    ``rows`` must not change once :attr:`keys` has been used (searches are cached)."""

    rows: FloatArray
    n: IntArray

    @property
    def index(self) -> IntArray:
        return np.arange(self.n.size)

    @cached_property
    def keys(self) -> np.ndarray:
        """The rows as one globally sorted 1-D array of complex keys row + value·j.

        numpy orders complex numbers lexicographically (real part, then imaginary), so
        one ``np.searchsorted`` finds a value in every row at once, exactly (no float
        offsets).  The NaN padding becomes +inf, which stays at the end of its row."""
        padded = self.rows.shape[1] > 0 and bool(np.isnan(self.rows[:, -1]).any())
        vals = np.where(np.isnan(self.rows), np.inf, self.rows) if padded else self.rows
        keys = np.empty(self.rows.shape, dtype=np.complex128)
        keys.real = self.index[:, None]
        keys.imag = vals
        return keys.reshape(-1)


def _sorted_groups(name: str, x: ArrayLike, groups: Groups) -> _Sorted:
    arr = as_finite(name, x)
    if arr.size != groups.size:
        raise CoreInputError(f"{name} has {arr.size} values but the groups cover {groups.size}")
    n = groups.counts()
    empty = np.flatnonzero(n == 0)
    if empty.size:
        raise CoreInputError(f"group(s) {empty[:10].tolist()} have no results")
    rows = groups.padded(arr)  # a fresh array: sort it in place
    _sort_rows(rows)
    return _Sorted(rows, n)


def _sort_rows(rows: FloatArray) -> None:
    """Sort every row in place; a large array is sorted as two blocks of rows in two
    threads (numpy releases the GIL while sorting), the largest single cost of the
    robust estimators.  The result does not depend on the split."""
    if rows.size < _PARALLEL_SORT_MIN or rows.shape[0] < 2:
        rows.sort(axis=1)
        return
    half = rows.shape[0] // 2
    with ThreadPoolExecutor(max_workers=2) as pool:
        for future in [pool.submit(block.sort, axis=1) for block in (rows[:half], rows[half:])]:
            future.result()


def _row_median(s: _Sorted) -> FloatArray:
    """Median of each sorted row (mean of the two middle values when n is even)."""
    r = s.index
    return (s.rows[r, (s.n - 1) // 2] + s.rows[r, s.n // 2]) / 2


def _row_quantile(s: _Sorted, q: float) -> FloatArray:
    """Quantile by linear interpolation between order statistics (Hyndman-Fan type 7,
    numpy's and R's default), the definition pt13528 uses for Table E.5."""
    h = (s.n - 1) * q
    j = np.floor(h).astype(np.intp)
    t = h - j
    a = s.rows[s.index, j]
    b = s.rows[s.index, np.minimum(j + 1, s.n - 1)]
    diff = b - a
    return np.where(t >= 0.5, b - diff * (1 - t), a + diff * t)


def _count_below(s: _Sorted, sel: IntArray, v: FloatArray, *, inclusive: bool) -> IntArray:
    """Per selected row, how many of its first n sorted values are < v (<= v if inclusive),
    for all rows in one binary search over :attr:`_Sorted.keys`."""
    q = np.empty(sel.size, dtype=np.complex128)
    q.real = sel
    q.imag = v
    pos = np.searchsorted(s.keys, q, side="right" if inclusive else "left")
    return np.minimum(pos - sel * s.rows.shape[1], s.n[sel])


def _more_than_half_identical(s: _Sorted, value: FloatArray) -> BoolArray:
    """True where more than half of a group's results equal ``value`` (its median)."""
    sel = s.index
    equal = _count_below(s, sel, value, inclusive=True) - _count_below(
        s, sel, value, inclusive=False
    )
    return 2 * equal > s.n


def _made(s: _Sorted, med: FloatArray) -> FloatArray:
    """MADe = 1.483 median|x_i - median(x)|, ISO 13528:2022 C.2.2.

    The absolute deviations of a sorted row are two sorted runs (left of the median,
    read backwards, and right of it), so their order statistics come from a k-th
    smallest search over two sorted arrays instead of a second sort."""
    n = s.n
    lo_k = _kth_abs_deviation(s, med, (n - 1) // 2)
    hi_k = _kth_abs_deviation(s, med, n // 2)
    return MADE_FACTOR * (lo_k + hi_k) / 2


def _kth_abs_deviation(s: _Sorted, med: FloatArray, k: IntArray) -> FloatArray:
    """k-th smallest (0-based) of |x_i - med| per sorted row, by bisection on how many
    deviations are on the left side: O(log n) vectorised steps, no sort."""
    r = s.index
    split = _count_below(s, r, med, inclusive=False)  # x_i < med left of split
    n_left, n_right = split, s.n - split
    last = s.rows.shape[1] - 1

    def left(t: IntArray) -> FloatArray:  # t-th smallest deviation on the left (0-based)
        return med - s.rows[r, np.clip(split - 1 - t, 0, last)]

    def right(t: IntArray) -> FloatArray:
        return s.rows[r, np.clip(split + t, 0, last)] - med

    # Find how many of the k+1 smallest come from the left: lo <= a <= hi.
    lo = np.maximum(0, k + 1 - n_right)
    hi = np.minimum(k + 1, n_left)
    for _ in range(int(s.rows.shape[1]).bit_length() + 1):
        a = (lo + hi) // 2
        b = k + 1 - a
        # too few from the left when the next left value is smaller than the last right one
        more = (a < n_left) & (b > 0) & (left(a) < right(b - 1))
        lo = np.where(more & (lo < hi), a + 1, lo)
        hi = np.where(~more & (lo < hi), a, hi)
    a = lo
    b = k + 1 - a
    cand_left = np.where(a > 0, left(a - 1), -np.inf)
    cand_right = np.where(b > 0, right(b - 1), -np.inf)
    return np.maximum(cand_left, cand_right)


def _assigned(
    s: _Sorted, med: FloatArray, s_star: FloatArray, method: str, groups: Groups, **diag: np.ndarray
) -> AssignedValues:
    return AssignedValues(
        value=med,
        standard_uncertainty=U_FACTOR * s_star / np.sqrt(s.n),
        method=method,
        included=np.ones(groups.size, dtype=bool),
        diagnostics={"s_star": s_star, "n": s.n.copy(), **diag},
    )


def median_made(x: ArrayLike, groups: Groups) -> AssignedValues:
    """x* = median, s* = MADe (ISO 13528:2022 C.2.1, C.2.2); u(x_pt) = 1.25 s*/sqrt(p) (7.7.3).

    ``degenerate`` is True where s* = 0, i.e. more than half of the results are identical."""
    s = _sorted_groups("x", x, groups)
    med = _row_median(s)
    s_star = _made(s, med)
    degenerate = (s_star == 0) | _more_than_half_identical(s, med)
    return _assigned(s, med, s_star, "median_made", groups, degenerate=degenerate)


def median_niqr(x: ArrayLike, groups: Groups) -> AssignedValues:
    """x* = median, s* = nIQR = 0.7413 (Q3 - Q1) (ISO 13528:2022 C.2.1, C.2.3).

    Quartiles by linear interpolation between order statistics (Hyndman-Fan type 7,
    ``numpy.quantile`` default), as pt13528 does: it reproduces Table E.5 (the NOTE
    under that table warns that packages differ).  ``degenerate``: s* = 0 or more
    than half of the results identical."""
    s = _sorted_groups("x", x, groups)
    med = _row_median(s)
    s_star = NIQR_FACTOR * (_row_quantile(s, 0.75) - _row_quantile(s, 0.25))
    degenerate = (s_star == 0) | _more_than_half_identical(s, med)
    return _assigned(s, med, s_star, "median_niqr", groups, degenerate=degenerate)


def q_hampel(x: ArrayLike, groups: Groups) -> AssignedValues:
    """Q/Hampel, ISO 13528:2022 C.5.4: s* by the Q method (C.5.2.2, one result per
    laboratory) and x* by the Hampel estimator with that s* (C.5.3.3, finite-step
    algorithm: the zero of sum psi((x_i - x*) / s*) closest to the median); u(x_pt) =
    1.25 s*/sqrt(p) (7.7.3, as for the other robust estimators here).  Algorithms and
    conventions (ties, rounding): :mod:`analysis.core.qhampel`.

    Diagnostics: ``s_star``, ``n``, ``degenerate`` (s* = 0: all results identical, or a
    single one; x* is then the median) and ``median_fallback`` (x* is the median because
    no single zero is closest to it, or s* = 0)."""
    s = _sorted_groups("x", x, groups)
    med = _row_median(s)
    s_star, _ = q_method_scale(s.rows, s.n)
    x_star, fallback = hampel_location(s.rows, s.n, med, s_star)
    return _assigned(
        s, x_star, s_star, "q_hampel", groups, degenerate=s_star == 0, median_fallback=fallback
    )


@dataclass
class _Window:
    """Sum and sum of squares of the values at positions i..j-1 of every sorted row,
    kept up to date as Algorithm A moves its clipping limits.

    The first window is summed directly (numpy's pairwise summation); afterwards only
    the values that enter or leave the window are added or subtracted.  The limits
    settle within a few iterations, so the whole iteration touches a small fraction of
    the results instead of building full prefix sums (four cumulative sums over every
    result, which cost more than the sort).

    Cancellation: a value added and later removed leaves a rounding residue of order
    eps * v**2 in the sum of squares.  When the window shrinks onto results much closer
    together than the values that passed through it (a collapsing iteration, or a
    cluster of near-identical results), that residue would act as a spurious variance
    and give the iteration a false fixed point.  ``mag`` bounds the residue (sum of the
    squares of every value added or removed since the window was last summed
    directly); where the window's own centred sum of squares falls below
    ``_RESUM * mag`` its sums are recomputed directly (:meth:`resum`), so the centred
    sum always carries a relative error below ~1e-12.
    """

    rows: FloatArray
    i: IntArray
    j: IntArray
    s1: FloatArray
    s2: FloatArray
    mag: FloatArray

    @classmethod
    def start(cls, rows: FloatArray, sel: IntArray, i: IntArray, j: IntArray) -> _Window:
        """Windows [i, j) of the selected rows summed directly; the others start empty."""
        g = rows.shape[0]
        win = cls(
            rows,
            np.zeros(g, np.intp),
            np.zeros(g, np.intp),
            np.zeros(g),
            np.zeros(g),
            np.zeros(g),
        )
        win.i[sel], win.j[sel] = i, j
        win.resum(sel)
        return win

    def resum(self, sel: IntArray) -> None:
        """Sum the selected rows' current windows directly.

        Each window is reduced on its own (``np.add.reduceat``), so a group's sums, and
        hence its Algorithm A result, do not depend on the other groups of the call."""
        if not sel.size:
            return
        width = self.rows.shape[1]
        i, j = self.i[sel], self.j[sel]
        flat = self.rows.reshape(-1)
        bounds = np.column_stack((sel * width + i, sel * width + j)).reshape(-1)
        if bounds[-1] == flat.size:  # reduceat's last segment runs to the end anyway
            bounds = bounds[:-1]
        bounds = np.minimum(bounds, flat.size - 1)  # only an empty window can be clipped
        nonempty = j > i
        self.s1[sel] = np.where(nonempty, np.add.reduceat(flat, bounds)[::2], 0.0)
        self.s2[sel] = np.where(nonempty, np.add.reduceat(flat * flat, bounds)[::2], 0.0)
        self.mag[sel] = self.s2[sel]

    def move(self, sel: IntArray, i: IntArray, j: IntArray) -> tuple[FloatArray, FloatArray]:
        """Move the selected rows' windows to [i, j) and return their sums (summed
        afresh where the residue of the updates could matter, see the class)."""
        # sum[i', j') = sum[i, j) - sum[i, i') + sum[j, j'), with sum[a, b) = -sum[b, a)
        d1, d2 = _segment_sums(self.rows, sel, self.j[sel], j)
        e1, e2 = _segment_sums(self.rows, sel, self.i[sel], i)
        self.s1[sel] += d1 - e1
        self.s2[sel] += d2 - e2
        self.mag[sel] += np.abs(d2) + np.abs(e2)
        self.i[sel], self.j[sel] = i, j
        k = j - i
        s1, s2 = self.s1[sel], self.s2[sel]
        centred = s2 - s1 * s1 / np.maximum(k, 1)
        self.resum(sel[(k > 0) & (centred < _RESUM * self.mag[sel])])
        return self.s1[sel], self.s2[sel]


def _segment_sums(
    rows: FloatArray, sel: IntArray, old: IntArray, new: IntArray
) -> tuple[FloatArray, FloatArray]:
    """Signed sum and sum of squares of rows[sel, old:new] (negative when new < old),
    all rows at once: the ragged segments are gathered into one flat array."""
    lo, length = np.minimum(old, new), np.abs(new - old)
    total = int(length.sum())
    if total == 0:
        return np.zeros(sel.size), np.zeros(sel.size)
    seg = np.repeat(np.arange(sel.size), length)
    offset = np.arange(total) - np.repeat(np.cumsum(length) - length, length)
    v = rows[sel[seg], lo[seg] + offset]
    sign = np.where(new >= old, 1.0, -1.0)
    s1 = np.bincount(seg, weights=v, minlength=sel.size)
    s2 = np.bincount(seg, weights=v * v, minlength=sel.size)
    return sign * s1, sign * s2


def _cum(v: FloatArray) -> FloatArray:
    out = np.zeros((v.shape[0], v.shape[1] + 1))
    np.cumsum(v, axis=1, out=out[:, 1:])
    return out


@dataclass
class _AState:
    """Per-group state of Algorithm A, in units centred on the median and scaled."""

    x: FloatArray
    s: FloatArray
    s0: FloatArray
    active: BoolArray
    iterations: IntArray
    converged: BoolArray
    collapsed: BoolArray
    ratio: FloatArray


def _a_step(
    a: _Sorted, win: _Window | None, sel: IntArray, x: FloatArray, s: FloatArray, solve: bool
) -> tuple[FloatArray, FloatArray, BoolArray, BoolArray, _Window]:
    """One update of Formulae (C.7) to (C.10) for the selected groups.

    Also says whether every result inside the limits is identical (the collapse
    pattern), and where the exact fixed point was reached (see :func:`_a_fixed_point`)."""
    n = a.n[sel]
    lo, hi = x - ALG_A_DELTA * s, x + ALG_A_DELTA * s
    i = _count_below(a, sel, lo, inclusive=False)
    j = _count_below(a, sel, hi, inclusive=True)
    k_lo, k_in, k_hi = i, j - i, n - j
    if win is None:
        win = _Window.start(a.rows, sel, i, j)
        s1, s2 = win.s1[sel], win.s2[sel]
        stable = np.zeros(sel.size, bool)
    else:
        stable = (win.i[sel] == i) & (win.j[sel] == j)
        s1, s2 = win.move(sel, i, j)
    first = a.rows[sel, np.minimum(i, n - 1)]
    last = a.rows[sel, np.maximum(j - 1, 0)]
    flat = (k_in > 0) & (first == last)
    # identical results inside: their sums are known exactly, and the squared deviations
    # are taken from the value itself (no cancellation in s2 - 2 mean s1 + k mean^2)
    s1 = np.where(flat, k_in * first, s1)
    mean = (k_lo * lo + s1 + k_hi * hi) / n
    inside = np.where(flat, k_in * (first - mean) ** 2, s2 - 2 * mean * s1 + k_in * mean**2)
    ss = k_lo * (lo - mean) ** 2 + k_hi * (hi - mean) ** 2 + inside
    new_s = ALG_A_FACTOR * np.sqrt(np.maximum(ss, 0.0) / (n - 1))
    exact = np.zeros(sel.size, bool)
    try_ = np.flatnonzero(stable & ~flat & (k_in > 1) & solve)
    if try_.size:
        x_f, s_f, ok = _a_fixed_point(a, sel[try_], i[try_], j[try_], s1[try_], s2[try_])
        hit = try_[ok]
        mean[hit], new_s[hit], exact[hit] = x_f[ok], s_f[ok], True
    return mean, new_s, flat, exact, win


def _a_fixed_point(
    a: _Sorted, sel: IntArray, i: IntArray, j: IntArray, s1: FloatArray, s2: FloatArray
) -> tuple[FloatArray, FloatArray, BoolArray]:
    """The fixed point of Algorithm A for a given split of the results, if it has one.

    Once k_lo results are clipped at x* - 1.5 s*, k_hi at x* + 1.5 s* and the k_in
    results in between sum to S1 (squares S2), Formulae (C.8)-(C.10) at the fixed point
    are linear in x* and quadratic in s*:  x* = A + B s* with A = S1/k_in,
    B = 1.5 (k_hi - k_lo)/k_in, and s*^2 ((p-1)/1.134^2 - 2.25 (k_lo + k_hi) - k_in B^2)
    = S2 - S1^2/k_in.  The solution is the fixed point if it splits the results the
    same way (checked by searching its limits); then the iteration's own limit has been
    reached exactly and iterating further would only approach it."""
    n = a.n[sel]
    k_lo, k_in, k_hi = i, j - i, n - j
    b = ALG_A_DELTA * (k_hi - k_lo) / k_in
    c = np.maximum(s2 - s1 * s1 / k_in, 0.0)
    d = (n - 1) / ALG_A_FACTOR**2 - ALG_A_DELTA**2 * (k_lo + k_hi) - k_in * b * b
    s = np.sqrt(c / np.where(d > 0, d, 1.0))
    x = s1 / k_in + b * s
    same = (
        (d > 0)
        & (s > 0)
        & (_count_below(a, sel, x - ALG_A_DELTA * s, inclusive=False) == i)
        & (_count_below(a, sel, x + ALG_A_DELTA * s, inclusive=True) == j)
    )
    return x, s, same


def _a_update(
    st: _AState,
    sel: IntArray,
    new_x: FloatArray,
    new_s: FloatArray,
    flat: BoolArray,
    exact: BoolArray,
    it: int,
    rtol: float,
) -> None:
    """Stopping rule and collapse detection (after pt13528's), then commit the update."""
    x, s = st.x[sel], st.s[sel]
    shrink = flat & (new_s < s)
    r = np.where(shrink, new_s / np.where(s > 0, s, 1.0), np.nan)
    collapse = (
        (new_s < _COLLAPSE * st.s0[sel])
        | (new_s < _SUBNORMAL)
        | (shrink & (np.abs(r - st.ratio[sel]) <= 1e-12))
    )
    limit = np.maximum(rtol * new_s, _EPS * np.abs(new_x))
    done = exact | ((np.abs(new_x - x) < limit) & (np.abs(new_s - s) < limit))
    st.ratio[sel] = r
    st.x[sel] = np.where(collapse, 0.0, new_x)
    st.s[sel] = np.where(collapse, 0.0, new_s)
    stop = collapse | done
    st.collapsed[sel] = collapse
    st.converged[sel] = stop
    st.iterations[sel] = it
    st.active[sel] = ~stop


def _same_3_figures(new: FloatArray, old: FloatArray) -> BoolArray:
    """True where ``new`` and ``old`` agree to three significant figures (of ``new``)."""
    mag = np.floor(np.log10(np.maximum(np.abs(new), np.finfo(np.float64).tiny)))
    q = 10.0 ** (mag - 2)
    return np.asarray(np.round(new / q) == np.round(old / q))


def _a_start(a: _Sorted) -> tuple[FloatArray, BoolArray]:
    """Starting s* = MADe of the scaled results; where MADe = 0 (more than half of the
    results identical) C.3.1 NOTE 2 falls back to the standard deviation."""
    made = _made(a, _row_median(a))
    s = made.copy()
    zero = np.flatnonzero((made == 0) & (a.n > 1))
    if zero.size:
        s[zero] = np.nanstd(a.rows[zero], axis=1, ddof=1)
    return s, made == 0


def algorithm_a(
    x: ArrayLike,
    groups: Groups,
    *,
    rtol: float = 1e-10,
    max_iter: int = 500,
    stopping: Literal["exact", "iso2022"] = "exact",
) -> AssignedValues:
    """Robust mean and standard deviation by Algorithm A, ISO 13528:2022 C.3.1, per group.

    Start x* = median, s* = MADe; iterate delta = 1.5 s*, clip to [x* - delta, x* + delta],
    x* = mean, s* = 1.134 sd(ddof=1) of the clipped results (Formulae C.5 to C.10), all
    groups together.  Stopping rule: the iteration stops at its exact limit as soon as
    the split of the results into clipped-low, inside and clipped-high has stayed the
    same for one step and the fixed point of that split (solved in closed form, see
    :func:`_a_fixed_point`) splits the results the same way; otherwise when both
    |change of x*| and |change of s*| are below ``rtol * s*`` (floored at rounding
    level; pt13528's rule).  Both are stricter than the standard's "no change in the
    third significant figure" and, unlike it, independent of unit and origin; the exact
    stop needs typically 3 to 10 steps where the plain iteration needs 60 to 350, and
    agrees with pt13528 run to tol = 1e-15.  u(x_pt) = 1.25 s*/sqrt(p) (7.7.3).

    ``stopping="iso2022"`` applies the standard's own rule instead (C.3.1: stop when
    x* and s* no longer change in their third significant figure from one update to
    the next; the start is not an update).  It stops before convergence and depends on
    the unit and origin of the data, but it is the rule the worked examples of Annex E
    were computed with (e.g. Table E.1 prints s* = 7.23 where the limit is 7.2373).

    Degenerate cases (``degenerate`` True):
    * MADe = 0 (more than half of the results identical): s* starts from the standard
      deviation (C.3.1 NOTE 2); if the iteration then collapses (s* -> 0, detected as in
      pt13528), x* = median and s* = 0 are returned.
    * all results identical, or a group of one result: x* = median, s* = 0, 0 iterations.
    * s* below 2**-969 (~2e-292) of the largest deviation from the median (e.g. results
      0, 2e-311 and 6e5): the iteration would run in subnormal arithmetic, where it can
      stall and its few significant bits mean nothing; reported as a collapse, x* =
      median and s* = 0 (pt13528 iterates on and returns an s* of order 1e-311).
    A group of two results gives x* = mean and s* = 1.134 |x1 - x2| / sqrt(2) (no
    clipping happens).  Diagnostics: ``s_star``, ``iterations``, ``converged``,
    ``degenerate``, ``n``; a group that hits ``max_iter`` has ``converged`` False.
    """
    if not (rtol > 0 and max_iter >= 1):
        raise CoreInputError("rtol must be > 0 and max_iter >= 1")
    if stopping not in ("exact", "iso2022"):
        raise CoreInputError(f"unknown stopping rule {stopping!r}: use 'exact' or 'iso2022'")
    s = _sorted_groups("x", x, groups)
    med = _row_median(s)
    # Centre on the median and scale to the largest deviation, in place (the sorted
    # rows are not needed again): the iteration then works in units of order one.
    rows = s.rows
    rows -= med[:, None]
    m = np.fmax(np.abs(rows[s.index, 0]), np.abs(rows[s.index, s.n - 1]))
    unit = np.where(m > 0, m, 1.0)
    rows /= unit[:, None]
    a = _Sorted(rows, s.n)
    s0, made_zero = _a_start(a)
    g = s.n.size
    st = _AState(
        np.zeros(g),
        s0.copy(),
        s0,
        (s0 > 0) & (s.n > 1),
        np.zeros(g, np.intp),
        ~((s0 > 0) & (s.n > 1)),
        np.zeros(g, bool),
        np.full(g, np.nan),
    )
    win: _Window | None = None
    for it in range(1, max_iter + 1):
        sel = np.flatnonzero(st.active)
        if not sel.size:
            break
        new_x, new_s, flat, exact, win = _a_step(
            a, win, sel, st.x[sel], st.s[sel], solve=stopping == "exact"
        )
        if stopping == "iso2022":  # original units: significant figures depend on them
            exact = (it >= 2) & _same_3_figures(
                med[sel] + unit[sel] * new_x, med[sel] + unit[sel] * st.x[sel]
            )
            exact &= _same_3_figures(unit[sel] * new_s, unit[sel] * st.s[sel])
        _a_update(st, sel, new_x, new_s, flat, exact, it, 0.0 if stopping == "iso2022" else rtol)
    st.iterations[st.active] = max_iter
    s_star = unit * st.s
    degenerate = made_zero | (s_star == 0)
    return _assigned(
        s,
        med + unit * st.x,
        s_star,
        "algorithm_a",
        groups,
        degenerate=degenerate,
        iterations=st.iterations,
        converged=st.converged.copy(),
    )


SIGMA_PT_ESTIMATORS = ("algorithm_a", "q_method")


def sigma_pt_robust(
    x: ArrayLike,
    groups: Groups,
    *,
    rtol: float = 1e-10,
    max_iter: int = 500,
    estimator: str | Sequence[str] = "algorithm_a",
    needed: ArrayLike | None = None,
) -> FloatArray:
    """sigma_pt = robust standard deviation s* of the round per group (ISO 13528:2022 8.7):
    by Algorithm A (C.3), or by the Q method (C.5.2.2) where ``estimator`` (one name, or
    one per group) is ``"q_method"``, the s* that goes with a Q/Hampel assigned value.
    Raises CoreInputError for groups where s* = 0 (degenerate data): no z score can be
    formed there; prescribe sigma_pt for those measurement points.  ``needed`` (a bool
    per group, default all) marks the groups whose s* is used: one not needed (its
    sigma_pt is prescribed) gets NaN where its s* is 0 instead of an error."""
    names = np.broadcast_to(np.asarray(estimator, dtype=object), (groups.n_groups,))
    unknown = set(names.tolist()) - set(SIGMA_PT_ESTIMATORS)
    if unknown:
        raise CoreInputError(f"unknown robust estimator(s) {sorted(unknown)!r} for sigma_pt")
    s_star = np.zeros(groups.n_groups)
    for name in SIGMA_PT_ESTIMATORS:  # a loop over two estimators, not over groups
        sel = np.flatnonzero(names == name)
        if not sel.size:
            continue
        part, sub = _subset(x, groups, sel)
        if name == "q_method":
            s_star[sel] = q_hampel(part, sub).diagnostics["s_star"]
        else:
            s_star[sel] = algorithm_a(part, sub, rtol=rtol, max_iter=max_iter).diagnostics["s_star"]
    use = np.ones(groups.n_groups, dtype=bool) if needed is None else np.asarray(needed, bool)
    s_star[(s_star == 0) & ~use] = np.nan
    bad = np.flatnonzero(s_star == 0)
    if bad.size:
        raise DegenerateScaleError(
            f"robust s* is 0 for group(s) {bad[:10].tolist()} (more than half of the results "
            "identical for Algorithm A, all of them for the Q method, or a single result): "
            "prescribe sigma_pt for these measurement points",
            groups=tuple(int(g) for g in bad),
        )
    return s_star


class DegenerateScaleError(CoreInputError):
    """A robust s* of 0 where σ_pt is to be s*; ``groups`` lists those groups."""

    def __init__(self, message: str, *, groups: tuple[int, ...]) -> None:
        super().__init__(message)
        self.groups = groups


def _subset(x: ArrayLike, groups: Groups, sel: IntArray) -> tuple[FloatArray, Groups]:
    """The results of the selected groups, as groups 0 .. sel.size - 1 in that order."""
    arr = np.asarray(x, dtype=np.float64).reshape(-1)
    if sel.size == groups.n_groups:
        return arr, groups
    rows = np.flatnonzero(np.isin(groups.index, sel))
    index = np.searchsorted(sel, groups.index[rows])
    return arr[rows], Groups.from_index(index, sel.size)


def algorithm_s_factors(degrees_of_freedom: ArrayLike) -> tuple[FloatArray, FloatArray]:
    """Limit factor eta and adjustment factor xi of Algorithm S (ISO 13528:2022 Table C.1).

    With w^2 ~ sigma^2 chi2_nu / nu: eta = sqrt(chi2_{0.90; nu} / nu) and
    xi = 1 / sqrt(F_{nu+2}(nu eta^2) + eta^2 (1 - F_nu(nu eta^2))), F_k the chi-square
    cdf, so that the winsorised mean square is unbiased at the normal model.
    """
    nu = np.asarray(degrees_of_freedom, dtype=np.float64)
    if not (np.all(np.isfinite(nu)) and np.all(nu >= 1) and np.all(nu == np.round(nu))):
        raise CoreInputError("degrees of freedom must be integers >= 1")
    c = stats.chi2.ppf(0.90, nu)
    eta = np.sqrt(c / nu)
    xi = 1.0 / np.sqrt(stats.chi2.cdf(c, nu + 2) + eta**2 * stats.chi2.sf(c, nu))
    return np.asarray(eta, dtype=np.float64), np.asarray(xi, dtype=np.float64)


def algorithm_s(
    w: ArrayLike,
    groups: Groups,
    degrees_of_freedom: ArrayLike,
    *,
    rtol: float = 1e-10,
    max_iter: int = 500,
) -> PooledDeviation:
    """Robust pooled standard deviation or range, Algorithm S, ISO 13528:2022 C.4.

    ``w`` holds one standard deviation (nu = m - 1) or range of duplicates (nu = 1) per
    participant; ``degrees_of_freedom`` is one integer, or one per group.  Start w* =
    median(w) (root mean square where the median is 0, C.4 NOTE); iterate psi = eta w*,
    w* = xi sqrt(mean(min(w_i, psi)^2)) until |change| < rtol * w*.  A majority of zeros
    drives w* to 0: reported as w* = 0 with ``degenerate`` True (as pt13528)."""
    s = _sorted_groups("w", w, groups)
    if np.any(s.rows[:, 0] < 0):
        raise CoreInputError("standard deviations and ranges cannot be negative")
    eta, xi = (np.broadcast_to(f, s.n.shape) for f in algorithm_s_factors(degrees_of_freedom))
    top = s.rows[s.index, s.n - 1]
    unit = np.where(top > 0, top, 1.0)
    a = _Sorted(s.rows / unit[:, None], s.n)
    c2 = _cum(np.nan_to_num(a.rows * a.rows))
    w0 = _row_median(a)
    w0 = np.where(w0 > 0, w0, np.sqrt(c2[a.index, a.n] / a.n))
    w_star, its = w0.copy(), np.zeros(a.n.size, np.intp)
    active, degenerate = top > 0, top == 0
    for it in range(1, max_iter + 1):
        sel = np.flatnonzero(active)
        if not sel.size:
            break
        psi = eta[sel] * w_star[sel]
        k = _count_below(a, sel, psi, inclusive=True)
        new = xi[sel] * np.sqrt((c2[sel, k] + (a.n[sel] - k) * psi**2) / a.n[sel])
        zeros_only = (k == 0) | (a.rows[sel, np.maximum(k - 1, 0)] == 0)
        collapse = (new < _COLLAPSE * w0[sel]) | ((new < w_star[sel]) & zeros_only)
        done = np.abs(new - w_star[sel]) < np.maximum(rtol, _EPS) * new
        w_star[sel] = np.where(collapse, 0.0, new)
        degenerate[sel] |= collapse
        its[sel] = it
        active[sel] = ~(collapse | done)
    return PooledDeviation(
        unit * np.where(top > 0, w_star, 0.0),
        its,
        ~active,
        degenerate,
        s.n.copy(),
        np.array(eta),
        np.array(xi),
    )
