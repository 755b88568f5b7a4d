"""Assigned values x_pt, u(x_pt) and σ_pt (ISO 13528:2022 §7–§8; domain spec §5).

Every method handles all measurement points (groups) at once and returns an
:class:`AssignedValues`.  Robust consensus (Algorithm A) lives in
``analysis.core.robust``.
"""

from __future__ import annotations

from itertools import combinations

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
from analysis.core.types import AssignedValues
from analysis.core.uncertainty import Distribution, absolute_from_relative, u_from_tolerance

EXHAUSTIVE_MAX = 14
"""Largest group whose subsets :func:`largest_consistent_subset` enumerates (vectorised
over groups, it beats the sweep on small groups; above about 14 results the sweep wins)."""

EXACT_MAX = 600
"""Largest group solved exactly by the sweep of :func:`largest_consistent_subset` (its work
grows as n³: about 0.1 s at 200 results, 2 s at 600). Larger inconsistent groups get the
sequential approximation and ``exhaustive = False``."""

# Upper bound on the number of float cells of one vectorised subset batch.
_BATCH_CELLS = 4_000_000


def _results(x: ArrayLike, u: ArrayLike, groups: Groups) -> tuple[FloatArray, FloatArray]:
    """Validate results: finite x, u > 0, one entry per result, no empty group."""
    xs = as_finite("x", x)
    us = as_finite("u", u, positive=True)
    if not (xs.size == us.size == groups.size):
        raise CoreInputError(
            f"x, u and groups must have one entry per result: got {xs.size}, {us.size}, "
            f"{groups.size}"
        )
    empty = np.flatnonzero(groups.counts() == 0)
    if empty.size:
        raise CoreInputError(f"group(s) {empty[:10].tolist()} have no results")
    return xs, us


def _group_array(name: str, values: ArrayLike, n: int) -> FloatArray:
    """One finite float per group: a scalar is broadcast, any other length is an error."""
    arr = np.asarray(values, dtype=np.float64)
    if arr.ndim > 1 or (arr.ndim == 1 and arr.size != n):
        raise CoreInputError(f"{name} needs a scalar or one value per group ({n}), got {arr.shape}")
    return as_finite(name, np.broadcast_to(arr, (n,)).copy())


def _weighted(
    x: FloatArray, w: FloatArray, groups: Groups, mask: BoolArray
) -> tuple[FloatArray, FloatArray, FloatArray, IntArray]:
    """Weighted mean y, (Σw)^(-1/2), Σw(x − y)² and n per group over ``mask``.

    x is shifted by each group's median over ``mask`` so that identical values give
    exactly that value and χ² suffers no cancellation, also when a group holds a result
    many orders of magnitude away from the others (shifted by that result, the others
    would round to it and vanish).
    """
    counts = groups.counts()
    everyone = bool(mask.all())
    shift = _median(x, groups, None if everyone else mask)
    idx = groups.index
    dx = x - shift[idx]
    wm = w if everyone else np.where(mask, w, 0.0)
    s1 = groups.sum(wm)
    wdx = wm * dx
    dy = groups.sum(wdx) / s1
    r = dx - dy[idx]
    r *= r
    r *= wm
    chi2 = groups.sum(r)
    n = counts if everyone else np.bincount(idx[mask], minlength=groups.n_groups)
    return shift + dy, 1.0 / np.sqrt(s1), chi2, n


def _median(x: FloatArray, groups: Groups, mask: BoolArray | None = None) -> FloatArray:
    """Median of each group (over ``mask``; 0 for a group with nothing in it)."""
    padded = groups.padded(x if mask is None else np.where(mask, x, np.nan))
    empty = np.isnan(padded).all(axis=1)
    padded[empty] = 0.0
    return np.nanmedian(padded, axis=1)


def _consistency(chi2_obs: FloatArray, n: IntArray, alpha: float) -> dict[str, np.ndarray]:
    """χ² consistency test of Cox 2002 procedure A, one entry per group.

    With a single result (dof = 0) the test is void: chi2_obs = 0,
    chi2_crit = 0, p_value = 1, consistent = True and birge_ratio = 0.
    """
    dof = n - 1
    nu = np.maximum(dof, 1)
    many = dof > 0
    chi2_obs = np.where(many, chi2_obs, 0.0)
    crit = np.where(many, stats.chi2.ppf(1.0 - alpha, nu), 0.0)
    return {
        "n": n,
        "dof": dof,
        "chi2_obs": chi2_obs,
        "chi2_crit": crit,
        "p_value": np.where(many, stats.chi2.sf(chi2_obs, nu), 1.0),
        "consistent": chi2_obs <= crit,
        "birge_ratio": np.sqrt(chi2_obs / nu),
    }


