"""Reads of the standard graphs (docs/domain.md §11): one run's stored scores and results
turned into the plain numbers ``analysis.core.graphs`` and ``analysis.standard_charts``
take.  Each function runs a fixed number of queries, whatever the number of laboratories
or points (the pages' query budgets)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from analysis.core import graphs
from analysis.models import AnalysisRun, AssignedValue
from analysis.selectors import run_scores
from common.points import format_number, point_label
from proficiency.models import MeasurementPoint
from proficiency.selectors import POINT_ORDER

Z_NAMES = {"z": "z", "z_prime": "z′"}


@dataclass(frozen=True)
class PointData:
    """One point's results and scores in a run, by participant code (ascending)."""

    labels: list[str]
    values: list[float]
    expanded: list[float]
    standard: list[float]
    en: list[float]  # NaN: not scored
    z: list[float]  # the z that counts (z or z′), NaN where none
    z_name: str  # "z" or "z′"
    in_assigned: list[bool]  # inside x_pt with the correlation correction (as En)
    assigned: AssignedValue

    def doe(self) -> graphs.DoEData:
        """Degrees of equivalence with U(d_i), k = 2 (``core.graphs.doe_data``)."""
        a = self.assigned
        return graphs.doe_data(self.labels, self.values, self.standard, a.value,
                               a.standard_uncertainty, in_assigned=self.in_assigned)  # fmt: skip


def point_choice_label(p: MeasurementPoint) -> str:
    """A point as the pages, forms and charts name it (its key, joined by " · ")."""
    return point_label(p.key, sep=" · ")


def _nan(value: float | None) -> float:
    return float("nan") if value is None else float(value)


def point_data(run: AnalysisRun, point: MeasurementPoint) -> PointData:
    """Two queries: the point's assigned value and its scores with the z used."""
    assigned = run.assigned_values.get(measurement_point=point)
    found = sorted(run_scores(run, {}).filter(result__measurement_point=point),
                   key=lambda s: s.result.submission.participant.code)  # fmt: skip
    primes = any(getattr(s, "z_is_prime", False) for s in found)
    return PointData(
        labels=[s.result.submission.participant.code for s in found],
        values=[s.result.value for s in found],
        expanded=[s.result.expanded_uncertainty for s in found],
        standard=[s.result.expanded_uncertainty / s.result.coverage_factor for s in found],
        en=[_nan(s.en) for s in found],
        z=[_nan(getattr(s, "z_used", None)) for s in found],
        z_name=Z_NAMES["z_prime" if primes else "z"],
        # the correlation correction where the score's En had it (tried, or failed: a sole
        # contributor); a robust consensus takes every result without it (docs/domain.md §5.4)
        in_assigned=[s.correlation_applied or s.correlation_failed for s in found],
        assigned=assigned,
    )


# --------------------------------------------------------------------------- pairs


def run_points(run: AnalysisRun) -> list[MeasurementPoint]:
    """The points the run assigned a value to, in the points' order (one query)."""
    found = AssignedValue.objects.filter(run=run).select_related("measurement_point__device")
    return [a.measurement_point for a in found.order_by(*POINT_ORDER)]


def point_pairs(points: list[MeasurementPoint]) -> list[tuple[str, str]]:
    """The Youden pairs worth drawing, as (``"<pk>-<pk>"``, label): the same device, axis
    and frequency on the two benches or in two directions first (the benches have their
    own directions), then two devices at the same axis, frequency, bench and direction;
    both points of one quantity kind (a phase against a magnitude has no common unit)."""
    ranked: list[tuple[int, str, str]] = []
    by_key: dict[tuple, list[MeasurementPoint]] = {}
    for p in points:
        name, axis, f, bench, direction = p.key[:5]
        by_key.setdefault(("bench", p.quantity, name, axis, f), []).append(p)
        by_key.setdefault(("device", p.quantity, axis, f, bench, direction), []).append(p)
    for (kind, *_), group in by_key.items():
        for i, a in enumerate(group):
            for b in group[i + 1 :]:
                rank = 2 if kind == "device" else int(a.bench == b.bench)  # benches first
                ranked.append((rank, f"{a.pk}-{b.pk}", _pair_label(kind, a, b)))
    ranked.sort(key=lambda r: r[0])  # stable: the points' order within a rank
    return [(key, label) for _, key, label in ranked]


