"""One analysis of a results table: assigned values, scores, compatibility matrices.

Plain Python over ``analysis.core`` (no ORM): used by the offline command
``pt_compare`` (docs/interfaces.md §4) and by the analysis runs of the service, so both
compute the same numbers.  All measurement points go through the core in one
call each; nothing here loops over results.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field, replace
from itertools import repeat
from typing import Any

import numpy as np

from analysis import circular as circ
from analysis.consistency import consistency_records
from analysis.core import assigned as av
from analysis.core import robust
from analysis.core.compatibility import CompatibilityMatrix, compatibility_matrices
from analysis.core.groups import BoolArray, CoreInputError, FloatArray, Groups
from analysis.core.pooled import Moments
from analysis.core.scores import FLAG_LABELS, Scores, compute_scores
from analysis.core.types import AssignedValues
from common.points import POINT_FIELDS, point_label
from common.quantities import CIRCULAR
from common.quantities import DEFAULT as DEFAULT_QUANTITY
from common.sizes import counted
from labs.importers import ResultRow

METHODS = (
    "reference", "nominal", "weighted_mean", "algorithm_a", "median", "median_niqr", "q_hampel",
    "dersimonian_laird",
)  # fmt: skip
FACTORS = ("lab", "axis", "frequency", "device", "bench", "direction")


@dataclass(frozen=True)
class ResultTable:
    """Columnar results: one entry per result in every array."""

    lab: np.ndarray
    device: np.ndarray
    axis: np.ndarray
    frequency_hz: FloatArray
    bench: np.ndarray
    direction: np.ndarray
    value: FloatArray
    expanded_uncertainty: FloatArray
    coverage_factor: FloatArray
    repeat_sd: FloatArray  # NaN where the laboratory gave no repeat data
    n_repeats: np.ndarray  # integers, 0 where the laboratory gave no repeat data
    #: the point's quantity kind (common.quantities); left out: every result a magnitude
    quantity: np.ndarray = field(default_factory=lambda: np.zeros(0, np.str_))

    def __post_init__(self) -> None:
        if self.quantity.size != self.value.size:
            object.__setattr__(self, "quantity", np.full(self.value.size, DEFAULT_QUANTITY))

    @classmethod
    def from_rows(cls, rows: Sequence[ResultRow]) -> ResultTable:
        def col(name: str, dtype: Any = np.str_) -> np.ndarray:
            return np.array([getattr(r, name) for r in rows], dtype=dtype)

        return cls(
            lab=col("lab"),
            device=col("device"),
            axis=col("axis"),
            frequency_hz=col("frequency_hz", np.float64),
            bench=col("bench"),
            direction=col("direction"),
            value=col("sensitivity", np.float64),
            expanded_uncertainty=col("expanded_uncertainty", np.float64),
            coverage_factor=col("coverage_factor", np.float64),
            repeat_sd=np.array([r.repeat_sd or np.nan for r in rows], dtype=np.float64),
            n_repeats=np.array([r.n_repeats or 0 for r in rows], dtype=np.int64),
            quantity=col("quantity"),
        )

    @property
    def standard_uncertainty(self) -> FloatArray:
        return self.expanded_uncertainty / self.coverage_factor

    def columns(self) -> dict[str, np.ndarray]:
        return {
            "lab": self.lab,
            "device": self.device,
            "axis": self.axis,
            "frequency_hz": self.frequency_hz,
            "bench": self.bench,
            "direction": self.direction,
            "quantity": self.quantity,
            "value": self.value,
            "standard_uncertainty": self.standard_uncertainty,
        }

    @property
    def circular(self) -> BoolArray:
        """Per result: whether its kind is circular (a phase, docs/domain.md §12)."""
        if not CIRCULAR:
            return np.zeros(self.value.size, dtype=bool)
        return np.isin(self.quantity, list(CIRCULAR))


@dataclass(frozen=True)
class AssignedSpec:
    """How x_pt is obtained (docs/domain.md §5); ``parse`` reads the command-line syntax."""

    method: str
    reference_lab: str | None = None
    nominal: float | None = None
    tolerance: float | None = None
    tolerance_relative: bool = False
    distribution: str = "rectangular"

    @classmethod
    def parse(cls, text: str) -> AssignedSpec:
        """``reference:<LAB>`` | ``nominal:<value>:<tol>[%][:rect|:normal]`` |
        ``weighted-mean`` | ``algorithm-a`` | ``median`` (MADe) | ``median-niqr`` |
        ``q-hampel`` | ``dersimonian-laird``."""
        head, _, rest = text.partition(":")
        method = head.strip().lower().replace("-", "_")
        if method == "reference" and rest.strip():
            return cls(method, reference_lab=rest.strip())
        if method == "nominal" and rest:
            return cls._parse_nominal(text, rest)
        if method in METHODS and method not in ("reference", "nominal") and not rest:
            return cls(method)
        raise ValueError(
            f"--assigned {text!r} is not understood; use reference:<LAB>, "
            "nominal:<value>:<tolerance>[%][:rect|:normal], weighted-mean, algorithm-a, "
            "median, median-niqr, q-hampel or dersimonian-laird"
        )

    @classmethod
    def _parse_nominal(cls, text: str, rest: str) -> AssignedSpec:
        parts = rest.split(":")
        dist = {"rect": "rectangular", "rectangular": "rectangular", "normal": "normal"}
        try:
            value = float(parts[0])
            tol_text = parts[1].strip()
            relative = tol_text.endswith("%")
            tolerance = float(tol_text.rstrip("%"))
            distribution = dist[parts[2].strip().lower()] if len(parts) > 2 else "rectangular"
        except (IndexError, ValueError, KeyError):
            raise ValueError(
                f"--assigned {text!r}: expected nominal:<value>:<tolerance>[%][:rect|:normal], "
                "e.g. nominal:418:1%:rect"
            ) from None
        if len(parts) > 3 or not (value > 0 and tolerance > 0 and math.isfinite(value + tolerance)):
            raise ValueError(f"--assigned {text!r}: value and tolerance must be finite and > 0")
        return cls(
            "nominal",
            nominal=value,
            tolerance=tolerance,
            tolerance_relative=relative,
            distribution=distribution,
        )


@dataclass(frozen=True)
class SigmaPtSpec:
    """σ_pt: none, prescribed (absolute or % of x_pt) or the robust s* of the round."""

    mode: str = "none"
    value: float | None = None

    @classmethod
    def parse(cls, text: str | None) -> SigmaPtSpec:
        if text is None or text.strip().lower() == "none":
            return cls()
        if text.strip().lower() == "robust":
            return cls("robust")
        relative = text.strip().endswith("%")
        try:
            value = float(text.strip().rstrip("%"))
        except ValueError:
            value = math.nan
        if not (value > 0 and math.isfinite(value)):
            raise ValueError(f"--sigma-pt {text!r}: use a number > 0, a percentage, or robust")
        return cls("relative" if relative else "absolute", value)


NO_SIGMA_PT = SigmaPtSpec()


@dataclass(frozen=True)
class Analysis:
    table: ResultTable
    groups: Groups
    points: list[tuple[Any, ...]]  # one POINT_FIELDS tuple per group
    assigned: AssignedValues
    sigma_pt: FloatArray  # NaN where σ_pt is not used
    scores: Scores
    compatibility: list[CompatibilityMatrix]

    @property
    def in_assigned_value(self) -> tuple[np.ndarray, np.ndarray]:
        """Per result: whether it entered its point's assigned value, and whether the
        question applies (it does not where the method uses no result: a nominal value)."""
        return inclusion(self.assigned, self.groups)


# Methods whose assigned value is made of no participant's result.
_NO_RESULTS = frozenset({"nominal"})


def inclusion(values: AssignedValues, groups: Groups) -> tuple[np.ndarray, np.ndarray]:
    """``(included, applies)`` per result: ``included`` as the method reports it (the
    largest consistent subset, the reference laboratory; every result for the robust
    estimators, which weight but never drop a result), ``applies`` false where the
    point's method takes no result at all."""
    if values.method == "mixed":
        methods = np.asarray(values.diagnostics["method"])
        applies = ~np.isin(methods, list(_NO_RESULTS))[groups.index]
    else:
        applies = np.full(groups.size, values.method not in _NO_RESULTS)
    return values.included & applies, applies