def _check_alpha(alpha: float) -> None:
    if not 0.0 < alpha < 1.0:
        raise CoreInputError(f"significance level alpha must be in (0, 1), got {alpha!r}")


def reference_value(
    x: ArrayLike,
    u: ArrayLike,
    groups: Groups,
    is_reference: ArrayLike,
    k: ArrayLike | None = None,
) -> AssignedValues:
    """Reference (pilot) laboratory value, ISO 13528:2022 7.5; domain spec §5.1.

    x_pt = the reference result, u(x_pt) = its u, and U(x_pt) its reported U: ``k`` (per
    result, the coverage factors the laboratories reported) gives the reference's own k
    (a key-comparison pilot often reports k = 2.4 or so), which the scores of the others
    then use in En (ISO 13528:2022 9.7, Formula 20, with U(x_pt) as reported).  Without
    ``k``, k = 2.  Every group needs exactly one reference result.  Diagnostics:
    ``reference_index`` (result index per group).
    """
    xs, us = _results(x, u, groups)
    ref = np.asarray(is_reference)
    if ref.dtype != np.bool_ or ref.shape != (groups.size,):
        raise CoreInputError(f"is_reference must be a boolean array of {groups.size} entries")
    count = np.bincount(groups.index[ref], minlength=groups.n_groups)
    if (count != 1).any():
        g = int(np.flatnonzero(count != 1)[0])
        what = "no reference result" if count[g] == 0 else f"{count[g]} reference results"
        raise CoreInputError(f"group {g} has {what}: mark exactly one result per group")
    where = np.flatnonzero(ref)
    position = np.empty(groups.n_groups, dtype=np.intp)
    position[groups.index[where]] = where
    coverage = None
    if k is not None:
        ks = as_finite("k", k, positive=True)
        if ks.shape != (groups.size,):
            raise CoreInputError(f"k must have one entry per result ({groups.size})")
        coverage = ks[position]
    return AssignedValues(
        value=xs[position],
        standard_uncertainty=us[position],
        method="reference",
        included=ref.copy(),
        diagnostics={"reference_index": position},
        coverage_factor=coverage,
    )


def nominal_value(
    nominal: ArrayLike,
    tolerance: ArrayLike,
    groups: Groups,
    *,
    relative: bool = False,
    distribution: Distribution = "rectangular",
    k: float = 2.0,
) -> AssignedValues:
    """Nominal (manufacturer) value with a tolerance, domain spec §5.2 (GUM 4.3.7).

    ``nominal`` and ``tolerance`` (half-width; in % of the nominal when
    ``relative``) are scalars or one per group; u(x_pt) from
    :func:`u_from_tolerance` (``k`` only for ``normal``).  No result is included.
    418 ± 1 % rectangular gives u = 2.41329.  Diagnostics: ``half_width``.
    """
    nom = _group_array("nominal", nominal, groups.n_groups)
    tol = _group_array("tolerance", tolerance, groups.n_groups)
    half = (
        absolute_from_relative(nom, tol) if relative else as_finite("tolerance", tol, positive=True)
    )
    return AssignedValues(
        value=nom,
        standard_uncertainty=u_from_tolerance(half, distribution, k),
        method="nominal",
        included=np.zeros(groups.size, dtype=np.bool_),
        diagnostics={"half_width": half},
    )


def weighted_mean(
    x: ArrayLike, u: ArrayLike, groups: Groups, alpha: float = 0.05
) -> AssignedValues:
    """Weighted mean, Cox (2002) Metrologia 39:589, procedure A; domain spec §5.3.

    y = Σ(x/u²)/Σ(1/u²), u(y) = (Σ 1/u²)^(−1/2); χ²_obs = Σ(x − y)²/u² against
    χ²_{1−α}(N − 1) (scipy), Birge ratio √(χ²_obs/(N − 1)).  Diagnostics: n,
    dof, chi2_obs, chi2_crit, p_value, consistent, birge_ratio; for a single
    result see ``_consistency`` (consistent, Birge ratio reported as 0).
    """
    _check_alpha(alpha)
    xs, us = _results(x, u, groups)
    everyone = np.ones(groups.size, dtype=np.bool_)
    y, u_y, chi2, n = _weighted(xs, 1.0 / us**2, groups, everyone)
    return AssignedValues(
        value=y,
        standard_uncertainty=u_y,
        method="weighted_mean",
        included=everyone,
        diagnostics=_consistency(chi2, n, alpha),
    )


