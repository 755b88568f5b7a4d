"""The Q method and the Hampel estimator, ISO 13528:2022 C.5.2.2 and C.5.3 (Q/Hampel, C.5.4).

Both work on the sorted, NaN-padded rows of :mod:`analysis.core.robust` (one row per
group, ``n`` results in each), all groups at once.

Q method (one result per laboratory).  H1 is the empirical distribution function of
the p(p-1)/2 absolute differences |x_i - x_j|, H1(0) the proportion of tied pairs.  G1
is 0 at 0 and, at each positive discontinuity x_l of H1, the mid-point of its jump,
(H1(x_l) + H1(x_l-1)) / 2, with H1 just below the first positive one being H1(0); G1
is linear in between; s* = G1^-1(0.25 + 0.75 H1(0)) / (sqrt(2) Phi^-1(0.625 + 0.375
H1(0))).  (pt13528 and the R implementations of the standard read it the same way; one
R version leaves H1(0) out of the first mid-point, which matters only if the quantile
falls below the first positive difference.)  Only the order statistics around that
quantile are needed, so the differences are never all formed: they are counted (how
many are <= t, per group) by a search on each sorted row, exact for the computed
differences because rounded subtraction is monotone; a bisection on t narrows every
group to a window of a few candidates per result, which are then formed and sorted.
Memory and time grow as p log p per group, not p^2 (10,000 laboratories at one point
are 5e7 pairs).

Ties.  Results reported to a fixed number of decimals give differences that are equal
in decimal but differ by rounding in binary (0.3 - 0.1 and 0.4 - 0.2); they are one
discontinuity of H1.  A difference within ``_TIE`` x the largest |x| of the group (twice
the largest such rounding spread) of 0 is a tied pair; above, a discontinuity is its
first difference (the anchor, where G1 is placed) and every difference within that
tolerance above it, and the next anchor is the first difference beyond: pt13528's rule.
The count of pairs is kept in integers, so a target quantile that falls exactly on a
node of G1 is met exactly (pt13528 sums H1 in floating point and may step into the
next segment there).

Hampel estimator, finite-step algorithm (C.5.3.3).  With psi of Formula (C.30)
(breakpoints 1.5, 3, 4.5), f(x) = sum psi((x_i - x) / s*) is continuous and linear
between the nodes x_i +/- 1.5 s*, +/- 3 s*, +/- 4.5 s*, so its zeros are the nodes
where f = 0 and the linear interpolations where f changes sign between nodes; x* is
the zero closest to the median, or the median where two are equally close.  One
addition to the printed search: where f vanishes at the median itself (on an interval
around it, e.g. two clusters of results more than 3 s* from the median), the median is
a zero and the closest one, so x* = median; the search of nodes alone finds only the
interval's ends (pt13528 takes the nearer end).  f is accumulated node to node from
its slopes, with the node spacings taken from the results and the breakpoints
separately, so a far outlier leaves no rounding residue in f near the centre; zeros
count as equally close within 1e-10 of their size (pt13528's tolerance grows with the
largest |x_i - median| / s* instead).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from typing import Literal

import numpy as np

from analysis.core.groups import BoolArray, FloatArray, IntArray
from analysis.core.lazy import stats  # scipy.stats on first use (pt_compare start-up)

_TIE = 4 * np.finfo(np.float64).eps  # times max|x|: differences merged as one discontinuity
_WINDOW = 4  # candidates per result at which the bisection stops and enumerates
_BREAKS = np.array([-4.5, -3.0, -1.5, 1.5, 3.0, 4.5])  # node offsets, units of s*
_SLOPES = np.array([1.0, -1.0, -1.0, 1.0, 1.0, -1.0])  # change of f's slope at each node
_CHUNK = 1 << 21  # Hampel nodes handled at once (memory bound for large rounds)


@dataclass(frozen=True)
class _Pairs:
    """The differences d(i, j) = x_j - x_i (j > i) of every sorted row, one entry per
    result: ``g`` its row, ``i`` its position.  A *bound* is, per result, the first
    j > i whose difference exceeds a threshold (the row length if none)."""

    rows: FloatArray
    n: IntArray
    g: IntArray
    i: IntArray
    start: IntArray  # flat index of each result's row start in ``rows``
    x: FloatArray  # each result's value

    @classmethod
    def of(cls, rows: FloatArray, n: IntArray) -> _Pairs:
        g = np.repeat(np.arange(n.size), n)
        i = np.arange(g.size) - np.repeat(np.cumsum(n) - n, n)
        start = g * rows.shape[1]
        return cls(rows, n, g, i, start, rows.reshape(-1)[start + i])

    def diff(self, e: IntArray, j: IntArray) -> FloatArray:
        """d(i, j) = x_j - x_i for results e (j must lie in the row)."""
        return np.asarray(self.rows.reshape(-1)[self.start[e] + j] - self.x[e])

    def bound(
        self,
        t: FloatArray,
        groups: BoolArray,
        *,
        strict: bool = False,
        lo: IntArray | None = None,
        hi: IntArray | None = None,
    ) -> IntArray:
        """First j with d(i, j) > t[g] (>= t[g] if ``strict``) for the results of the
        selected ``groups``, known to lie in [lo, hi] where given (the other results
        keep ``lo``, or i + 1)."""
        out = self.i + 1 if lo is None else lo.copy()
        e = np.flatnonzero(groups[self.g])
        g, i = self.g[e], self.i[e]
        a = i + 1 if lo is None else lo[e]
        b = self.n[g] if hi is None else hi[e]
        # Start from where x_i + t falls in the row (one search of every row at once):
        # that is the bound unless rounding puts a result next to x_i + t on the wrong
        # side, which the two checks find.
        q = np.empty(e.size, dtype=np.complex128)
        q.real = g
        with np.errstate(over="ignore"):
            q.imag = self.x[e] + t[g]
        side: Literal["left", "right"] = "left" if strict else "right"
        guess = np.clip(np.searchsorted(self.keys, q, side=side) - self.start[e], a, b)
        left_ok = (guess == a) | self._passes(e, guess - 1, t, strict)
        right_ok = (guess == b) | ~self._passes(e, guess, t, strict)
        a = np.where(right_ok, np.where(left_ok, guess, a), guess + 1)
        b = np.where(left_ok, np.where(right_ok, guess, b), guess - 1)
        act = np.flatnonzero(a < b)
        while act.size:  # binary search where the start was wrong
            mid = (a[act] + b[act]) // 2
            ok = self._passes(e[act], mid, t, strict)
            a[act] = np.where(ok, mid + 1, a[act])
            b[act] = np.where(ok, b[act], mid)
            act = act[a[act] < b[act]]
        out[e] = a
        return out

    def _passes(self, e: IntArray, j: IntArray, t: FloatArray, strict: bool) -> BoolArray:
        """d(i, j) <= t (< t if strict) for results e (j clipped into the row)."""
        d = self.diff(e, np.clip(j, 0, self.rows.shape[1] - 1))
        limit = t[self.g[e]]
        return np.asarray(d < limit if strict else d <= limit)

    @cached_property
    def keys(self) -> np.ndarray:
        """The rows as one sorted array of complex keys row + value·j (as in robust.py)."""
        keys = np.empty(self.rows.shape, dtype=np.complex128)
        keys.real = np.arange(self.n.size)[:, None]
        keys.imag = np.where(np.isnan(self.rows), np.inf, self.rows)
        return keys.reshape(-1)

    def count(self, bound: IntArray) -> IntArray:
        """Differences before the bound, per group."""
        return np.bincount(self.g, weights=bound - self.i - 1, minlength=self.n.size).astype(
            np.int64
        )

    def below(self, bound: IntArray, groups: BoolArray | None = None) -> FloatArray:
        """Largest difference before the bound, per (selected) group (-inf if none)."""
        has = bound - 1 > self.i
        out = np.full(self.n.size, -np.inf)
        e = np.flatnonzero(has if groups is None else has & groups[self.g])
        d = self.diff(e, bound[e] - 1)
        np.maximum.at(out, self.g[e], d)
        return out

    def above(self, bound: IntArray, groups: BoolArray | None = None) -> FloatArray:
        """Smallest difference at or after the bound, per (selected) group (+inf if none)."""
        has = bound < self.n[self.g]
        e = np.flatnonzero(has if groups is None else has & groups[self.g])
        out = np.full(self.n.size, np.inf)
        d = self.diff(e, bound[e])
        np.minimum.at(out, self.g[e], d)
        return out

    def run_bottom(self, v: FloatArray, tol: FloatArray, groups: BoolArray) -> FloatArray:
        """Smallest difference reached from v down through gaps of at most ``tol``."""
        bottom, act = v.copy(), groups.copy()
        while act.any():
            new = self.above(self.bound(bottom - tol, act, strict=True), act)
            act &= new < bottom
            bottom = np.where(act, new, bottom)
        return bottom

    def cluster(
        self, v: FloatArray, tol: FloatArray, groups: BoolArray
    ) -> tuple[FloatArray, IntArray, IntArray]:
        """The discontinuity of H1 that holds the difference v: its first member (the
        anchor; 0 for the tied pairs) and the bounds of the differences below the anchor
        and up to its last member.

        A discontinuity is an anchor and every difference within ``tol`` above it; the
        next anchor is the first difference beyond.  After a gap above ``tol`` a new one
        starts in any case, so the anchors are followed from the bottom of v's run
        (the differences connected to v by gaps of at most ``tol``), and those within
        ``tol`` of 0 form the tied pairs."""
        bottom = self.run_bottom(v, tol, groups)
        anchor = np.where(bottom <= tol, 0.0, bottom)
        top, j_le, act = anchor.copy(), self.i + 1, groups.copy()
        while act.any():  # one step per discontinuity from the run's bottom to v's
            j = self.bound(anchor + tol, act)
            mine = act[self.g]
            j_le[mine] = j[mine]
            top = np.where(act, self.below(j, act), top)
            act &= v > top
            anchor = np.where(act, self.above(j, act), anchor)
        return anchor, self.bound(anchor, groups, strict=True), j_le


def q_method_scale(rows: FloatArray, n: IntArray) -> tuple[FloatArray, FloatArray]:
    """s* by the Q method (ISO 13528:2022 C.5.2.2, Formulae C.22 to C.25, one result per
    laboratory) of every sorted row, and H1(0), the proportion of tied pairs.  s* = 0
    where all results are tied (or a group has one result)."""
    pairs = _Pairs.of(rows, n)
    big_n = n.astype(np.int64) * (n - 1) // 2
    last = rows[np.arange(n.size), np.maximum(n - 1, 0)]
    tol = _TIE * np.fmax(np.abs(rows[:, 0]), np.abs(last))
    everyone = big_n > 0
    j_zero = pairs.bound(tol, everyone)  # differences within tol of 0 are tied pairs
    c0 = pairs.count(j_zero)
    h0 = np.where(everyone, c0 / np.maximum(big_n, 1), 1.0)
    live = c0 < big_n
    s_star = np.zeros(n.size)
    if not live.any():
        return s_star, h0
    # G1 is counted in units of 1/(2N): the target 0.25 + 0.75 H1(0) is (N + 3 c0) / 2
    target2 = big_n + 3 * c0
    v = _select(pairs, (target2 + 3) // 4, live, tol, j_zero, c0, last - rows[:, 0])
    x_prev, s_prev, x_u, s_u = _bracket(pairs, v, tol, live, c0)
    with np.errstate(invalid="ignore", divide="ignore"):
        frac = (target2 / 2 - s_prev) / (s_u - s_prev)
        numerator = x_prev + frac * (x_u - x_prev)
        denominator = np.sqrt(2.0) * stats.norm.ppf(0.625 + 0.375 * h0)
        s_star = np.where(live, numerator / denominator, 0.0)
    return np.asarray(s_star, dtype=np.float64), h0


def _select(
    pairs: _Pairs,
    k: IntArray,
    groups: BoolArray,
    lo: FloatArray,
    j_lo: IntArray,
    c_lo: IntArray,
    hi: FloatArray,
) -> FloatArray:
    """The k-th smallest difference (1-based) of the selected groups, exactly, given
    count(<= lo) = c_lo < k <= count(<= hi).  The window (lo, hi] is narrowed until a
    group has at most ``_WINDOW`` candidates per result in it, which are then sorted.
    Each step cuts the window where the counts say the k-th difference should be
    (linear interpolation), or, after a step that did not halve the candidates, at the
    middle of the bit patterns of lo and hi (for t >= 0 they order like t, so at most
    64 such steps, whatever the spread)."""
    lo, hi, c_lo = lo.copy(), hi.copy(), c_lo.copy()
    j_lo, j_hi = j_lo.copy(), pairs.n[pairs.g].copy()
    c_hi = pairs.count(j_hi)
    act, slow = groups.copy(), np.zeros(k.size, dtype=bool)
    f_lo, f_hi = (c_lo - k).astype(np.float64), (c_hi - k).astype(np.float64)
    side = np.zeros(k.size, dtype=np.int8)  # which end the last step moved: -1 lo, +1 hi
    while True:
        # Shrink (lo, hi] onto the differences it holds (same counts): from just below
        # the smallest to the largest.  The bisection then never searches empty ranges,
        # and a window holding a single (much repeated) value is recognised at once.
        lo = np.where(act, np.nextafter(pairs.above(j_lo, act), 0.0), lo)
        hi = np.where(act, pairs.below(j_hi, act), hi)
        lo_bits, hi_bits = lo.view(np.int64), hi.view(np.int64)
        act &= (c_hi - c_lo > _WINDOW * pairs.n) & (hi_bits - lo_bits > 1)
        if not act.any():
            break
        halve = np.where(act, lo_bits + (hi_bits - lo_bits) // 2, hi_bits).view(np.float64)
        with np.errstate(invalid="ignore", divide="ignore"):
            frac = np.clip(-f_lo / (f_hi - f_lo), 1 / 64, 63 / 64)
            guess = lo + (hi - lo) * frac
        mid = np.where(slow | ~((guess > lo) & (guess < hi)), halve, guess)
        j_mid = pairs.bound(mid, act, lo=j_lo, hi=j_hi)
        c_mid = pairs.count(j_mid)
        up = act & (c_mid >= k)
        down = act & ~up
        slow = 2 * np.where(up, c_mid - c_lo, c_hi - c_mid) > c_hi - c_lo
        # Illinois rule: when the same end moves twice, halve the other end's weight,
        # so that the interpolation does not creep towards k from one side
        f_new = (c_mid - k).astype(np.float64)
        f_lo = np.where(down, f_new, np.where(up & (side == 1), f_lo / 2, f_lo))
        f_hi = np.where(up, f_new, np.where(down & (side == -1), f_hi / 2, f_hi))
        side = np.where(up, 1, np.where(down, -1, side)).astype(np.int8)
        hi, c_hi = np.where(up, mid, hi), np.where(up, c_mid, c_hi)
        lo, c_lo = np.where(down, mid, lo), np.where(down, c_mid, c_lo)
        j_hi = np.where(up[pairs.g], j_mid, j_hi)
        j_lo = np.where(down[pairs.g], j_mid, j_lo)
    # One float apart: every candidate in (lo, hi] is hi.  Otherwise sort the window.
    out = hi.copy()
    few = groups & (hi.view(np.int64) - lo.view(np.int64) > 1)
    e = np.flatnonzero(few[pairs.g])
    length = j_hi[e] - j_lo[e]
    owner = np.repeat(e, length)
    j = np.repeat(j_lo[e] - np.cumsum(length) + length, length) + np.arange(int(length.sum()))
    g = pairs.g[owner]
    d = pairs.diff(owner, j)
    order = np.lexsort((d, g))
    start = np.cumsum(np.bincount(g, minlength=pairs.n.size)) - np.bincount(
        g, minlength=pairs.n.size
    )
    sel = np.flatnonzero(few)
    out[sel] = d[order][start[sel] + (k[sel] - c_lo[sel] - 1)]
    return out


def _bracket(
    pairs: _Pairs, v: FloatArray, tol: FloatArray, groups: BoolArray, c0: IntArray
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """The two G1 nodes around the target quantile: (x, 2N G1) below and above it.

    With S = count(< anchor) + count(<= last member) (so G1 = S / 2N at a
    discontinuity), the first one whose S reaches the target 2N q is v's, v being the
    k-th smallest difference with k = ceil(2N q / 2), or the next one (v's has
    count(<= last) >= k, the next has count(< anchor) >= k)."""
    anchor, j_lt, j_le = pairs.cluster(v, tol, groups)
    lt, le = pairs.count(j_lt), pairs.count(j_le)
    s_v = lt + le
    big_n = pairs.n.astype(np.int64) * (pairs.n - 1) // 2
    reached = 2 * s_v >= big_n + 3 * c0
    # reached: the node below is the previous discontinuity, or G1(0) = 0 when only the
    # tied pairs are below
    has_prev = groups & reached & (lt > c0)
    prev_anchor, j, _ = pairs.cluster(pairs.below(j_lt, has_prev), tol, has_prev)
    s_prev = pairs.count(j) + lt
    # not reached: the node above is the next discontinuity, from the next difference
    nxt = groups & ~reached
    next_anchor = pairs.above(j_le, nxt)
    s_next = le + pairs.count(pairs.bound(next_anchor + tol, nxt))
    x_prev = np.where(reached, np.where(has_prev, prev_anchor, 0.0), anchor)
    x_u = np.where(reached, anchor, next_anchor)
    s_lo = np.where(reached, np.where(has_prev, s_prev, 0), s_v)
    s_hi = np.where(reached, s_v, s_next)
    return x_prev, s_lo.astype(np.float64), x_u, s_hi.astype(np.float64)


def hampel_location(
    rows: FloatArray, n: IntArray, centre: FloatArray, scale: FloatArray
) -> tuple[FloatArray, BoolArray]:
    """x* by the Hampel estimator (ISO 13528:2022 C.5.3.3, finite-step algorithm) of every
    sorted row, with s* = ``scale`` and the median ``centre``; also whether x* fell back
    to the median (no unique closest zero).  Rows with scale 0 get the median."""
    x = np.array(centre, dtype=np.float64)
    fallback = np.ones(n.size, dtype=bool)
    ok = np.flatnonzero(scale > 0)
    width = max(rows.shape[1], 1)
    step = max(1, _CHUNK // (6 * width))
    for start in range(0, ok.size, step):  # chunks of groups, to bound memory
        sel = ok[start : start + step]
        z = (rows[sel] - centre[sel, None]) / scale[sel, None]
        u, fb = _hampel_standardised(z)
        x[sel] = centre[sel] + scale[sel] * u
        fallback[sel] = fb
    return x, fallback


def _hampel_standardised(z: FloatArray) -> tuple[FloatArray, BoolArray]:
    """Zero of f(u) = sum psi(z_i - u) closest to 0 per row (NaN-padded, centred on the
    median, in units of s*), and whether 0 was taken because there is no unique one."""
    g, w = z.shape
    # six sorted runs z + c, one per breakpoint: a stable sort (timsort) merges them
    node_z = np.tile(z, 6)
    which = np.repeat(np.arange(6), w)
    nodes = np.where(np.isnan(node_z), np.inf, node_z + _BREAKS[which])
    order = np.argsort(nodes, axis=1, kind="stable")
    u = np.take_along_axis(nodes, order, axis=1)
    zs = np.take_along_axis(node_z, order, axis=1)
    run = which[order]
    cs = _BREAKS[run]
    valid = np.isfinite(u)
    slope = np.cumsum(np.where(valid, _SLOPES[run], 0.0), axis=1)
    with np.errstate(invalid="ignore"):
        du = np.where(valid[:, 1:], (zs[:, 1:] - zs[:, :-1]) + (cs[:, 1:] - cs[:, :-1]), 0.0)
    rise = slope[:, :-1] * du
    f = np.zeros(u.shape)
    np.cumsum(rise, axis=1, out=f[:, 1:])
    tol_f = np.maximum(1e-12, 32 * np.finfo(np.float64).eps * np.abs(rise).sum(axis=1))[:, None]
    zero = valid & (np.abs(f) <= tol_f)
    a, b = f[:, :-1], f[:, 1:]
    change = valid[:, 1:] & ~zero[:, :-1] & ~zero[:, 1:] & (np.sign(a) != np.sign(b))
    with np.errstate(invalid="ignore", divide="ignore"):
        root = u[:, :-1] + a * du / (a - b)
    # f at the median (u = 0): it is the closest zero when it vanishes there
    k = np.maximum((u <= 0).sum(axis=1) - 1, 0)
    r = np.arange(g)
    f0 = np.where(u[r, k] <= 0, f[r, k] + slope[r, k] * (0.0 - u[r, k]), 0.0)
    sols = np.concatenate(
        [np.where(zero, u, np.inf), np.where(change, root, np.inf), np.zeros((g, 1))], axis=1
    )
    sols[:, -1] = np.where(np.abs(f0) <= tol_f[:, 0], 0.0, np.inf)
    dist = np.abs(sols)
    best = np.argmin(dist, axis=1)
    x = sols[r, best]
    tol_d = 1e-10 * np.maximum(1.0, np.abs(x))  # rounding of a zero, relative to its size
    rival = (np.abs(dist - dist[r, best][:, None]) <= tol_d[:, None]) & (
        np.abs(sols - x[:, None]) > tol_d[:, None]
    )
    fallback = rival.any(axis=1) | ~np.isfinite(x)
    return np.where(fallback, 0.0, x), fallback
