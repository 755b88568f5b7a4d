"""Read side of a run's kits (docs/domain.md §13, §14): the per-point drift and link fits,
each result's kit, date, drift handling and linked degree of equivalence, for the
coordinator's results page, the API and the reports."""

from __future__ import annotations

from dataclasses import dataclass, field

from django.db.models import CharField, FloatField, OuterRef, QuerySet, Subquery

from analysis.models import AnalysisRun, KitPointFit, KitScore, Score
from proficiency.selectors import POINT_ORDER

#: the keys each score gains in the API (docs/interfaces.md §3), null where they do not apply
KIT_KEYS = ("kit", "linked_d", "linked_expanded_uncertainty", "u_link", "drift_correction",
            "u_drift")  # fmt: skip


def run_has_kits(run: AnalysisRun) -> bool:
    return KitPointFit.objects.filter(run=run).exists()


def kit_fits(run: AnalysisRun) -> QuerySet[KitPointFit]:
    return (KitPointFit.objects.filter(run=run).select_related("measurement_point__device")
            .order_by(*POINT_ORDER))  # fmt: skip


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