def analyse(
    table: ResultTable,
    assigned: AssignedSpec,
    *,
    sigma_pt: SigmaPtSpec = NO_SIGMA_PT,
    en_limit: float = 1.0,
    compare: Sequence[tuple[str, Sequence[str] | None]] = (),
) -> Analysis:
    """Assigned values and scores for every measurement point (device, axis, frequency,
    bench, direction and quantity kind), plus the requested matrices."""
    groups, points = Groups.from_labels(
        table.device, table.axis, table.frequency_hz, table.bench, table.direction,
        table.quantity,
    )  # fmt: skip
    values = assigned_values(table, groups, points, assigned)
    sigma = sigma_pt_values(linear_values_of(table, groups), groups, values, sigma_pt)
    return analyse_grouped(
        table, groups, points, values, sigma=sigma, en_limit=en_limit, compare=compare
    )


def analyse_grouped(
    table: ResultTable,
    groups: Groups,
    points: list[tuple[Any, ...]],
    values: AssignedValues,
    *,
    sigma: FloatArray,
    en_limit: float = 1.0,
    compare: Sequence[tuple[str, Sequence[str] | None]] = (),
) -> Analysis:
    """Scores and matrices for results already grouped, with their assigned values; a
    phase's D is the wrapped difference and it has no D% (docs/domain.md §12)."""
    is_circular = table.circular
    x = circ.score_values(table.value, is_circular, groups, values.value)
    u = table.standard_uncertainty
    contributes = _contributes(values)
    scores = compute_scores(
        x,
        u,
        table.expanded_uncertainty,
        groups,
        values.value,
        values.standard_uncertainty,
        U_pt=values.expanded_uncertainty,
        sigma_pt=sigma,
        contributes=contributes,
        en_limit=en_limit,
        relative=~circ.circular_groups(is_circular, groups),
    )
    linear = replace(table, value=linear_values_of(table, groups)) if is_circular.any() else table
    matrices = [
        m
        for factor, by in compare
        for m in compatibility_matrices(linear.columns(), factor, by, limit=en_limit)
    ]
    return Analysis(table, groups, points, values, sigma, scores, matrices)