def largest_consistent_subset(
    x: ArrayLike,
    u: ArrayLike,
    groups: Groups,
    alpha: float = 0.05,
    exhaustive_max: int | None = None,
    exact_max: int | None = None,
) -> AssignedValues:
    """Weighted mean of the largest consistent subset, Cox (2007) Metrologia 44:187.

    The subset is the *largest* set of results whose χ² (about its own weighted mean)
    passes the test, ties going to the smallest χ²_obs. It is found exactly:

    * groups of up to ``exhaustive_max`` results (default :data:`EXHAUSTIVE_MAX`): every
      subset of size N−1, N−2, … is tested until a size has a consistent subset;
    * groups of up to ``exact_max`` results (default :data:`EXACT_MAX`): the sweep of
      :func:`_sweep_row`, exact by construction (see there), in O(N³) work;
    * larger groups: the sequential approach, dropping the result with the largest
      (x_i − y)²/u_i² until consistent. It can end on a smaller subset than the largest,
      so these groups have ``exhaustive = False`` and callers must say so.

    Diagnostics as :func:`weighted_mean` for the chosen subset, plus n_excluded,
    consistent_all (the full set passed) and exhaustive (the subset is the exact one).
    """
    _check_alpha(alpha)
    exhaustive_max = EXHAUSTIVE_MAX if exhaustive_max is None else exhaustive_max
    exact_max = EXACT_MAX if exact_max is None else exact_max
    xs, us = _results(x, u, groups)
    w = 1.0 / us**2
    everyone = np.ones(groups.size, dtype=np.bool_)
    full = _consistency(_weighted(xs, w, groups, everyone)[2], groups.counts(), alpha)
    counts = groups.counts()
    shift = _median(xs, groups)  # as in _weighted: no result vanishes in the shift
    xp = groups.padded(xs - shift[groups.index], fill=0.0)
    wp = groups.padded(w, fill=0.0)
    keep = np.arange(xp.shape[1]) < counts[:, np.newaxis]
    small = counts <= exhaustive_max
    exact = counts <= max(exact_max, exhaustive_max)
    todo = ~full["consistent"]
    r = np.flatnonzero(todo & small)
    if r.size:
        keep[r] = _exhaustive(xp[r], wp[r], counts[r], alpha)
    r = np.flatnonzero(todo & ~small)
    if r.size:
        keep[r] = _sequential(xp[r], wp[r], counts[r], alpha)
        for row in r[exact[r]]:
            n_row = int(counts[row])
            keep[row, :n_row] = _sweep_row(
                xp[row, :n_row], wp[row, :n_row], int(keep[row].sum()), alpha
            )
    included = groups.unpad(keep).astype(np.bool_)
    y, u_y, chi2, n = _weighted(xs, w, groups, included)
    diagnostics = _consistency(chi2, n, alpha)
    # a group consistent as a whole is its own largest subset, whatever its size
    exhaustive = exact | full["consistent"]
    diagnostics.update(
        n_excluded=counts - n, consistent_all=full["consistent"], exhaustive=exhaustive
    )
    return AssignedValues(y, u_y, "largest_consistent_subset", included, diagnostics)