def default_pair(pairs: list[tuple[str, str]], point: int | None = None) -> str | None:
    """The pair shown when none is asked for: the first pair of ``point`` (the point
    shown), else the first pair (None: the run has no pair)."""
    mine = (key for key, _ in pairs if point is not None and str(point) in key.split("-"))
    return next(mine, None) or next((key for key, _ in pairs), None)


def _pair_label(kind: str, a: MeasurementPoint, b: MeasurementPoint) -> str:
    if kind == "bench":
        return f"{point_label(a.key, sep=' · ')} vs {b.bench} {b.direction}"
    return f"{point_label(a.key, sep=' · ')} vs {b.device.name}"


@dataclass(frozen=True)
class PairData:
    """Each participant's results at two points (only those with both), by code."""

    labels: list[str]
    x: list[float]
    y: list[float]
    assigned_x: float
    assigned_y: float


def pair_data(run: AnalysisRun, a: MeasurementPoint, b: MeasurementPoint) -> PairData:
    """Two queries: the two assigned values and the two points' results."""
    assigned = dict(run.assigned_values.filter(measurement_point__in=[a, b])
                    .values_list("measurement_point_id", "value"))  # fmt: skip
    rows = run_scores(run, {}).filter(result__measurement_point__in=[a, b]).values_list(
        "result__submission__participant__code", "result__measurement_point_id", "result__value"
    )  # fmt: skip
    at: dict[str, dict[int, float]] = {}
    for code, pk, value in rows:
        at.setdefault(code, {})[pk] = value
    both = sorted(code for code, v in at.items() if a.pk in v and b.pk in v)
    return PairData(both, [at[c][a.pk] for c in both], [at[c][b.pk] for c in both],
                    assigned[a.pk], assigned[b.pk])  # fmt: skip


# --------------------------------------------------------------------------- Mandel


@dataclass(frozen=True)
class MandelData:
    labs: list[str]
    points: list[str]
    devices: list[str]  # each point's device (the chart's groups)
    graph: graphs.MandelGraph | None  # None: no result at all


def mandel_data(run: AnalysisRun) -> MandelData:
    """Mandel's h and k of every participant at every point of the run, from the results'
    values and repeat standard deviations (``core.graphs.mandel_statistics``); two queries."""
    points = run_points(run)
    column = {p.pk: j for j, p in enumerate(points)}
    rows = list(run_scores(run, {}).values_list(
        "result__submission__participant__code", "result__measurement_point_id",
        "result__value", "result__repeat_sd", "result__n_repeats"))  # fmt: skip
    labs = sorted({r[0] for r in rows})
    labels = [point_label(p.key, sep=" · ") for p in points]
    devices = [p.device.name for p in points]
    if not rows:
        return MandelData(labs, labels, devices, None)
    row = {code: i for i, code in enumerate(labs)}
    shape = (len(labs), len(points))
    means, sds, n = np.full(shape, np.nan), np.full(shape, np.nan), np.ones(shape)
    for code, pk, value, sd, repeats in rows:
        i, j = row[code], column[pk]
        means[i, j] = value
        if sd is not None and repeats and repeats >= 2:
            sds[i, j], n[i, j] = sd, repeats
    return MandelData(labs, labels, devices, graphs.mandel_statistics(means, sds, n))


# --------------------------------------------------------------------------- one lab


@dataclass(frozen=True)
class OverviewData:
    points: list[str]  # axis, frequency, direction
    groups: list[str]  # device · bench
    en: list[float]
    z: list[float]
    z_name: str


def lab_overview(run: AnalysisRun, code: str) -> OverviewData:
    """One participant's En and z (the one that counts) at each of its points, grouped by
    device and bench (the scores' order); one query."""
    found = list(run_scores(run, {"lab": code}))
    names = {bool(getattr(s, "z_is_prime", False)) for s in found if s.z is not None}
    z_name = "z′" if names == {True} else "z" if names == {False} else "z or z′"
    points = [s.result.measurement_point for s in found]
    return OverviewData(
        points=[f"{p.axis} {format_number(p.frequency_hz)} Hz {p.direction}" for p in points],
        groups=[f"{p.device.name} · {p.bench}" for p in points],
        en=[_nan(s.en) for s in found],
        z=[_nan(getattr(s, "z_used", None)) for s in found],
        z_name=z_name,
    )