def linear_values_of(table: ResultTable, groups: Groups) -> FloatArray:
    """The values the linear statistics take: phases unwrapped about their point's circular
    mean, every other value as it is (:func:`analysis.circular.linear_values`)."""
    return circ.linear_values(table.value, table.circular, groups)[0]


def _contributes(values: AssignedValues) -> np.ndarray | None:
    """Results whose own value entered x_pt with weights 1/u² (Cox 2002 correction)."""
    if values.method == "mixed":
        methods = np.asarray(values.diagnostics["method"])
        correlated = np.isin(methods, list(_CORRELATED))
        return values.included & correlated[_result_groups(values)]
    return values.included if values.method in _CORRELATED else None


def _result_groups(values: AssignedValues) -> np.ndarray:
    return np.asarray(values.diagnostics["_group_of_result"])


def assigned_values_mixed(
    table: ResultTable, groups: Groups, points: list[tuple[Any, ...]], specs: list[AssignedSpec]
) -> AssignedValues:
    """Assigned values where each measurement point may have its own method (per-point
    override, docs/domain.md §5): each distinct method runs once over its points."""
    if len(set(specs)) == 1:
        return assigned_values(table, groups, points, specs[0])
    value = np.empty(groups.n_groups)
    u_pt = np.empty(groups.n_groups)
    k_pt = np.empty(groups.n_groups)
    included = np.zeros(groups.size, dtype=bool)
    method = np.empty(groups.n_groups, dtype=object)
    diagnostics: dict[str, np.ndarray] = {}
    for spec in dict.fromkeys(specs):  # a loop over methods, not over results
        sel = np.flatnonzero([s == spec for s in specs])
        rows = np.flatnonzero(np.isin(groups.index, sel))
        sub = Groups.from_index(np.searchsorted(sel, groups.index[rows]), sel.size)
        part = assigned_values(take_rows(table, rows), sub, [points[g] for g in sel], spec)
        value[sel], u_pt[sel], included[rows] = part.value, part.standard_uncertainty, part.included
        k_pt[sel] = part.coverage_factors
        method[sel] = [point_method_of(part, g) for g in range(sel.size)]
        for key, arr in part.diagnostics.items():
            diagnostics.setdefault(key, np.full(groups.n_groups, np.nan, dtype=object))[sel] = arr
    diagnostics["method"] = method
    diagnostics["_group_of_result"] = groups.index
    return AssignedValues(value, u_pt, "mixed", included, diagnostics, coverage_factor=k_pt)


