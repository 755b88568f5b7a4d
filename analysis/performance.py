"""How each laboratory did in one analysis run: counts of flags per score type, broken
down by device, bench and axis, and its worst results (docs/domain.md, "Performance
summary").

Read in a fixed number of queries whatever the size of the round: one grouped count over
the run's scores (laboratory × device × bench × axis × En flag × z flag) and, for one
laboratory, its worst scores by |En| and by the |z| or |z′| that counts.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field

from django.db.models import Count, F, Max, QuerySet
from django.db.models.functions import Abs

from analysis.core.scores import FLAG_LABELS
from analysis.models import AnalysisRun, Score
from analysis.selectors import run_scores

SATISFACTORY, WARNING, ACTION, NOT_SCORED = FLAG_LABELS
#: the breakdowns of a laboratory's summary: (key, heading, the score's field)
BREAKDOWNS = (
    ("device", "Device", "result__measurement_point__device__name"),
    ("bench", "Bench", "result__measurement_point__bench"),
    ("axis", "Axis", "result__measurement_point__axis"),
)
WORST = 5  # worst results listed per score type


@dataclass
class Tally:
    """Counts of one score type's flags; ``z`` tallies only points with a σ_pt."""

    satisfactory: int = 0
    warning: int = 0
    action: int = 0
    not_scored: int = 0

    def add(self, flag: str, n: int) -> None:
        if flag == SATISFACTORY:
            self.satisfactory += n
        elif flag == WARNING:
            self.warning += n
        elif flag == ACTION:
            self.action += n
        else:
            self.not_scored += n

    @property
    def scored(self) -> int:
        return self.satisfactory + self.warning + self.action

    @property
    def share_satisfactory(self) -> float | None:
        """Proportion of satisfactory among the scored results (None: nothing scored)."""
        return self.satisfactory / self.scored if self.scored else None


@dataclass
class Row:
    """One level of a breakdown (a device, a bench, an axis) or the whole laboratory."""

    level: str
    en: Tally = field(default_factory=Tally)
    z: Tally = field(default_factory=Tally)  # empty where no point has a σ_pt

    def add(self, en_flag: str, z_flag: str, n: int) -> None:
        self.en.add(en_flag, n)
        if z_flag:  # blank where the point has no σ_pt: no z at all, not "not scored"
            self.z.add(z_flag, n)


@dataclass
class LabPerformance:
    """One laboratory's summary in one run."""

    code: str
    total: Row
    breakdowns: list[tuple[str, str, list[Row]]]  # (key, heading, rows by level)
    max_abs_en: float | None = None
    max_abs_z: float | None = None
    worst_en: list[Score] = field(default_factory=list)
    worst_z: list[Score] = field(default_factory=list)

    @property
    def signals(self) -> int:
        """Results with an action signal in En or in z (each result counted once per type)."""
        return self.total.en.action + self.total.z.action


def _grouped(run: AnalysisRun, codes: Iterable[str] | None) -> QuerySet[Score, dict]:
    qs = Score.objects.filter(run=run)
    if codes is not None:
        qs = qs.filter(result__submission__participant__code__in=list(codes))
    keys = [path for _, _, path in BREAKDOWNS]
    return (
        qs.order_by()
        .values("result__submission__participant__code", *keys, "flag", "z_flag")
        .annotate(n=Count("pk"))
    )


#: one group of a run's scores: (lab code, device, bench, axis, En flag, z flag, count)
Group = tuple[str, str, str, str, str, str, int]


def _grouped_rows(run: AnalysisRun, codes: Iterable[str] | None) -> Iterable[Group]:
    keys = ["result__submission__participant__code", *(path for _, _, path in BREAKDOWNS)]
    for g in _grouped(run, codes):
        yield (*(str(g[k]) for k in keys), g["flag"], g["z_flag"], g["n"])


def summaries_of(groups: Iterable[Group]) -> dict[str, LabPerformance]:
    """The laboratories' summaries (by code, in code order; no maxima, no worst lists) of
    grouped flag counts: what :func:`performance` reads, or a report's own score rows
    (``analysis.reports.assemble``), so both count by one rule."""
    by_lab: dict[str, tuple[Row, list[dict[str, Row]]]] = {}
    for code, *levels_of, en_flag, z_flag, n in groups:
        total, levels = by_lab.setdefault(code, (Row("all"), [{} for _ in BREAKDOWNS]))
        total.add(en_flag, z_flag, n)
        for level, rows in zip(levels_of, levels, strict=True):
            rows.setdefault(level, Row(level)).add(en_flag, z_flag, n)
    out = {}
    for code in sorted(by_lab):
        total, levels = by_lab[code]
        pairs = zip(BREAKDOWNS, levels, strict=True)
        breakdowns = [(key, heading, [rows[k] for k in sorted(rows)])
                      for (key, heading, _), rows in pairs]  # fmt: skip
        out[code] = LabPerformance(code, total, breakdowns)
    return out


def _maxima(run: AnalysisRun, codes: Iterable[str] | None) -> dict[str, tuple[float, float]]:
    qs = run_scores(run, {})
    if codes is not None:
        qs = qs.filter(result__submission__participant__code__in=list(codes))
    rows = (
        qs.order_by()
        .values("result__submission__participant__code")
        .annotate(en=Max(Abs("en")), z=Max(Abs(F("z_used"))))
    )
    return {r["result__submission__participant__code"]: (r["en"], r["z"]) for r in rows}


def performance(run: AnalysisRun, codes: Iterable[str] | None = None) -> list[LabPerformance]:
    """Every participant's summary in ``run`` (or only ``codes``), by code; no worst lists.

    Two queries: the grouped flag counts and the largest |En| and |z| (z′ where it counts)
    per laboratory."""
    codes = list(codes) if codes is not None else None
    summaries = summaries_of(_grouped_rows(run, codes))
    for code, (en, z) in _maxima(run, codes).items():
        if code in summaries:
            summaries[code].max_abs_en, summaries[code].max_abs_z = en, z
    return list(summaries.values())


def lab_performance(run: AnalysisRun, code: str) -> LabPerformance | None:
    """One laboratory's summary with its largest |En| and |z| (or |z′|) results, whatever
    their flags (None: it has no score in ``run``)."""
    found = performance(run, [code])
    if not found:
        return None
    summary = found[0]
    scores = run_scores(run, {"lab": code}, "en")
    summary.worst_en = list(scores[:WORST])
    summary.worst_z = list(run_scores(run, {"lab": code}, "z").exclude(z_flag="")[:WORST])
    return summary
