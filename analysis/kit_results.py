"""Read side of a run's kits (docs/domain.md §13, §14): the per-point drift and link fits,
each result's kit, date, drift handling and linked degree of equivalence, for the
coordinator's results page, the API and the reports."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from django.db.models import CharField, FloatField, OuterRef, QuerySet, Subquery

from analysis.core.linking import factored_covariance
from analysis.models import AnalysisRun, KitPointFit, KitScore, Score
from common.points import POINT_FIELDS
from proficiency.models import MeasurementPoint
from proficiency.selectors import POINT_ORDER

#: the keys each score gains in the API (docs/interfaces.md §3), null where they do not apply
KIT_KEYS = ("kit", "linked_d", "linked_expanded_uncertainty", "u_link", "drift_correction",
            "u_drift")  # fmt: skip


def run_has_kits(run: AnalysisRun) -> bool:
    return KitPointFit.objects.filter(run=run).exists()


def kit_fits(run: AnalysisRun) -> QuerySet[KitPointFit]:
    """The run's per-point fits without their covariances (:func:`kit_covariances`)."""
    return (KitPointFit.objects.filter(run=run).select_related("measurement_point__device")
            .defer("doe_covariance").order_by(*POINT_ORDER))  # fmt: skip


def kit_scores(run: AnalysisRun, code: str | None = None) -> QuerySet[KitScore]:
    """Every result's kit row, in point order then participant code; ``code``: one
    participant's only."""
    found = KitScore.objects.filter(run=run)
    if code is not None:
        found = found.filter(result__submission__participant__code=code)
    order = [f"result__{f}" for f in POINT_ORDER]
    return found.select_related(
        "kit", "result__measurement_point__device", "result__submission__participant"
    ).order_by(*order, "result__submission__participant__code")


def with_kit_scores(scores: QuerySet[Score]) -> QuerySet[Score]:
    """``scores`` annotated with :data:`KIT_KEYS` from the run's kit rows (null without)."""
    row = KitScore.objects.filter(run=OuterRef("run"), result=OuterRef("result"))

    def value(name: str, kind: type = FloatField) -> Subquery:
        return Subquery(row.values(name)[:1], output_field=kind())

    return scores.annotate(
        kit=value("kit__name", CharField), linked_d=value("linked_d"),
        linked_expanded_uncertainty=value("linked_u") * 2, u_link=value("u_link"),
        drift_correction=value("drift_correction"), u_drift=value("u_drift"),
    )  # fmt: skip


@dataclass
class DriftLine:
    """One kit at one point, as judged (docs/domain.md §13)."""

    point: str
    kit: str
    n: int
    model: str
    slope: float
    u_slope: float
    p_value: float | None


@dataclass
class KitSummary:
    """What a run did with its kits, for a report or a page's head."""

    treatment: str
    references: list[str]
    linked_points: int
    unlinked_points: int
    drift: list[DriftLine] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)


def kit_summary(run: AnalysisRun, labels: dict[int, str] | None = None) -> KitSummary | None:
    """The run's kit handling in a few lines (None: a round without kits).  ``labels``:
    point labels by point id (a report's), else the points' own."""
    fits = list(kit_fits(run))
    if not fits:
        return None
    treatment = str(run.parameters.get("drift_treatment") or run.comparison.drift_treatment)
    summary = KitSummary(
        treatment=treatment,
        references=sorted({f.reference for f in fits if f.reference}),
        linked_points=sum(1 for f in fits if f.reference),
        unlinked_points=sum(1 for f in fits if not f.reference),
    )
    for f in fits:
        label = (labels or {}).get(f.measurement_point_id) or str(f.measurement_point)
        summary.drift += [DriftLine(label, d["kit"], d["n"], d["model"], d["slope"],
                                    d["u_slope"], d.get("p_value")) for d in f.drift]  # fmt: skip
        summary.notes += [n for n in f.notes if n not in summary.notes]
    return summary


# --- the covariance of the linked degrees of equivalence (docs/domain.md §14) -------------

#: the columns of the long-form covariance download (docs/interfaces.md §6)
COVARIANCE_COLUMNS = [*POINT_FIELDS, "code_a", "code_b", "covariance", "correlation"]
#: up to this many participants a point's correlations are shown as a matrix, beyond as
#: its largest pairs
MATRIX_MAX = 15
LARGEST_PAIRS = 10


@dataclass(frozen=True)
class DoeCovariance:
    """The covariance of the linked participants' degrees of equivalence at one point,
    rebuilt from its stored factored form (``KitPointFit.doe_covariance``)."""

    point: MeasurementPoint
    reference: str
    codes: list[str]
    covariance: np.ndarray

    @property
    def correlation(self) -> np.ndarray:
        """r_ab = cov_ab / (u_a·u_b); NaN where a u is 0."""
        s = np.sqrt(np.diag(self.covariance))
        with np.errstate(invalid="ignore", divide="ignore"):
            r = self.covariance / np.outer(s, s)
        r[np.diag_indices(len(self.codes))] = np.where(s > 0, 1.0, np.nan)
        return r

    def largest(self, n: int = LARGEST_PAIRS) -> list[tuple[str, str, float]]:
        """The ``n`` pairs a < b of largest |r|, largest first (then in code order)."""
        r = self.correlation
        a, b = np.triu_indices(len(self.codes), k=1)
        values = r[a, b]
        keep = np.flatnonzero(np.isfinite(values))
        order = keep[np.argsort(-np.abs(values[keep]), kind="stable")][:n]
        return [(self.codes[a[i]], self.codes[b[i]], float(values[i])) for i in order]


def covariance_of(fit: KitPointFit) -> DoeCovariance | None:
    """The covariance stored with ``fit`` (None: not linked, or a run stored before it)."""
    rec = fit.doe_covariance
    if not rec or not rec.get("codes"):
        return None
    cov = factored_covariance(rec["own"], rec["factor"], rec["core"])
    return DoeCovariance(fit.measurement_point, fit.reference, list(rec["codes"]), cov)


def kit_covariances(run: AnalysisRun, point: MeasurementPoint | None = None
                    ) -> Iterator[DoeCovariance]:  # fmt: skip
    """The covariance of the linked degrees of equivalence at each linked point of the run
    (``point``: that one only), in point order, read a few hundred points at a time."""
    found = (KitPointFit.objects.filter(run=run).exclude(reference="")
             .select_related("measurement_point__device").order_by(*POINT_ORDER))  # fmt: skip
    if point is not None:
        found = found.filter(measurement_point=point)
    for fit in found.iterator(chunk_size=200):
        cov = covariance_of(fit)
        if cov is not None:
            yield cov


def covariance_rows(run: AnalysisRun) -> Iterator[dict[str, Any]]:
    """Every linked point's covariances in long form, full precision: one row per pair
    a ≤ b in the stored code order (a = b: u²(d) and r = 1), r empty where undefined."""
    for c in kit_covariances(run):
        keys = dict(zip(POINT_FIELDS, c.point.key.measurand, strict=True))
        r = c.correlation
        a, b = np.triu_indices(len(c.codes))
        for i, j in zip(a.tolist(), b.tolist(), strict=True):
            rij = float(r[i, j])
            yield keys | {"code_a": c.codes[i], "code_b": c.codes[j],
                          "covariance": float(c.covariance[i, j]),
                          "correlation": rij if np.isfinite(rij) else None}  # fmt: skip