def _sweep_row(x: FloatArray, w: FloatArray, m_lb: int, alpha: float) -> BoolArray:
    """The largest consistent subset of one group, exactly, given a consistent subset of
    ``m_lb`` results (the sequential approach's): the answer has at least that many.

    Why it is exact. χ²(S) = min over y of Σ_{i∈S} f_i(y) with f_i(y) = w_i (x_i − y)².
    Let S* be the subset of size m with the smallest χ², y* its weighted mean, and T the m
    results with the smallest f_i(y*). Then χ²(T) ≤ Σ_T f_i(y*) ≤ Σ_{S*} f_i(y*) = χ²(S*),
    so T is as good as S*: for every size m the best subset is "the m smallest f_i(y)" for
    some y. That set changes only where two f_i cross, at y = (s_i x_i ± s_j x_j)/(s_i ± s_j)
    (s = √w), and a crossing of the results ranked p and p + 1 changes only the set of size
    p. So the sets of every size m ≥ m_lb are constant between consecutive crossings of
    rank ≥ m_lb, and one evaluation between each two (the m smallest, by prefix sums) meets
    every candidate; by continuity a y* on a crossing is met by a neighbouring interval.
    Only y where at least m_lb results have f_i(y) ≤ χ²_crit(N) can be the mean of a
    consistent subset of m_lb or more results, so crossings elsewhere are skipped.
    The chosen subset's χ² is then recomputed in two passes and tested.
    """
    n = x.size
    crit_all = _crit(np.arange(1, n + 1), alpha)
    slack = 1.0 + 1e-9  # generous: an extra crossing costs time, a missed one the answer
    starts, ends = _region(x, w, m_lb, float(crit_all[-1]) * slack)
    s = np.sqrt(w)
    i, j = np.triu_indices(n, 1)
    differ = s[i] != s[j]
    yc = np.concatenate(
        [
            (s[i] * x[i] + s[j] * x[j]) / (s[i] + s[j]),
            (s[i] * x[i] - s[j] * x[j])[differ] / (s[i] - s[j])[differ],
        ]
    )
    ic, jc = np.concatenate([i, i[differ]]), np.concatenate([j, j[differ]])
    inside = _in_region(yc, starts, ends)
    yc, ic, jc = yc[inside], ic[inside], jc[inside]
    level = np.maximum(w[ic] * (x[ic] - yc) ** 2, w[jc] * (x[jc] - yc) ** 2) * slack
    relevant = np.zeros(yc.size, dtype=np.bool_)
    step = max(1, _BATCH_CELLS // n)
    for a in range(0, yc.size, step):
        f = w * (x - yc[a : a + step, np.newaxis]) ** 2
        below = np.count_nonzero(f <= level[a : a + step, np.newaxis], axis=1) - 2
        relevant[a : a + step] = below >= m_lb - 1
    edges = np.unique(np.concatenate([yc[relevant], starts, ends]))
    mids = 0.5 * (edges[:-1] + edges[1:])
    mids = mids[_in_region(mids, starts, ends)]
    if mids.size == 0:
        mids = starts
    sizes = n - m_lb + 1  # m = m_lb … n
    best = np.full(sizes, np.inf)
    # the ranking that gave each size its best χ², kept as it was (not recomputed): where a
    # y lies on a crossing (ties in f), another sort could rank the tied results otherwise
    # and pick a different subset than the one whose χ² was computed
    ranked = np.zeros((sizes, n), dtype=np.intp)
    for a in range(0, mids.size, step):
        chi2, order = _prefix_chi2(x, w, mids[a : a + step], m_lb)
        arg = np.argmin(chi2, axis=0)
        low = chi2[arg, np.arange(sizes)]
        better = low < best
        best[better], ranked[better] = low[better], order[arg[better]]
    for m in range(n, m_lb - 1, -1):
        if not np.isfinite(best[m - m_lb]):
            continue
        chosen = ranked[m - m_lb, :m]
        xm, wm = x[chosen], w[chosen]
        ym = np.sum(wm * xm) / np.sum(wm)
        if m == 1 or np.sum(wm * (xm - ym) ** 2) <= crit_all[m - 1]:
            keep = np.zeros(n, dtype=np.bool_)
            keep[chosen] = True
            return keep
    raise AssertionError("the subset of m_lb results given is consistent")  # pragma: no cover


def _region(x: FloatArray, w: FloatArray, m: int, level: float) -> tuple[FloatArray, FloatArray]:
    """The y intervals (starts, ends) where at least ``m`` results have w(x − y)² ≤ level."""
    half = np.sqrt(level / w)
    at = np.concatenate([x - half, x + half])
    step = np.concatenate([np.ones(x.size, np.intp), -np.ones(x.size, np.intp)])
    order = np.lexsort((-step, at))  # an interval opening where another closes counts both
    at, count = at[order], np.cumsum(step[order])
    inside = count >= m
    before = np.concatenate([[False], inside[:-1]])
    return at[inside & ~before], at[~inside & before]


def _in_region(y: FloatArray, starts: FloatArray, ends: FloatArray) -> BoolArray:
    k = np.searchsorted(starts, y, side="right") - 1
    return (k >= 0) & (y <= ends[np.maximum(k, 0)])


def _prefix_chi2(
    x: FloatArray, w: FloatArray, y: FloatArray, m_lb: int
) -> tuple[FloatArray, IntArray]:
    """χ² of the m results with the smallest w(x − y)², for each y (rows) and each
    m = m_lb … n (columns), from prefix sums about y; and the ranking used, per y (its
    first m entries are the subset of size m)."""
    n = x.size
    d = x[np.newaxis, :] - y[:, np.newaxis]
    f = w * d * d
    rows = np.arange(y.size)[:, np.newaxis]
    order = np.argpartition(f, m_lb - 1, axis=1) if m_lb < n else np.tile(np.arange(n), (y.size, 1))
    head, tail = order[:, :m_lb], order[:, m_lb:]
    tail = np.take_along_axis(tail, np.argsort(f[rows, tail], axis=1), axis=1)
    wh, dh = w[head], d[rows, head]
    wt, dt = w[tail], d[rows, tail]
    s0 = _cumulative(wh.sum(axis=1), wt)
    s1 = _cumulative((wh * dh).sum(axis=1), wt * dt)
    s2 = _cumulative((wh * dh * dh).sum(axis=1), wt * dt * dt)
    return np.maximum(s2 - s1 * s1 / s0, 0.0), np.concatenate([head, tail], axis=1)


def _cumulative(head: FloatArray, tail: FloatArray) -> FloatArray:
    """[head, head + t_1, head + t_1 + t_2, …] per row."""
    return head[:, np.newaxis] + np.concatenate(
        [np.zeros((tail.shape[0], 1)), np.cumsum(tail, axis=1)], axis=1
    )


def _crit(m: IntArray, alpha: float) -> FloatArray:
    """χ²_{1−α}(m − 1) for subsets of m results (0 where m = 1: always consistent)."""
    return np.where(m > 1, stats.chi2.ppf(1.0 - alpha, np.maximum(m - 1, 1)), 0.0)


def _exhaustive(xp: FloatArray, wp: FloatArray, n: IntArray, alpha: float) -> BoolArray:
    """Cox 2007 search on padded rows (inconsistent groups): remove r = 1, 2, …
    results, all C(n, r) choices at once, until a consistent subset exists."""
    valid = np.arange(xp.shape[1]) < n[:, np.newaxis]
    keep = valid.copy()
    open_ = np.ones(n.size, dtype=np.bool_)
    for r in range(1, int(n.max())):
        rows = np.flatnonzero(open_ & (n > r))
        width = int(n[rows].max())
        removed = np.array(list(combinations(range(width), r)), dtype=np.intp)
        best = _best_removal(xp[rows, :width], wp[rows, :width], n[rows], removed, alpha)
        found = best >= 0
        hit = rows[found]
        keep[hit[:, np.newaxis], removed[best[found]]] = False
        open_[hit] = False
        if not open_.any():
            break
    return keep


def _best_removal(
    xp: FloatArray, wp: FloatArray, n: IntArray, removed: IntArray, alpha: float
) -> IntArray:
    """Index into ``removed`` of the consistent removal with the smallest χ²
    per row, or −1; evaluated in batches of combinations to bound memory."""
    rows, width = xp.shape
    crit = _crit(n - removed.shape[1], alpha)
    best_chi2 = np.full(rows, np.inf)
    best = np.full(rows, -1, dtype=np.intp)
    step = max(1, _BATCH_CELLS // (rows * width))
    for start in range(0, removed.shape[0], step):
        combo = removed[start : start + step]
        kept = np.ones((combo.shape[0], width), dtype=np.bool_)
        kept[np.arange(combo.shape[0])[:, np.newaxis], combo] = False
        w = np.where(kept[:, np.newaxis, :], wp[np.newaxis], 0.0)  # combos × rows × width
        y = np.sum(w * xp, axis=2) / np.sum(w, axis=2)
        chi2 = np.sum(w * (xp - y[..., np.newaxis]) ** 2, axis=2)
        # one kept result is consistent by definition, whatever rounding leaves in χ²
        ok = (combo.max(axis=1)[:, np.newaxis] < n) & ((chi2 <= crit) | (crit == 0))
        chi2 = np.where(ok, chi2, np.inf)
        arg = np.argmin(chi2, axis=0)
        low = chi2[arg, np.arange(rows)]
        better = low < best_chi2
        best_chi2[better] = low[better]
        best[better] = start + arg[better]
    return best


def _sequential(xp: FloatArray, wp: FloatArray, n: IntArray, alpha: float) -> BoolArray:
    """Drop, one at a time, the result with the largest (x_i − y)²/u_i² from every
    still-inconsistent row (the sequential form of Cox 2007 for large N)."""
    keep = np.arange(xp.shape[1]) < n[:, np.newaxis]
    for _ in range(xp.shape[1]):
        w = np.where(keep, wp, 0.0)
        y = np.sum(w * xp, axis=1) / np.sum(w, axis=1)
        contribution = w * (xp - y[:, np.newaxis]) ** 2
        crit = _crit(keep.sum(axis=1), alpha)
        bad = (np.sum(contribution, axis=1) > crit) & (crit > 0)
        if not bad.any():
            break
        worst = np.argmax(np.where(keep, contribution, -1.0), axis=1)
        keep[np.flatnonzero(bad), worst[bad]] = False
    return keep


def _dl_scale(w: FloatArray, groups: Groups) -> FloatArray:
    """S1 − S2/S1 per group without its cancellation: Σ w_i·o_i / S1, o_i the sum of the
    weights other than w_i, the largest weight's o summed from the others.  Taken as
    S1 − w_max it is 0 when that weight dwarfs the rest (a U of 1e-29 beside U of 0.5
    gave 0, τ² = ∞ and a NaN consensus); every other o is at least w_max, so S1 − w_i
    is exact enough."""
    idx = groups.index
    largest = np.zeros(groups.n_groups)
    np.maximum.at(largest, idx, w)  # weights are > 0; an empty group keeps 0
    candidates = np.flatnonzero(w == largest[idx])
    _, first = np.unique(idx[candidates], return_index=True)
    top = np.zeros(w.size, dtype=np.bool_)
    top[candidates[first]] = True  # one largest weight per group
    rest = groups.sum(np.where(top, 0.0, w))  # summed in result order, as groups.sum does
    s1 = largest + rest
    others = np.where(top, rest[idx], s1[idx] - w)
    with np.errstate(invalid="ignore", divide="ignore"):  # an empty group: not used
        return groups.sum(w * others) / s1


def dersimonian_laird(x: ArrayLike, u: ArrayLike, groups: Groups) -> AssignedValues:
    """Random-effects mean, DerSimonian & Laird (1986) as in the NIST Consensus Builder.

    Weights w = 1/u², Q = Σw(x − ȳ_w)², τ² = max(0, (Q − (N−1)) / (S1 − S2/S1)),
    then μ = Σw*x/Σw* with w* = 1/(u² + τ²), u(μ) = (Σw*)^(−1/2).  A single
    result gives τ = 0.  Diagnostics: tau ("dark uncertainty"), tau2, q, n.
    """
    xs, us = _results(x, u, groups)
    w = 1.0 / us**2
    everyone = np.ones(groups.size, dtype=np.bool_)
    _, _, q, n = _weighted(xs, w, groups, everyone)
    denom = np.where(n > 1, _dl_scale(w, groups), 1.0)
    tau2 = np.where(n > 1, np.maximum(0.0, (q - (n - 1)) / denom), 0.0)
    mu, u_mu, _, _ = _weighted(xs, 1.0 / (us**2 + tau2[groups.index]), groups, everyone)
    return AssignedValues(
        value=mu,
        standard_uncertainty=u_mu,
        method="dersimonian_laird",
        included=everyone,
        diagnostics={"tau": np.sqrt(tau2), "tau2": tau2, "q": q, "n": n},
    )


def sigma_pt_prescribed(
    value: ArrayLike, n_groups: int, *, x_pt: ArrayLike | None = None, relative: bool = False
) -> FloatArray:
    """σ_pt by fitness for purpose, ISO 13528:2022 8.2: absolute, or (``relative``)
    ``value`` percent of |x_pt|.  Scalars broadcast to ``n_groups``."""
    sigma = as_finite("sigma_pt", _group_array("sigma_pt", value, n_groups), positive=True)
    if not relative:
        return sigma
    if x_pt is None:
        raise CoreInputError("a relative sigma_pt needs x_pt")
    return absolute_from_relative(_group_array("x_pt", x_pt, n_groups), sigma)


def sigma_pt_given(value: ArrayLike, n_groups: int) -> FloatArray:
    """σ_pt given by the coordinator, e.g. from previous rounds (ISO 13528:2022 8.3):
    validated (finite, > 0) and broadcast to ``n_groups``."""
    return as_finite("sigma_pt", _group_array("sigma_pt", value, n_groups), positive=True)