def take_rows(table: ResultTable, rows: np.ndarray) -> ResultTable:
    return ResultTable(**{f: getattr(table, f)[rows] for f in table.__dataclass_fields__})


# Methods whose x_pt is built from the participants' own results with weights 1/u²,
# so that the Cox (2002) correction u²(d) = u²(x) − u²(x_pt) applies.
_CORRELATED = frozenset({"weighted_mean", "largest_consistent_subset", "reference"})


def assigned_values(
    table: ResultTable, groups: Groups, points: list[tuple[Any, ...]], spec: AssignedSpec
) -> AssignedValues:
    """x_pt by ``spec`` at every point; at a phase's point computed on the phases unwrapped
    about their circular mean and wrapped back (docs/domain.md §12)."""
    is_circular = table.circular
    if not is_circular.any():
        return _assigned_linear(table, groups, points, spec)
    x, no_centre = circ.linear_values(table.value, is_circular, groups)
    if no_centre.any() and spec.method not in circ.NO_CENTRE_NEEDED:
        raise CoreInputError(circ.no_centre_message(points, no_centre))
    values = _assigned_linear(replace(table, value=x), groups, points, spec)
    wrapped = circ.wrap_groups(values.value, circ.circular_groups(is_circular, groups))
    return replace(values, value=wrapped)


def _assigned_linear(
    table: ResultTable, groups: Groups, points: list[tuple[Any, ...]], spec: AssignedSpec
) -> AssignedValues:
    x, u = table.value, table.standard_uncertainty
    if spec.method == "reference":
        is_ref = table.lab == spec.reference_lab
        if not is_ref.any():
            labs = ", ".join(sorted({str(v) for v in table.lab}))
            raise CoreInputError(
                f"reference laboratory {spec.reference_lab!r} is not in the table (labs: {labs})"
            )
        return _reference(table, groups, points, is_ref)
    if spec.method == "nominal":
        assert spec.nominal is not None and spec.tolerance is not None
        return av.nominal_value(
            spec.nominal,
            spec.tolerance,
            groups,
            relative=spec.tolerance_relative,
            # a Distribution: what parse() and the model field's choices allow
            distribution=spec.distribution,  # type: ignore[arg-type]
        )
    if spec.method == "weighted_mean":
        return _weighted_mean_or_subset(x, u, groups)
    if spec.method == "algorithm_a":
        return robust.algorithm_a(x, groups)
    if spec.method == "median":
        return robust.median_made(x, groups)
    if spec.method == "median_niqr":
        return robust.median_niqr(x, groups)
    if spec.method == "q_hampel":
        return robust.q_hampel(x, groups)
    if spec.method == "dersimonian_laird":
        return av.dersimonian_laird(x, u, groups)
    raise CoreInputError(f"unknown assigned-value method {spec.method!r}")


