"""Consistency tools for the coordinator (ISO 5725-2:2019 §7.2-7.3) and artefact stability.

Mandel's h and k, Grubbs' single and double tests and Cochran's C, each for many
measurement points (groups) at once, with critical values at 5 % (straggler) and
1 % (outlier).  Also the stability check of docs/domain.md §7 and the combination of
the components of u(x_pt).

Where a test cannot be run (too few laboratories or results) the result carries
``tested`` False, the critical value is +inf (or -inf for the lower-tailed double
Grubbs test) and the code is 0: nothing is flagged silently and no NaN leaks out.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike
from scipy import special  # t and F quantiles (what scipy.stats calls), without its 0.5 s import

from analysis.core.groups import (
    BoolArray,
    CoreInputError,
    FloatArray,
    Groups,
    IntArray,
    as_finite,
)

OK, STRAGGLER, OUTLIER = 0, 1, 2

# ISO 5725-2:2019 Table 5, Grubbs' test for the two largest or two smallest
# observations: lower critical values at 1 % and 5 % for p = 4 .. 40.  The
# distribution of the statistic has no closed form (Grubbs 1950 gives it as
# nested integrals), hence the table; p outside 4..40 is not tested.
# Re-checked against a Monte Carlo simulation (10^6 samples) in the tests.
_DOUBLE_P0 = 4
_DOUBLE_1 = np.array([
    0.0000, 0.0018, 0.0116, 0.0308, 0.0563, 0.0851, 0.1150, 0.1448, 0.1738, 0.2016,
    0.2280, 0.2530, 0.2767, 0.2990, 0.3200, 0.3398, 0.3585, 0.3761, 0.3927, 0.4085,
    0.4234, 0.4376, 0.4510, 0.4638, 0.4759, 0.4875, 0.4985, 0.5091, 0.5192, 0.5288,
    0.5381, 0.5469, 0.5554, 0.5636, 0.5714, 0.5789, 0.5862,
])  # fmt: skip
_DOUBLE_5 = np.array([
    0.0002, 0.0090, 0.0349, 0.0708, 0.1101, 0.1492, 0.1864, 0.2213, 0.2537, 0.2836,
    0.3112, 0.3367, 0.3603, 0.3822, 0.4025, 0.4214, 0.4391, 0.4556, 0.4711, 0.4857,
    0.4994, 0.5123, 0.5245, 0.5360, 0.5470, 0.5574, 0.5672, 0.5766, 0.5856, 0.5941,
    0.6023, 0.6101, 0.6175, 0.6247, 0.6316, 0.6382, 0.6445,
])  # fmt: skip


def classify(
    statistic: ArrayLike, critical_5: ArrayLike, critical_1: ArrayLike, *, lower: bool = False
) -> IntArray:
    """ISO 5725-2 §7.3.2 codes: 0 correct, 1 straggler (beyond the 5 % but not the 1 %
    critical value), 2 outlier (beyond the 1 % critical value).  ``lower`` for tests
    that reject small values (double Grubbs)."""
    s, c5, c1 = (np.asarray(v, dtype=np.float64) for v in (statistic, critical_5, critical_1))
    if lower:
        s, c5, c1 = -s, -c5, -c1
    return np.where(s > c1, OUTLIER, np.where(s > c5, STRAGGLER, OK)).astype(np.intp)


def _p_array(name: str, p: ArrayLike, minimum: int) -> FloatArray:
    arr = np.asarray(p, dtype=np.float64)
    if not np.all(arr >= minimum) or not np.all(arr == np.round(arr)):
        raise CoreInputError(f"{name} must be integers >= {minimum}")
    return arr


def _check_alpha(alpha: float) -> None:
    if not 0 < alpha < 1:
        raise CoreInputError(f"alpha must lie in (0, 1), got {alpha!r}")


def mandel_h_critical(p: ArrayLike, alpha: float) -> FloatArray:
    """Critical h for p laboratories, ISO 5725-2 §7.3.2 (Table 6 formula):
    h = (p - 1) t / sqrt(p (t^2 + p - 2)), t two-sided at alpha with p - 2 df."""
    _check_alpha(alpha)
    pp = _p_array("p", p, 3)
    t = special.stdtrit(pp - 2, 1 - alpha / 2)
    return np.asarray((pp - 1) * t / np.sqrt(pp * (t * t + pp - 2)), dtype=np.float64)


def mandel_k_critical(p: ArrayLike, n: ArrayLike, alpha: float) -> FloatArray:
    """Critical k for p laboratories with n replicates, ISO 5725-2 §7.3.2 (Table 6 formula):
    k = sqrt(p / (1 + (p - 1)/F)), F upper alpha with nu1 = n - 1, nu2 = (p - 1)(n - 1)."""
    _check_alpha(alpha)
    pp, nn = _p_array("p", p, 2), _p_array("n", n, 2)
    f = special.fdtri(nn - 1, (pp - 1) * (nn - 1), 1 - alpha)
    return np.asarray(np.sqrt(pp / (1 + (pp - 1) / f)), dtype=np.float64)


def grubbs_critical(p: ArrayLike, alpha: float) -> FloatArray:
    """Critical value of Grubbs' single-outlier test, ISO 5725-2 §7.3.4 (Table 5), from
    the t distribution (two-sided, alpha/(2p) in each tail, as pt13528):
    G = (p - 1)/sqrt(p) sqrt(t^2 / (p - 2 + t^2)), t with p - 2 df."""
    _check_alpha(alpha)
    pp = _p_array("p", p, 3)
    t = special.stdtrit(pp - 2, 1 - alpha / (2 * pp))
    return np.asarray((pp - 1) / np.sqrt(pp) * np.sqrt(t * t / (pp - 2 + t * t)), np.float64)


def grubbs_double_critical(p: ArrayLike, alpha: float) -> FloatArray:
    """Lower critical value of Grubbs' double test, ISO 5725-2 §7.3.4 Table 5 (tabulated,
    no closed form; alpha 0.05 or 0.01, 4 <= p <= 40).  The tabulated 5 % and 1 % apply
    to the two-sided use (two largest or two smallest), i.e. each tail at alpha/2."""
    pp = _p_array("p", p, _DOUBLE_P0).astype(np.intp)
    if np.any(pp > _DOUBLE_P0 + _DOUBLE_1.size - 1):
        raise CoreInputError("ISO 5725-2 Table 5 gives double Grubbs values for p <= 40 only")
    table = {0.05: _DOUBLE_5, 0.01: _DOUBLE_1}.get(alpha)
    if table is None:
        raise CoreInputError("double Grubbs critical values exist for alpha 0.05 and 0.01 only")
    return np.asarray(table[pp - _DOUBLE_P0], dtype=np.float64)


def cochran_critical(p: ArrayLike, n: ArrayLike, alpha: float) -> FloatArray:
    """Critical C for p variances from n results each, ISO 5725-2 §7.2.3 (Table 4), from
    the F distribution: C = F/(F + p - 1), F upper alpha/p, nu1 = n - 1,
    nu2 = (p - 1)(n - 1) (exact when C > 1/2, as for all tabulated values)."""
    _check_alpha(alpha)
    pp, nn = _p_array("p", p, 2), _p_array("n", n, 2)
    f = special.fdtri(nn - 1, (pp - 1) * (nn - 1), 1 - alpha / pp)
    return np.asarray(f / (f + pp - 1), dtype=np.float64)


@dataclass(frozen=True)
class Cells:
    """Cell statistics (one laboratory at one measurement point), ISO 5725-2 §7.1.

    ``sd`` is the within-cell standard deviation (ddof = 1), 0 where n = 1."""

    group: IntArray
    lab: IntArray
    n: IntArray
    mean: FloatArray
    sd: FloatArray
    n_groups: int

    @property
    def groups(self) -> Groups:
        return Groups.from_index(self.group, self.n_groups)


def cell_statistics(x: ArrayLike, lab: ArrayLike, groups: Groups) -> Cells:
    """Cell means and standard deviations from replicate results (flat arrays)."""
    v = as_finite("x", x)
    labs = np.asarray(lab, dtype=np.intp).reshape(-1)
    if v.size != groups.size or labs.size != groups.size:
        raise CoreInputError(f"x, lab and groups must have the same length ({groups.size})")
    if labs.size and labs.min() < 0:
        raise CoreInputError("lab index must be >= 0")
    empty = np.flatnonzero(groups.counts() == 0)
    if empty.size:
        raise CoreInputError(f"group(s) {empty[:10].tolist()} have no results")
    n_labs = int(labs.max()) + 1 if labs.size else 1
    ids, cell = np.unique(groups.index * n_labs + labs, return_inverse=True)
    cg = Groups.from_index(cell.reshape(-1), ids.size)
    n = cg.counts()
    mean = cg.mean(v)
    ss = cg.sum((v - mean[cg.index]) ** 2)
    sd = np.sqrt(ss / np.maximum(n - 1, 1))
    return Cells(ids // n_labs, ids % n_labs, n, mean, sd, groups.n_groups)


def cells_from_summaries(
    mean: ArrayLike, sd: ArrayLike, n: ArrayLike, lab: ArrayLike, groups: Groups
) -> Cells:
    """Cells given by their summaries, ISO 5725-2 §7.1: one entry per laboratory and group
    with the cell mean, the within-cell standard deviation (ddof = 1) and the number of
    replicates behind them; ``n`` = 1 with ``sd`` = 0 where a laboratory reports its mean
    only.  (A results table carries a laboratory's mean with its repeatability, not its
    replicates.)"""
    m, s = as_finite("mean", mean), as_finite("sd", sd)
    nn = np.asarray(n, dtype=np.float64).reshape(-1)
    labs = np.asarray(lab, dtype=np.intp).reshape(-1)
    if not m.size == s.size == nn.size == labs.size == groups.size:
        raise CoreInputError(f"mean, sd, n, lab and groups must have the same length ({m.size})")
    if np.any(s < 0) or not np.all((nn >= 1) & (nn == np.round(nn))):
        raise CoreInputError("sd must be >= 0 and n integers >= 1")
    if np.any((nn == 1) & (s != 0)):
        raise CoreInputError("a cell of one replicate has no standard deviation (sd must be 0)")
    if labs.size and labs.min() < 0:
        raise CoreInputError("lab index must be >= 0")
    empty = np.flatnonzero(groups.counts() == 0)
    if empty.size:
        raise CoreInputError(f"group(s) {empty[:10].tolist()} have no results")
    key = np.sort(groups.index * (int(labs.max()) + 1 if labs.size else 1) + labs)
    if np.any(key[1:] == key[:-1]):
        raise CoreInputError("each laboratory may have one cell per group")
    return Cells(groups.index, labs, nn.astype(np.intp), m, s, groups.n_groups)


def _cell_mode(cells: Cells, mask: BoolArray) -> IntArray:
    """Per group, the cell size that occurs most often among ``mask`` cells (smallest on a
    tie): the n used for the critical values of k and C with unbalanced cells."""
    out = np.zeros(cells.n_groups, dtype=np.intp)
    if not np.any(mask):
        return out
    # distinct (group, n) pairs with their counts, not a table of every n up to the
    # largest: n may be a laboratory's 10⁹ repeats
    pairs, counts = np.unique(
        np.stack([cells.group[mask], cells.n[mask]], axis=1), axis=0, return_counts=True
    )
    order = np.lexsort((pairs[:, 1], -counts, pairs[:, 0]))  # per group: most, then smallest
    ranked = pairs[order]
    first = np.r_[True, ranked[1:, 0] != ranked[:-1, 0]]
    out[ranked[first, 0]] = ranked[first, 1]
    return out


@dataclass(frozen=True)
class Mandel:
    """Mandel's h and k per cell, with per-group critical values (ISO 5725-2 §7.3.2).

    Cell arrays: ``group``, ``lab``, ``h``, ``k``, ``h_code``, ``k_code``,
    ``k_tested`` (n >= 2).  Group arrays: ``p`` (labs), ``n`` (replicates used for the
    k critical value), ``h_critical_5/1``, ``k_critical_5/1``, ``h_tested`` (p >= 3),
    ``k_tested_group`` (>= 2 cells with n >= 2), ``degenerate_h`` / ``degenerate_k``
    (all cell means / all sds identical: h or k set to 0)."""

    group: IntArray
    lab: IntArray
    h: FloatArray
    k: FloatArray
    h_code: IntArray
    k_code: IntArray
    k_tested: BoolArray
    p: IntArray
    n: IntArray
    h_critical_5: FloatArray
    h_critical_1: FloatArray
    k_critical_5: FloatArray
    k_critical_1: FloatArray
    h_tested: BoolArray
    k_tested_group: BoolArray
    degenerate_h: BoolArray
    degenerate_k: BoolArray


def _critical_or_inf(
    ok: BoolArray, fn: Callable[..., FloatArray], *args: ArrayLike, fill: float = np.inf
) -> FloatArray:
    """Critical values where the test applies (``ok``), ``fill`` (never rejects) elsewhere."""
    out = np.full(ok.shape, fill)
    if ok.any():
        picked = [np.asarray(a)[ok] if np.ndim(a) else a for a in args]
        out[ok] = fn(*picked)
    return out


def _mandel_h(cells: Cells) -> tuple[FloatArray, IntArray, BoolArray]:
    g = cells.groups
    p = g.counts()
    grand = g.mean(cells.mean)
    dev = cells.mean - grand[cells.group]
    s = np.sqrt(g.sum(dev * dev) / np.maximum(p - 1, 1))
    flat = s == 0
    h = np.where(flat[cells.group], 0.0, dev / np.where(flat, 1.0, s)[cells.group])
    return h, p, flat & (p > 1)


def _mandel_k(cells: Cells) -> tuple[FloatArray, BoolArray, IntArray, BoolArray]:
    tested = cells.n >= 2
    g = cells.groups
    p_k = np.bincount(cells.group[tested], minlength=cells.n_groups)
    var = np.where(tested, cells.sd**2, 0.0)
    mean_var = g.sum(var) / np.maximum(p_k, 1)
    flat = mean_var == 0
    k = np.where(
        tested & ~flat[cells.group],
        cells.sd / np.sqrt(np.where(flat, 1.0, mean_var))[cells.group],
        0.0,
    )
    return k, tested, p_k, flat & (p_k > 0)


def mandel(x: ArrayLike, lab: ArrayLike, groups: Groups) -> Mandel:
    """Mandel's between-laboratory h and within-laboratory k statistics, ISO 5725-2 §7.3.2.

    h_i = (ybar_i - ybar) / s(ybar_i) over the p cell means of a group; k_i = s_i sqrt(p)/
    sqrt(sum s_j^2) over the cells with n >= 2.  Codes compare |h| and k with the
    critical values of :func:`mandel_h_critical` / :func:`mandel_k_critical`."""
    return mandel_cells(cell_statistics(x, lab, groups))


def mandel_cells(cells: Cells) -> Mandel:
    """:func:`mandel` from cell statistics (:func:`cell_statistics` or
    :func:`cells_from_summaries`), ISO 5725-2 §7.3.2."""
    h, p, deg_h = _mandel_h(cells)
    k, k_cell, p_k, deg_k = _mandel_k(cells)
    n = _cell_mode(cells, k_cell)
    h_ok, k_ok = p >= 3, (p_k >= 2) & (n >= 2)
    hc5, hc1 = (_critical_or_inf(h_ok, mandel_h_critical, p, a) for a in (0.05, 0.01))
    kc5, kc1 = (_critical_or_inf(k_ok, mandel_k_critical, p_k, n, a) for a in (0.05, 0.01))
    gi = cells.group
    k_code = np.where(k_cell, classify(k, kc5[gi], kc1[gi]), OK)
    return Mandel(
        cells.group,
        cells.lab,
        h,
        k,
        classify(np.abs(h), hc5[gi], hc1[gi]),
        k_code,
        k_cell,
        p,
        n,
        hc5,
        hc1,
        kc5,
        kc1,
        h_ok,
        k_ok,
        deg_h,
        deg_k,
    )


@dataclass(frozen=True)
class Grubbs:
    """Grubbs' tests per group, ISO 5725-2 §7.3.4.

    ``g_high`` / ``g_low``: single statistics (x_max - mean)/s and (mean - x_min)/s;
    ``g_high2`` / ``g_low2``: double statistics s^2_{p-1,p}/s_0^2 (two largest) and
    s^2_{1,2}/s_0^2 (two smallest), small values reject.  Codes per statistic
    (``code_high`` ...); ``single_tested`` (p >= 3), ``double_tested`` (4 <= p <= 40);
    ``degenerate``: all values identical (statistics set to 0, resp. 1)."""

    n: IntArray
    g_high: FloatArray
    g_low: FloatArray
    g_high2: FloatArray
    g_low2: FloatArray
    single_critical_5: FloatArray
    single_critical_1: FloatArray
    double_critical_5: FloatArray
    double_critical_1: FloatArray
    code_high: IntArray
    code_low: IntArray
    code_high2: IntArray
    code_low2: IntArray
    single_tested: BoolArray
    double_tested: BoolArray
    degenerate: BoolArray


def _sorted_rows(x: ArrayLike, groups: Groups) -> tuple[FloatArray, IntArray, IntArray]:
    v = as_finite("x", x)
    if v.size != groups.size:
        raise CoreInputError(f"x has {v.size} values but the groups cover {groups.size}")
    n = groups.counts()
    empty = np.flatnonzero(n == 0)
    if empty.size:
        raise CoreInputError(f"group(s) {empty[:10].tolist()} have no results")
    rows = np.sort(groups.padded(v), axis=1)
    cols = np.arange(rows.shape[1])[None, :]
    return rows, n, cols


def _masked_ss(rows: FloatArray, mask: BoolArray) -> FloatArray:
    """Sum of squared deviations from their mean of the masked values of each row."""
    m = np.maximum(mask.sum(axis=1), 1)
    vals = np.where(mask, rows, 0.0)
    mean = vals.sum(axis=1) / m
    return np.asarray(np.where(mask, (rows - mean[:, None]) ** 2, 0.0).sum(axis=1), np.float64)


def grubbs(x: ArrayLike, groups: Groups) -> Grubbs:
    """Grubbs' single and double outlier tests per group, ISO 5725-2 §7.3.4, on one value
    per laboratory (normally the cell means of :func:`cell_statistics`)."""
    rows, n, cols = _sorted_rows(x, groups)
    r = np.arange(n.size)
    valid = cols < n[:, None]
    ss0 = _masked_ss(rows, valid)
    # all values equal: the rounded mean may leave a tiny ss0, so test the range too
    flat = (ss0 == 0) | (rows[r, n - 1] == rows[r, 0])
    s = np.sqrt(ss0 / np.maximum(n - 1, 1))
    safe_s, safe_ss0 = np.where(flat, 1.0, s), np.where(flat, 1.0, ss0)
    mean = np.where(valid, rows, 0.0).sum(axis=1) / n
    g_high = np.where(flat, 0.0, (rows[r, n - 1] - mean) / safe_s)
    g_low = np.where(flat, 0.0, (mean - rows[r, 0]) / safe_s)
    high2 = np.where(flat, 1.0, _masked_ss(rows, cols < (n - 2)[:, None]) / safe_ss0)
    low2 = np.where(flat, 1.0, _masked_ss(rows, valid & (cols >= 2)) / safe_ss0)
    single, double = n >= 3, (n >= 4) & (n <= 40)
    s5, s1 = (_critical_or_inf(single, grubbs_critical, n, a) for a in (0.05, 0.01))
    d5, d1 = (
        _critical_or_inf(double, grubbs_double_critical, n, a, fill=-np.inf) for a in (0.05, 0.01)
    )
    return Grubbs(
        n,
        g_high,
        g_low,
        high2,
        low2,
        s5,
        s1,
        d5,
        d1,
        classify(g_high, s5, s1),
        classify(g_low, s5, s1),
        classify(high2, d5, d1, lower=True),
        classify(low2, d5, d1, lower=True),
        single,
        double,
        flat,
    )


@dataclass(frozen=True)
class Cochran:
    """Cochran's C per group, ISO 5725-2 §7.2.3: ``c`` = s_max^2 / sum s_i^2 over the cells
    with n >= 2, ``lab`` the laboratory with the largest variance (-1 if none), ``p``
    cells, ``n`` replicates used for the critical value (most frequent cell size),
    ``tested`` (p >= 2 and not all variances 0), ``code``."""

    c: FloatArray
    lab: IntArray
    p: IntArray
    n: IntArray
    critical_5: FloatArray
    critical_1: FloatArray
    code: IntArray
    tested: BoolArray


def cochran(x: ArrayLike, lab: ArrayLike, groups: Groups) -> Cochran:
    """Cochran's test for the largest within-laboratory variance, ISO 5725-2 §7.2.3, per
    measurement point, from replicate results (flat ``x``, laboratory and group index).
    With unbalanced cells the standard's rule of thumb is followed: n = the cell size
    occurring most often."""
    return cochran_cells(cell_statistics(x, lab, groups))


def cochran_cells(cells: Cells) -> Cochran:
    """:func:`cochran` from cell statistics (:func:`cell_statistics` or
    :func:`cells_from_summaries`), ISO 5725-2 §7.2.3."""
    used = cells.n >= 2
    g = cells.groups
    var = np.where(used, cells.sd**2, -1.0)
    padded = g.padded(var, fill=-1.0)
    j = np.argmax(padded, axis=1)
    r = np.arange(cells.n_groups)
    vmax = np.maximum(padded[r, j], 0.0)
    total = g.sum(np.where(used, var, 0.0))
    p = np.bincount(cells.group[used], minlength=cells.n_groups)
    n = _cell_mode(cells, used)
    tested = (p >= 2) & (total > 0)
    c = np.where(tested, vmax / np.where(total > 0, total, 1.0), 0.0)
    c5, c1 = (_critical_or_inf(tested, cochran_critical, p, n, a) for a in (0.05, 0.01))
    best = g.padded(cells.lab.astype(np.float64), fill=-1.0)[r, j].astype(np.intp)
    return Cochran(c, np.where(vmax > 0, best, -1), p, n, c5, c1, classify(c, c5, c1), tested)


@dataclass(frozen=True)
class Stability:
    """Artefact stability per measurement point (docs/domain.md §7): drift ``delta`` = ybar_after
    - ybar_before, ``en`` = |delta| / sqrt(U_before^2 + U_after^2), ``stable`` and the
    uncertainty contribution ``u_stab`` (|delta|/sqrt(3) where unstable, else 0)."""

    delta: FloatArray
    en: FloatArray
    stable: BoolArray
    u_stab: FloatArray


def _point_means(
    name: str, y: ArrayLike, u: ArrayLike, groups: Groups | None
) -> tuple[FloatArray, FloatArray]:
    yy, uu = as_finite(name, y), as_finite(f"u_{name}", u, positive=True)
    if yy.size != uu.size:
        raise CoreInputError(f"{name} and u_{name} must have the same length")
    if groups is None:
        return yy, uu
    if groups.size != yy.size or np.any(groups.counts() == 0):
        raise CoreInputError(f"groups must cover {name} and every point needs a result")
    return groups.mean(yy), np.sqrt(groups.mean(uu * uu))


def stability_check(
    before: ArrayLike,
    u_before: ArrayLike,
    after: ArrayLike,
    u_after: ArrayLike,
    sigma_pt: ArrayLike,
    groups: Groups | tuple[Groups, Groups] | None = None,
    *,
    k: float = 2.0,
) -> Stability:
    """Stability of the travelling artefact, docs/domain.md §7 (ISO 13528:2022 Annex B.5 idea).

    Without ``groups`` every array has one entry per measurement point.  With ``groups``
    (one shared, or a (before, after) pair) ``before``/``after`` are the pilot's
    repeated results, averaged per point; u of a mean is the root mean square of the
    individual u (the pilot's uncertainty is dominated by components common to its
    repeats, so it is not divided by sqrt(n)).  Stable when |delta| <= 0.3 sigma_pt or
    En <= 1 with U = k u; otherwise u_stab = |delta| / sqrt(3) (rectangular drift)."""
    g_b, g_a = groups if isinstance(groups, tuple) else (groups, groups)
    yb, ub = _point_means("before", before, u_before, g_b)
    ya, ua = _point_means("after", after, u_after, g_a)
    sig = as_finite("sigma_pt", sigma_pt, positive=True)
    if not (yb.size == ya.size and sig.size in (1, yb.size)):
        raise CoreInputError("before, after and sigma_pt must cover the same measurement points")
    if not k > 0:
        raise CoreInputError("coverage factor k must be > 0")
    delta = ya - yb
    en = np.abs(delta) / (k * np.sqrt(ub * ub + ua * ua))
    stable = (np.abs(delta) <= 0.3 * sig) | (en <= 1)
    return Stability(delta, en, stable, np.where(stable, 0.0, np.abs(delta) / np.sqrt(3)))


def combine_assigned_uncertainty(
    u_char: ArrayLike, u_hom: ArrayLike = 0.0, u_stab: ArrayLike = 0.0
) -> FloatArray:
    """u(x_pt) = sqrt(u_char^2 + u_hom^2 + u_stab^2), ISO 13528:2022 §7.2.2 / docs/domain.md §5."""
    parts = [np.asarray(v, dtype=np.float64) for v in (u_char, u_hom, u_stab)]
    for name, v in zip(("u_char", "u_hom", "u_stab"), parts, strict=True):
        bad = ~np.isfinite(v) | (v < 0)
        if bad.any():
            raise CoreInputError(f"{name} must be finite and >= 0 ({int(bad.sum())} bad value(s))")
    return np.asarray(np.sqrt(parts[0] ** 2 + parts[1] ** 2 + parts[2] ** 2), dtype=np.float64)
