"""Degrees of equivalence and compatibility matrices (docs/domain.md §6).

Pairwise normalised error between two results (ISO 13528:2022 §9.7,
Formula (20), applied lab against lab as in its 10.7.1; Chiominto et al.,
Micromachines 15:727, 2024, Table 2):

    En_ij = |x_i − x_j| / √(U_i² + U_j²)      compatible when En_ij ≤ 1

A compatibility matrix compares the levels of one factor (lab, axis,
frequency, device, bench, direction) within groups given by other label
columns; each level is first aggregated by the rule of docs/domain.md §3
(:func:`analysis.core.aggregate.aggregate`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from analysis.core.aggregate import Aggregate, aggregate, check_coverage_factor
from analysis.core.groups import BoolArray, CoreInputError, FloatArray, Groups, IntArray, as_finite
from analysis.core.phase import wrap
from common.points import POINT_FIELDS
from common.quantities import CIRCULAR

#: Above this many cells (groups × width²) the batch form works block by block
#: instead of on one padded 3-D array (8 bytes a cell: 2**24 cells = 128 MiB).
PADDED_CELL_LIMIT = 2**24
# Cells of one row band of pairwise_en (32768 × 8 B = 256 KiB: fits in L2 cache).
_BAND_CELLS = 2**15
# u_i² − u_pt² below this fraction of u_i² counts as "not positive" (sole contributor).
_COX_RTOL = 1e-9

LABEL_COLUMNS = ("lab", *POINT_FIELDS)
#: Factor name -> label column (``frequency`` reads ``frequency_hz``); ``quantity`` is a
#: by-key only (a magnitude and a phase are never compared with each other).
FACTORS = {c.removesuffix("_hz"): c for c in LABEL_COLUMNS}
QUANTITY = "quantity"


def pairwise_en(
    x: ArrayLike, U: ArrayLike, *, out: FloatArray | None = None, circular: bool = False
) -> FloatArray:
    """Square matrix En_ij = |x_i − x_j| / √(U_i² + U_j²) for one set of results.

    ``U`` are expanded uncertainties (> 0).  The matrix is exactly symmetric
    with a zero diagonal.  ``circular``: the values are phases in degrees and
    x_i − x_j is the wrapped difference (docs/domain.md §12).  It is filled in
    bands of rows whose denominator buffer (~256 KiB) stays in cache: 2–3× faster
    than whole-matrix temporaries for n in the thousands, and the only n×n array is
    the result (``out``).
    """
    xv, Uv = _pair_inputs(x, U)
    n = xv.size
    if out is None:
        out = np.empty((n, n), dtype=np.float64)
    elif out.shape != (n, n) or out.dtype != np.float64:
        raise CoreInputError(f"out must be a float64 array of shape ({n}, {n}), got {out.shape}")
    u2 = Uv * Uv
    rows = max(1, _BAND_CELLS // n)
    den = np.empty((min(rows, n), n), dtype=np.float64)
    for r0 in range(0, n, rows):
        band, d = out[r0 : r0 + rows], den[: min(rows, n - r0)]
        np.subtract.outer(xv[r0 : r0 + rows], xv, out=band)
        if circular:
            band[...] = wrap(band)
        np.abs(band, out=band)
        np.add.outer(u2[r0 : r0 + rows], u2, out=d)
        np.sqrt(d, out=d)
        np.divide(band, d, out=band)
    return out


def pairwise_en_padded(
    x: ArrayLike, U: ArrayLike, groups: Groups, circular: BoolArray | None = None
) -> FloatArray:
    """En matrices of all groups at once as a (n_groups, m, m) array, m = largest group.

    Block g holds the matrix of group g's results in input order in its top-left
    n_g × n_g corner; the rest is NaN.  Memory is n_groups·m² cells: use
    :func:`pairwise_en_grouped` when group sizes differ a lot.  ``circular`` (per
    group) marks groups of phases, whose differences are wrapped.
    """
    xv, Uv = _pair_inputs(x, U, groups)
    en, den = _padded_outer(xv, Uv, groups)
    if circular is not None and circular.any():
        en[circular] = wrap(en[circular])
    np.abs(en, out=en)
    return np.divide(en, den, out=en)


def _padded_outer(x: FloatArray, u: FloatArray, groups: Groups) -> tuple[FloatArray, FloatArray]:
    """Per group, x_i − x_j and √(u_i² + u_j²) on the padded (G, m, m) layout (NaN padding)."""
    xp = groups.padded(x)
    u2 = groups.padded(u * u)
    den = u2[:, :, None] + u2[:, None, :]
    return xp[:, :, None] - xp[:, None, :], np.sqrt(den, out=den)


@dataclass(frozen=True, eq=False)
class GroupedEn:
    """En matrices per group: ``blocks[g]`` compares the results ``members[g]`` (input order)."""

    blocks: list[FloatArray]
    members: list[IntArray]
    incompatible_pairs: IntArray


def pairwise_en_grouped(
    x: ArrayLike,
    U: ArrayLike,
    groups: Groups,
    *,
    limit: float = 1.0,
    circular: BoolArray | None = None,
) -> GroupedEn:
    """En matrix of every group, for groups of equal or different sizes; ``circular`` (per
    group) marks groups of phases, compared by wrapped differences.

    Many small groups are computed together on one padded 3-D array; when that
    array would exceed :data:`PADDED_CELL_LIMIT` cells (a few large groups, or
    very uneven sizes) each group's block is computed on its own (one vectorised
    matrix per group, no loop over results).
    """
    xv, Uv = _pair_inputs(x, U, groups)
    counts = groups.counts()
    members = np.split(groups.order(), np.cumsum(counts)[:-1])
    width = int(counts.max()) if groups.n_groups else 0
    if groups.n_groups * width * width <= PADDED_CELL_LIMIT:
        en = pairwise_en_padded(xv, Uv, groups, circular)
        blocks = [en[g, :c, :c] for g, c in enumerate(counts.tolist())]
        pairs = incompatible_pairs(en, limit)
    else:
        circ = np.zeros(groups.n_groups, bool) if circular is None else circular
        blocks = [
            pairwise_en(xv[m], Uv[m], circular=bool(circ[g])) if m.size else np.empty((0, 0))
            for g, m in enumerate(members)
        ]
        pairs = np.array([int(incompatible_pairs(b, limit)) for b in blocks], dtype=np.intp)
    return GroupedEn(blocks=blocks, members=list(members), incompatible_pairs=pairs)


def incompatible_pairs(en: ArrayLike, limit: float = 1.0) -> IntArray:
    """Number of pairs i < j with En_ij > ``limit`` (upper triangle; NaN padding never counts).

    Works on one matrix (returns a 0-d array) or a stack (..., m, m).
    """
    lim = float(limit)
    if not (math.isfinite(lim) and lim >= 0):
        raise CoreInputError(f"En limit must be finite and >= 0, got {limit!r}")
    e = np.asarray(en, dtype=np.float64)
    if e.ndim < 2 or e.shape[-1] != e.shape[-2]:
        raise CoreInputError(f"En must be a square matrix or a stack of them, got shape {e.shape}")
    return np.triu(e > lim, k=1).sum(axis=(-2, -1))


def en_against_reference(
    x: ArrayLike, U: ArrayLike, reference_value: float, reference_expanded_uncertainty: float
) -> FloatArray:
    """En_i = |x_i − x_ref| / √(U_i² + U_ref²) of each result against one reference value."""
    xv, Uv = _pair_inputs(x, U)
    ref = as_finite("reference_value", [reference_value])[0]
    u_ref = _non_negative("reference_expanded_uncertainty", [reference_expanded_uncertainty])[0]
    return np.abs(xv - ref) / np.hypot(Uv, u_ref)


@dataclass(frozen=True, eq=False)
class DegreesOfEquivalence:
    """Unilateral (one entry per result) and pairwise (per group, padded) degrees of equivalence.

    ``members[g, j]`` is the result in row/column j of group g's pairwise blocks
    (-1 in padding, where the pairwise arrays are NaN).  ``corrected`` marks
    results whose u(d_i) used the Cox 2002 correction; ``correction_failed``
    those where it was asked for but u_i² − u_pt² ≤ 0 (e.g. the only
    contributor), which then use the uncorrected sum, as ``scores.py`` does.
    """

    d: FloatArray
    standard_uncertainty: FloatArray
    expanded_uncertainty: FloatArray
    corrected: BoolArray
    correction_failed: BoolArray
    members: IntArray
    pairwise_d: FloatArray | None
    pairwise_expanded_uncertainty: FloatArray | None
    coverage_factor: float


def degrees_of_equivalence(
    x: ArrayLike,
    u: ArrayLike,
    x_pt: ArrayLike,
    u_pt: ArrayLike,
    groups: Groups,
    contributes: ArrayLike,
    k: float = 2.0,
    *,
    pairwise: bool = True,
) -> DegreesOfEquivalence:
    """Degrees of equivalence, docs/domain.md §6 (CIPM MRA key comparison convention).

    Unilateral: d_i = x_i − x_pt, U(d_i) = k·u(d_i), u²(d_i) = u_i² + u_pt², or
    u_i² − u_pt² where ``contributes[i]`` (the result is part of a weighted-mean
    assigned value: Cox, Metrologia 39:589, 2002).  Pairwise within each group:
    d_ij = x_i − x_j, U(d_ij) = k·√(u_i² + u_j²), on the padded (G, m, m) layout;
    pass ``pairwise=False`` for large rounds where G·m² cells do not fit.
    """
    kf = check_coverage_factor(k)
    xv, uv = _pair_inputs(x, u, groups, name_u="u")
    xpt, upt = _per_group(x_pt, u_pt, groups)
    contrib = _contributes(contributes, xv.size)
    u2 = uv * uv
    upt2 = groups.broadcast(upt * upt)
    failed = contrib & (u2 - upt2 <= _COX_RTOL * u2)
    corrected = contrib & ~failed
    std = np.sqrt(np.where(corrected, u2 - upt2, u2 + upt2))
    members = groups.padded(np.arange(xv.size, dtype=np.float64), fill=-1).astype(np.intp)
    pd: FloatArray | None = None
    pU: FloatArray | None = None
    if pairwise:
        _check_padded_size(groups)
        pd, pU = _padded_outer(xv, uv, groups)
        pU *= kf
    return DegreesOfEquivalence(
        d=xv - groups.broadcast(xpt),
        standard_uncertainty=std,
        expanded_uncertainty=kf * std,
        corrected=corrected,
        correction_failed=failed,
        members=members,
        pairwise_d=pd,
        pairwise_expanded_uncertainty=pU,
        coverage_factor=kf,
    )


@dataclass(frozen=True, eq=False)
class CompatibilityMatrix:
    """Pairwise En between the aggregated levels of ``factor`` within one ``group``.

    ``group`` maps the by-keys (column names) to this group's labels; ``levels``
    are sorted; ``value``/``standard_uncertainty``/``expanded_uncertainty``/``n``
    are per level (§3 aggregate, coverage factor ``coverage_factor``); ``en`` is
    the symmetric level × level matrix with zero diagonal; ``incompatible_pairs``
    counts pairs with En > ``limit``.
    """

    factor: str
    group: dict[str, object]
    levels: list[object]
    value: FloatArray
    standard_uncertainty: FloatArray
    expanded_uncertainty: FloatArray
    en: FloatArray
    incompatible_pairs: int
    n: IntArray
    coverage_factor: float = 2.0
    limit: float = 1.0


def default_by(factor: str) -> tuple[str, ...]:
    """Default grouping keys of docs/interfaces.md §4: device and axis less the factor; for
    ``lab`` the whole measurement point."""
    col = _factor_column(factor)
    if col == "lab":
        return POINT_FIELDS
    return tuple(c for c in ("device", "axis") if c != col)


def compatibility_matrices(
    table: Mapping[str, ArrayLike],
    factor: str,
    by: Sequence[str] | None = None,
    *,
    k: float = 2.0,
    limit: float = 1.0,
) -> list[CompatibilityMatrix]:
    """Compatibility matrices of ``factor`` per by-group (docs/domain.md §6, docs/interfaces.md §4).

    ``table`` is columnar: equal-length 1-D arrays ``value`` and
    ``standard_uncertainty`` (one entry per result) plus the label columns the
    factor and ``by`` need (of :data:`LABEL_COLUMNS`; the factor ``frequency``
    reads ``frequency_hz``).  Rows are grouped by (by-keys, level), every level
    is aggregated with the §3 rule in one bincount pass, and the level × level
    En matrices of all groups are computed in one batch.  Groups come out
    sorted by their keys.
    """
    col = _factor_column(factor)
    by_cols = with_quantity(_by_columns(by, col), table)
    value, u = _numeric_columns(table)
    lvl_code, lvl_names = _encode(table, col, value.size)
    by_code, by_shape, by_names = _encode_many(table, by_cols, value.size)
    n_lvl = lvl_names.size
    present, idx = np.unique(by_code * n_lvl + lvl_code, return_inverse=True)
    agg = aggregate(value, u, Groups.from_index(idx.reshape(-1), present.size), k)
    return _matrices_of_levels(
        factor, agg, present, lvl_names, (by_cols, by_shape, by_names), limit=limit
    )


def _matrices_of_levels(
    factor: str,
    agg: Aggregate,
    present: IntArray,
    lvl_names: np.ndarray,
    by: tuple[tuple[str, ...], tuple[int, ...], list[np.ndarray]],
    *,
    limit: float,
) -> list[CompatibilityMatrix]:
    """One matrix per by-group from the aggregated levels: ``present`` holds the code
    by_code * n_levels + level_code of every aggregated level (sorted), ``by`` the
    by-columns with their shape and names as :func:`_encode_many` gives them."""
    by_cols, by_shape, by_names = by
    n_lvl = lvl_names.size
    by_present, by_idx = np.unique(present // n_lvl, return_inverse=True)
    by_groups = Groups.from_index(by_idx.reshape(-1), by_present.size)
    parts = np.unravel_index(by_present, by_shape)
    circular = _circular_groups(by_cols, by_names, parts, by_present.size)
    batch = pairwise_en_grouped(
        agg.mean, agg.expanded_uncertainty, by_groups, limit=limit, circular=circular
    )
    level_names = lvl_names[present % n_lvl]
    mean = np.where(circular[by_groups.index], wrap(agg.mean), agg.mean)
    return [
        CompatibilityMatrix(
            factor=_factor_name(factor),
            group={c: by_names[j][parts[j][g]].item() for j, c in enumerate(by_cols)},
            levels=level_names[m].tolist(),
            value=mean[m],
            standard_uncertainty=agg.standard_uncertainty[m],
            expanded_uncertainty=agg.expanded_uncertainty[m],
            en=batch.blocks[g],
            incompatible_pairs=int(batch.incompatible_pairs[g]),
            n=agg.n[m],
            coverage_factor=agg.coverage_factor,
            limit=float(limit),
        )
        for g, m in enumerate(batch.members)
    ]


def with_quantity(by_cols: tuple[str, ...], table: Mapping[str, object]) -> tuple[str, ...]:
    """The by-columns with ``quantity`` where the table has that column (kinds are never
    pooled nor compared with each other), without it where it has not (a table of
    magnitudes written before kinds existed)."""
    cols = tuple(c for c in by_cols if c != QUANTITY)
    return (*cols, QUANTITY) if QUANTITY in table else cols


def _circular_groups(
    by_cols: tuple[str, ...], by_names: list[np.ndarray], parts: tuple[np.ndarray, ...], n: int
) -> BoolArray:
    """Per by-group: whether it holds a circular kind (its levels are phases)."""
    if QUANTITY not in by_cols:
        return np.zeros(n, dtype=bool)
    j = by_cols.index(QUANTITY)
    return np.isin(by_names[j][parts[j]], list(CIRCULAR))


@dataclass(frozen=True, eq=False)
class ReferenceComparison:
    """Each level of one compatibility matrix against a reference value (e.g. nominal)."""

    factor: str
    group: dict[str, object]
    levels: list[object]
    value: FloatArray
    expanded_uncertainty: FloatArray
    reference_value: float
    reference_expanded_uncertainty: float
    d: FloatArray
    en: FloatArray
    compatible: BoolArray


def against_reference(
    matrix: CompatibilityMatrix,
    reference_value: float,
    reference_standard_uncertainty: float,
    *,
    k: float | None = None,
) -> ReferenceComparison:
    """En of each level of ``matrix`` against a reference x_ref with u(x_ref).

    U(x_ref) = k·u(x_ref), k defaulting to the matrix's coverage factor.  For
    the manufacturer's nominal 418 ± 1 % rectangular (docs/domain.md §3):
    ``against_reference(m, 418.0, 4.18 / math.sqrt(3))``.  ``d`` is signed
    (level − reference), ``en`` = |d| / √(U² + U_ref²), compatible when ≤ limit.
    """
    kf = check_coverage_factor(matrix.coverage_factor if k is None else k)
    u_ref = _non_negative("reference_standard_uncertainty", [reference_standard_uncertainty])[0]
    big_u_ref = kf * float(u_ref)
    en = en_against_reference(matrix.value, matrix.expanded_uncertainty, reference_value, big_u_ref)
    return ReferenceComparison(
        factor=matrix.factor,
        group=dict(matrix.group),
        levels=list(matrix.levels),
        value=matrix.value,
        expanded_uncertainty=matrix.expanded_uncertainty,
        reference_value=float(reference_value),
        reference_expanded_uncertainty=big_u_ref,
        d=matrix.value - float(reference_value),
        en=en,
        compatible=en <= matrix.limit,
    )


def _pair_inputs(
    x: ArrayLike, U: ArrayLike, groups: Groups | None = None, *, name_u: str = "U"
) -> tuple[FloatArray, FloatArray]:
    xv = as_finite("x", x)
    Uv = as_finite(name_u, U, positive=True)
    if xv.size == 0:
        raise CoreInputError("no results to compare: x is empty")
    if xv.size != Uv.size:
        raise CoreInputError(f"x and {name_u} differ in length: {xv.size} vs {Uv.size}")
    if groups is not None and groups.size != xv.size:
        raise CoreInputError(f"{xv.size} results but a group index of length {groups.size}")
    return xv, Uv


def _non_negative(name: str, values: ArrayLike) -> FloatArray:
    arr = as_finite(name, values)
    if (arr < 0).any():
        i = int(np.flatnonzero(arr < 0)[0])
        raise CoreInputError(f"{name}[{i}] must be >= 0, got {arr[i]!r}")
    return arr


def _per_group(x_pt: ArrayLike, u_pt: ArrayLike, groups: Groups) -> tuple[FloatArray, FloatArray]:
    xpt = as_finite("x_pt", x_pt)
    upt = _non_negative("u_pt", u_pt)
    if xpt.size != groups.n_groups or upt.size != groups.n_groups:
        raise CoreInputError(
            f"x_pt and u_pt need one entry per group ({groups.n_groups}), "
            f"got {xpt.size} and {upt.size}"
        )
    return xpt, upt


def _contributes(contributes: ArrayLike, n: int) -> BoolArray:
    c = np.asarray(contributes)
    if c.dtype != np.bool_ or c.shape not in ((), (n,)):
        raise CoreInputError(
            f"contributes must be a boolean scalar or one boolean per result ({n}), "
            f"got dtype {c.dtype} and shape {c.shape}"
        )
    return np.broadcast_to(c, (n,)).copy()


def _check_padded_size(groups: Groups) -> None:
    width = int(groups.counts().max())
    cells = groups.n_groups * width * width
    if cells > 4 * PADDED_CELL_LIMIT:
        raise CoreInputError(
            f"pairwise degrees of equivalence need {cells} cells ({groups.n_groups} groups × "
            f"{width}²); pass pairwise=False and use pairwise_en_grouped for large rounds"
        )


def _factor_column(factor: str, *, by: bool = False) -> str:
    """The label column of a factor (or, with ``by``, of a by-key: ``quantity`` too)."""
    col = FACTORS.get(factor, factor if factor == "frequency_hz" else None)
    if col is None or (col == QUANTITY and not by):
        names = sorted(f for f in FACTORS if by or f != QUANTITY)
        raise CoreInputError(f"unknown factor {factor!r}; choose one of {names}")
    return col


def _factor_name(factor: str) -> str:
    return "frequency" if factor == "frequency_hz" else factor


def _by_columns(by: Sequence[str] | None, factor_col: str) -> tuple[str, ...]:
    if by is None:
        return default_by(factor_col)
    if isinstance(by, str):
        by = (by,)
    cols = tuple(_factor_column(b, by=True) for b in by)
    if factor_col in cols:
        raise CoreInputError(f"the factor {factor_col!r} cannot also be a 'by' key")
    if len(set(cols)) != len(cols):
        raise CoreInputError(f"'by' keys repeat: {list(by)}")
    return cols


def _numeric_columns(table: Mapping[str, ArrayLike]) -> tuple[FloatArray, FloatArray]:
    for name in ("value", "standard_uncertainty"):
        if name not in table:
            raise CoreInputError(f"the results table has no column {name!r}")
    value = as_finite("value", table["value"])
    u = as_finite("standard_uncertainty", table["standard_uncertainty"], positive=True)
    if value.size == 0:
        raise CoreInputError("the results table is empty")
    if value.size != u.size:
        raise CoreInputError(f"value and standard_uncertainty differ: {value.size} vs {u.size}")
    return value, u


def _encode(table: Mapping[str, ArrayLike], col: str, n: int) -> tuple[IntArray, np.ndarray]:
    """Integer code of each row's label in ``col`` and the sorted distinct labels."""
    if col not in table:
        raise CoreInputError(f"the results table has no column {col!r}, which is needed here")
    arr = np.asarray(table[col]).reshape(-1)
    if arr.size != n:
        raise CoreInputError(f"column {col!r} has {arr.size} rows, value has {n}")
    if arr.dtype.kind == "f" and not np.isfinite(arr).all():
        i = int(np.flatnonzero(~np.isfinite(arr))[0])
        raise CoreInputError(f"{col}[{i}] must be finite, got {arr[i]!r}")
    try:
        names, codes = np.unique(arr, return_inverse=True)
    except TypeError as exc:
        raise CoreInputError(f"column {col!r} mixes label types (or holds None): {exc}") from exc
    return codes.reshape(-1).astype(np.intp), names


def _encode_many(
    table: Mapping[str, ArrayLike], cols: tuple[str, ...], n: int
) -> tuple[IntArray, tuple[int, ...], list[np.ndarray]]:
    if not cols:
        return np.zeros(n, dtype=np.intp), (1,), []
    encoded = [_encode(table, c, n) for c in cols]
    shape = tuple(names.size for _, names in encoded)
    code = np.ravel_multi_index([c for c, _ in encoded], shape)
    return code.astype(np.intp), shape, [names for _, names in encoded]