def _reference(
    table: ResultTable, groups: Groups, points: list[tuple[Any, ...]], is_ref: np.ndarray
) -> AssignedValues:
    """The reference laboratory's results, U(x_pt) its reported U (its own k)."""
    missing = np.flatnonzero(groups.sum(is_ref) == 0)
    if missing.size:
        names = "; ".join(point_label(points[g], sep=" ") for g in missing[:10])
        raise CoreInputError(
            f"the reference laboratory has no result for "
            f"{counted(int(missing.size), 'measurement point')}: "
            f"{names}"
        )
    return av.reference_value(
        table.value, table.standard_uncertainty, groups, is_ref, k=table.coverage_factor
    )


def _weighted_mean_or_subset(x: FloatArray, u: FloatArray, groups: Groups) -> AssignedValues:
    """Weighted mean (Cox 2002 procedure A); where the χ² test fails, the largest
    consistent subset (Cox 2007).  The per-point ``method`` diagnostic says which."""
    return av.largest_consistent_subset(x, u, groups)


def sigma_pt_values(
    x: FloatArray,
    groups: Groups,
    values: AssignedValues,
    spec: SigmaPtSpec,
    prescribed: FloatArray | None = None,
) -> FloatArray:
    """σ_pt per point by ``spec``; where ``prescribed`` (per point, NaN for none) holds a
    value, that value instead, and a robust s* of 0 there is no error (docs/domain.md §5.7)."""
    own = np.full(groups.n_groups, np.nan) if prescribed is None else prescribed
    has_own = np.isfinite(own)
    if spec.mode == "none":
        sigma = np.full(groups.n_groups, np.nan)
    elif spec.mode == "robust":
        # Algorithm A's s*, except at points assigned by Q/Hampel: their Q method s*
        methods = point_methods(values, groups.n_groups)
        estimator = ["q_method" if m == "q_hampel" else "algorithm_a" for m in methods]
        sigma = robust.sigma_pt_robust(x, groups, estimator=estimator, needed=~has_own)
    else:
        assert spec.value is not None
        sigma = av.sigma_pt_prescribed(
            spec.value, groups.n_groups, x_pt=values.value, relative=spec.mode == "relative"
        )
    return np.where(has_own, own, sigma)


def overflowing_results(table: ResultTable) -> np.ndarray:
    """Results whose own numbers overflow double precision in the analysis' arithmetic
    (x, u, x², 1/u² or (x/u)² not finite, e.g. a sensitivity of 1e308 or U of 1e-300):
    the ones to name when an output is not finite."""
    x, u = table.value, table.standard_uncertainty
    with np.errstate(all="ignore"):
        ok = np.isfinite(x) & np.isfinite(u) & (u > 0) & np.isfinite(x * x)
        ok &= np.isfinite(1.0 / (u * u)) & np.isfinite((x / u) ** 2)
    return ~ok


def nonfinite_points(analysis: Analysis, m: Moments) -> np.ndarray:
    """Per point: whether a number to store there is NaN or infinite (x_pt, u(x_pt), σ_pt
    where set, a score of one of its results, or a moment).  z and z′ are NaN by design
    where σ_pt is not set."""
    v, s, groups = analysis.assigned, analysis.scores, analysis.groups
    bad = ~(np.isfinite(v.value) & np.isfinite(v.standard_uncertainty))
    bad |= np.isinf(analysis.sigma_pt)
    bad |= ~(np.isfinite(m.sum_x) & np.isfinite(m.sum_u) & np.isfinite(m.m2))
    # a phase has no D% (NaN by design, docs/domain.md §12)
    d_percent_ok = np.isfinite(s.d_percent) | analysis.table.circular
    per_result = ~(np.isfinite(s.d) & d_percent_ok & np.isfinite(s.en))
    per_result |= ~np.isfinite(s.zeta)
    with_z = np.isfinite(analysis.sigma_pt)[groups.index]
    per_result |= with_z & ~(np.isfinite(s.z) & np.isfinite(s.z_prime))
    return bad | (np.bincount(groups.index[per_result], minlength=groups.n_groups) > 0)


def point_method_of(values: AssignedValues, g: int) -> str:
    """The method name reported for one point (weighted mean vs largest subset)."""
    if values.method == "mixed":
        return str(values.diagnostics["method"][g])
    if values.method == "largest_consistent_subset":
        return "weighted_mean" if bool(values.diagnostics["consistent_all"][g]) else values.method
    return values.method


def point_methods(values: AssignedValues, n_groups: int) -> list[str]:
    """The method of every point, as :func:`point_method_of`."""
    if values.method == "mixed":
        return [str(m) for m in values.diagnostics["method"]]
    return [point_method_of(values, g) for g in range(n_groups)]


def point_method(analysis: Analysis, g: int) -> str:
    return point_method_of(analysis.assigned, g)


def json_value(v: Any) -> Any:
    """numpy scalars to JSON-safe Python; NaN and inf become None."""
    if isinstance(v, np.generic):
        v = v.item()
    if isinstance(v, float) and not math.isfinite(v):
        return None
    return v


def to_json(analysis: Analysis, *, scores: bool = True) -> dict[str, list[dict[str, Any]]]:
    """The JSON document of docs/interfaces.md §4 (full precision; NaN/inf as null).  With
    ``scores=False`` the ``scores`` and ``consistency`` lists (one entry per result) are
    left empty, for a writer that streams them (:func:`score_record_chunks`,
    ``analysis.consistency.iter_records``)."""
    return {
        "assigned_values": assigned_records(analysis),
        "scores": score_records(analysis) if scores else [],
        "compatibility": compatibility_records(analysis.compatibility),
        "consistency": consistency_records(analysis) if scores else [],
    }


def excluded_labs(analysis: Analysis) -> list[list[str] | None]:
    """Per point: the laboratories (codes, sorted) whose results the method left out of the
    assigned value (the results outside the largest consistent subset), or None where
    the method does not select results (a reference, a nominal value)."""
    a, groups = analysis.assigned, analysis.groups
    if "n_excluded" not in a.diagnostics:
        return [None] * groups.n_groups
    selects = np.asarray(
        [not (isinstance(n, float) and math.isnan(n)) for n in a.diagnostics["n_excluded"]]
    )
    out: list[list[str] | None] = [[] if sel else None for sel in selects]
    left_out = np.flatnonzero(~a.included & selects[groups.index])
    for i in left_out[np.lexsort((analysis.table.lab[left_out], groups.index[left_out]))]:
        out[groups.index[i]].append(str(analysis.table.lab[i]))
    return out


# A diagnostic's key in the JSON where the method's name would hide another: the weighted
# mean's ``n`` (the results in the consistent subset) is not the point's ``n`` (all its
# results, scored).
_DIAGNOSTIC_KEYS = {"n": "n_included"}


def assigned_records(analysis: Analysis) -> list[dict[str, Any]]:
    a = analysis.assigned
    big_u, k_pt = a.expanded_uncertainty, a.coverage_factors
    excluded = excluded_labs(analysis)
    out = []
    for g, point in enumerate(analysis.points):
        rec: dict[str, Any] = dict(zip(POINT_FIELDS, point, strict=True))
        rec |= {
            "value": json_value(a.value[g]),
            "standard_uncertainty": json_value(a.standard_uncertainty[g]),
            "expanded_uncertainty": json_value(big_u[g]),
            "coverage_factor": json_value(k_pt[g]),
            "method": point_method(analysis, g),
            "n": int(analysis.groups.counts()[g]),
        }
        if math.isfinite(analysis.sigma_pt[g]):
            rec["sigma_pt"] = json_value(analysis.sigma_pt[g])
        rec |= {
            _DIAGNOSTIC_KEYS.get(k, k): json_value(v[g])
            for k, v in a.diagnostics.items()
            if np.ndim(v) == 1 and not k.startswith("_") and k != "method"
        }
        if excluded[g] is not None:
            rec["excluded"] = excluded[g]
        out.append(rec)
    return out


#: Keys of a score record only where the result's point has a σ_pt.
SIGMA_KEYS = ("z", "z_prime", "z_flag")


def score_columns(analysis: Analysis) -> tuple[dict[str, np.ndarray], np.ndarray]:
    """The score records as columns, one array per key in record order, and per result
    whether its point has a σ_pt (only then its record has the :data:`SIGMA_KEYS`).

    Built from whole arrays (``tolist`` gives the same Python values the per-result
    ``float()``/``bool()`` would): a round of 200,000 results is written in a fraction of
    a second.  Non-finite numbers stay NaN/inf here; the writers turn them into null.
    """
    t, s = analysis.table, analysis.scores
    included, applies = analysis.in_assigned_value
    in_assigned = included.astype(object)
    in_assigned[~applies] = None
    labels = np.asarray(FLAG_LABELS, dtype=object)
    f64 = np.float64
    columns: dict[str, np.ndarray] = {
        "device": t.device,
        "axis": t.axis,
        "frequency_hz": t.frequency_hz.astype(f64, copy=False),
        "bench": t.bench,
        "direction": t.direction,
        "quantity": t.quantity,
        "lab": t.lab,
        "value": t.value.astype(f64, copy=False),
        "expanded_uncertainty": t.expanded_uncertainty.astype(f64, copy=False),
        "d": s.d.astype(f64, copy=False),
        "d_percent": s.d_percent.astype(f64, copy=False),
        "en": s.en.astype(f64, copy=False),
        "zeta": s.zeta.astype(f64, copy=False),
        "z": s.z.astype(f64, copy=False),
        "z_prime": s.z_prime.astype(f64, copy=False),
        "z_flag": labels[s.performance_flag],
        "flag": labels[s.en_flag],
        "correlation_applied": s.correlation_applied.astype(bool, copy=False),
        "correlation_failed": s.correlation_failed.astype(bool, copy=False),
        "in_assigned_value": in_assigned,
    }
    return columns, np.isfinite(analysis.sigma_pt)[analysis.groups.index]


def score_record_chunks(analysis: Analysis, size: int = 20_000) -> Iterator[list[dict[str, Any]]]:
    """The score records (docs/interfaces.md §4), ``size`` at a time, so that a writer holds one
    chunk of dictionaries at once, never a whole round's."""
    cols, has_sigma = score_columns(analysis)
    without = [k for k in cols if k not in SIGMA_KEYS]
    for start in range(0, has_sigma.size, size):
        rows = slice(start, start + size)
        sigma = has_sigma[rows]
        keys = list(cols) if sigma.any() else without
        values = [cols[k][rows].tolist() for k in keys]
        records = list(map(dict, map(zip, repeat(keys), zip(*values, strict=True))))
        if sigma.any() and not sigma.all():
            for i in np.flatnonzero(~sigma).tolist():
                for k in SIGMA_KEYS:
                    del records[i][k]
        yield records


def score_records(analysis: Analysis) -> list[dict[str, Any]]:
    """One record per result: the point's keys, ``lab``, the value and its U, the scores
    and flags; z, z′ and the z flag where σ_pt is known."""
    return [rec for chunk in score_record_chunks(analysis) for rec in chunk]


def matrix_record(m: CompatibilityMatrix) -> dict[str, Any]:
    """One matrix as plain JSON values, its by-keys under ``group``."""
    return {
        "factor": m.factor,
        "group": {k: json_value(v) for k, v in m.group.items()},
        "levels": [json_value(v) for v in m.levels],
        "value": [float(v) for v in m.value],
        "expanded_uncertainty": [float(v) for v in m.expanded_uncertainty],
        "en": [[float(v) for v in row] for row in m.en],
        "incompatible_pairs": int(m.incompatible_pairs),
    }


def compatibility_records(matrices: Sequence[CompatibilityMatrix]) -> list[dict[str, Any]]:
    """docs/interfaces.md §4: the group's keys at the top level of each record."""
    out = []
    for m in matrices:
        rec = matrix_record(m)
        out.append({"factor": rec.pop("factor")} | rec.pop("group") | rec)
    return out
