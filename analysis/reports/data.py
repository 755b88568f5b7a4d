"""The plain data a PT report needs (docs/domain.md §9): frozen dataclasses, no ORM objects."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from datetime import datetime

import numpy as np

from analysis.core.graphs import MandelGraph
from common.points import PointKey, point_label
from common.quantities import DEFAULT as DEFAULT_QUANTITY
from common.quantities import label_shown, unit_text

SUMMARY = "summary"
PARTICIPANT = "participant"


@dataclass(frozen=True)
class DeviceInfo:
    """A circulated artefact with its nominal sensitivity ± tolerance."""

    name: str
    model: str
    serial: str
    unit: str
    nominal: float | None
    tolerance: float | None
    tolerance_relative: bool
    distribution: str


@dataclass(frozen=True)
class PointInfo:
    """One measurand; ``index`` is its position in ``ReportData.points``."""

    index: int
    device: str
    axis: str
    frequency_hz: float
    bench: str
    direction: str
    amplitude_m_s2: float | None
    unit: str
    quantity: str = DEFAULT_QUANTITY

    @property
    def key(self) -> PointKey:
        return PointKey(
            self.device, self.axis, self.frequency_hz, self.bench, self.direction,
            self.amplitude_m_s2, self.quantity,
        )  # fmt: skip

    @property
    def label(self) -> str:
        """Without the device: the report's sections are headed by it."""
        return self._with_unit(point_label(self.key, device=False))

    @property
    def full_label(self) -> str:
        return self._with_unit(point_label(self.key))

    def _with_unit(self, label: str) -> str:
        """A kind other than the magnitude is not in its device's unit (the artefacts'
        table): its label names the unit, ``Z, 5 Hz, linear vertical, sensitivity phase
        (°)``, since the report's tables give numbers without one."""
        return f"{label} ({unit_text(self.unit)})" if label_shown(self.quantity) else label


@dataclass(frozen=True)
class ResultRow:
    point: int
    lab: str
    value: float
    expanded_uncertainty: float
    coverage_factor: float


@dataclass(frozen=True)
class AssignedRow:
    """x_pt, u(x_pt), the method and σ_pt of one point (docs/domain.md §5)."""

    point: int
    value: float
    standard_uncertainty: float
    method: str
    sigma_pt: float | None
    notes: str = ""
    coverage_factor: float = 2.0
    excluded: tuple[str, ...] | None = None  # codes left out of the consensus (None: n/a)
    exhaustive: bool = True  # False: the subset is the sequential approximation

    @property
    def expanded_uncertainty(self) -> float:
        """U(x_pt) = k·u(x_pt) (k = 2 unless a reference laboratory reported another)."""
        return self.coverage_factor * self.standard_uncertainty


@dataclass(frozen=True)
class ScoreRow:
    """Scores of one result (docs/domain.md §4); ``z`` holds z or z′ (``z_kind`` says which)."""

    point: int
    lab: str
    d: float
    d_percent: float | None  # None for a phase (docs/domain.md §12)
    en: float
    zeta: float
    z: float | None
    z_kind: str
    flag: str
    z_flag: str
    correlation_applied: bool
    in_assigned_value: bool | None = None
    correlation_failed: bool = False


@dataclass(frozen=True)
class Counts:
    """One score type's flags over some of a laboratory's results, as
    ``analysis.performance.Tally`` counts them: satisfactory, questionable (a warning
    signal), unsatisfactory (an action signal) and not scored."""

    satisfactory: int
    questionable: int
    unsatisfactory: int
    not_scored: int = 0

    @property
    def scored(self) -> int:
        return self.satisfactory + self.questionable + self.unsatisfactory


@dataclass(frozen=True)
class PerformanceLine:
    """The En and z counts of one level of a breakdown (a device, a bench, an axis) or of
    all the laboratory's results (``level`` "all"); ``z`` counts only points with a σ_pt."""

    level: str
    en: Counts
    z: Counts


@dataclass(frozen=True)
class LabSummary:
    """A laboratory's performance summary (docs/domain.md §4, "Performance summary"):
    its counts, by ``breakdowns`` (heading, lines), its largest |En| and |z| (z′ where it
    counts) and, in its own report, its largest scores (``worst_en``, ``worst_z``)."""

    code: str
    total: PerformanceLine
    breakdowns: tuple[tuple[str, tuple[PerformanceLine, ...]], ...] = ()
    max_en: float | None = None
    max_z: float | None = None
    worst_en: tuple[ScoreRow, ...] = ()
    worst_z: tuple[ScoreRow, ...] = ()

    @property
    def n_results(self) -> int:
        return self.total.en.scored + self.total.en.not_scored


@dataclass(frozen=True)
class KitLink:
    """One of a participant's results in a round with kits (docs/domain.md §13, §14): its
    point (index), kit, drift correction and u_drift, and d, U(d), u_link (None: not
    linked, or a round of one kit)."""

    code: str
    point: int
    kit: str
    correction: float
    u_drift: float
    d: float | None
    big_u: float | None
    u_link: float | None


@dataclass(frozen=True)
class KitDrift:
    """One kit at one point as judged by the pilot's repeats (§13)."""

    point: int
    kit: str
    n: int
    model: str
    slope: float
    u_slope: float
    p_value: float | None


@dataclass(frozen=True)
class KitCorrelations:
    """The correlations between the linked participants' degrees of equivalence at one
    point (§14): for a point of few participants the matrix of r (``codes`` and ``matrix``,
    row by row, None where undefined), else its largest pairs (code, code, r)."""

    point: int
    n: int
    codes: tuple[str, ...] = ()
    matrix: tuple[tuple[float | None, ...], ...] = ()
    pairs: tuple[tuple[str, str, float], ...] = ()


@dataclass(frozen=True)
class KitSection:
    """The "Linking and drift" part of a report: what was done, the drift judged per kit
    and point, and the links — every participant's by code in the summary, the reader's
    own in a participant report; the correlations between the degrees of equivalence in
    the summary only."""

    text: str
    drift: tuple[KitDrift, ...]
    notes: tuple[str, ...]
    links: tuple[KitLink, ...]
    linked_round: bool
    correlations: tuple[KitCorrelations, ...] = ()
    correlation_text: str = ""


@dataclass(frozen=True)
class StabilityRow:
    """The pilot's mean before and after circulation at one point (docs/domain.md §7):
    Δ = after − before, En of the two, the 0.3·σ_pt limit (None without σ_pt), the verdict
    and u_stab = |Δ|/√3 when unstable (else 0)."""

    point: int
    before: float
    after: float
    delta: float
    en: float
    limit: float | None
    stable: bool
    u_stab: float


@dataclass(frozen=True)
class MatrixData:
    """Pairwise En between the levels of one factor within one group (docs/domain.md §6)."""

    factor: str
    group: str
    levels: tuple[str, ...]
    values: tuple[float, ...]
    expanded_uncertainties: tuple[float, ...]
    en: tuple[tuple[float, ...], ...]
    incompatible_pairs: int


@dataclass(frozen=True)
class ConsistencyRow:
    """One finding of the ISO 5725-2 tests at a point: a Grubbs side, Cochran, or one
    laboratory's Mandel h or k, with the statistic, its critical values and the verdict."""

    point: int
    test: str
    labs: str
    statistic: float
    critical_5: float
    critical_1: float
    verdict: str


@dataclass(frozen=True)
class ConsistencySummary:
    """The consistency tests of a run (``analysis.consistency``): how many points were
    tested, at how many a test signals (``rows`` lists the findings there, in point order)
    and, per test and reason, at how many points the test did not apply."""

    n_points: int
    n_signalling: int
    not_applicable: tuple[tuple[str, str, int], ...]
    rows: tuple[ConsistencyRow, ...]


@dataclass(frozen=True)
class SpreadRow:
    """All results at one point: their number, min / median / max and how many |En| > limit."""

    point: int
    n: int
    low: float
    median: float
    high: float
    bad: int


@dataclass(frozen=True)
class PointValues:
    """Every lab's result at one point, labs in code order (a point chart's data), with
    what its degrees of equivalence take (``analysis.graph_data.PointData.doe``): each
    result's standard uncertainty U/k and whether its En had the correlation correction
    (inside x_pt, or tried and failed: a sole contributor)."""

    labs: tuple[str, ...]
    values: tuple[float, ...]
    uncertainties: tuple[float, ...]
    standard: tuple[float, ...] = ()
    in_assigned: tuple[bool, ...] = ()


@dataclass(frozen=True, eq=False)
class PointScores:
    """Every lab's En and z (or z′, the one that counts; NaN where the point has none) at
    one point, labs in code order (the sorted score charts' data)."""

    labs: tuple[str, ...]
    en: np.ndarray
    z: np.ndarray


@dataclass(frozen=True, eq=False)
class ResultListing:
    """Every scored result of a large round as columns, for the summary's results table
    (about 60 bytes a row instead of two row objects and a dict entry: about 1 kB).

    Rows are in device (name order), point, lab (code order) order; ``devices`` gives each
    device's name and its rows ``start:stop``.  ``lab`` indexes ``labs`` and ``flag``
    indexes ``flags``; ``z`` holds z or z′ as in :class:`ScoreRow`, NaN when neither."""

    labs: tuple[str, ...]
    flags: tuple[str, ...]
    devices: tuple[tuple[str, int, int], ...]
    point: np.ndarray
    lab: np.ndarray
    value: np.ndarray
    expanded_uncertainty: np.ndarray
    coverage_factor: np.ndarray
    d: np.ndarray
    en: np.ndarray
    zeta: np.ndarray
    z: np.ndarray
    flag: np.ndarray
    inside: np.ndarray | None = None  # per row: 1 in x_pt, 0 not, -1 not applicable
    failed: np.ndarray | None = None  # per row: the correlation correction could not be made

    def __len__(self) -> int:
        return len(self.point)


@dataclass(frozen=True, eq=False)
class RoundStats:
    """Figures over every result and score of a run (:mod:`analysis.reports.rounds`), the
    same in every report of the run: computed once per run, not once per report.

    ``frequency``: per device and quantity kind the device, the kind and its unit, and per
    line (bench direction axis) the frequencies and the median of the results there; ``largest_en``:
    (lab, largest |En|) in code order."""

    n_results: int
    n_scores: int
    n_bad: int
    spread: tuple[SpreadRow, ...]
    point_values: Mapping[int, PointValues]
    largest_en: tuple[tuple[str, float], ...]
    frequency: tuple[
        tuple[str, str, str, tuple[tuple[str, tuple[float, ...], tuple[float, ...]], ...]], ...
    ]
    point_scores: Mapping[int, PointScores] = field(default_factory=dict)


@dataclass(frozen=True, eq=False)
class MandelRound:
    """Mandel's h and k of every participant at every point of a run, as the web's
    ``analysis.graph_data.mandel_data`` reads them: participants by code, the points'
    labels and devices (the chart's groups) and ``core.graphs.MandelGraph``."""

    labs: tuple[str, ...]
    points: tuple[str, ...]
    devices: tuple[str, ...]
    graph: MandelGraph


@dataclass(frozen=True)
class HistoryRound:
    """One round of the participant's history (``analysis.history.RoundSummary``): its code
    and date, the participant's code there, its scored En and z and the satisfactory ones."""

    code: str
    date: datetime
    own_code: str
    en_satisfactory: int
    en_scored: int
    z_satisfactory: int
    z_scored: int


@dataclass(frozen=True)
class HistoryPoint:
    """A comparable point (docs/domain.md §4.1): its label, the rounds it was measured in
    and RSZ / RLP of its z (None: no z in any round)."""

    label: str
    n_rounds: int
    rsz: float | None
    rsz_flag: str
    rlp: float | None
    rlp_flag: str


@dataclass(frozen=True)
class ReportHistory:
    """The participant's own history up to the report's round, never another laboratory's;
    ``trend``: per round (in order) its En and its z at every point, the web's trend chart
    data (``analysis.history.trend_series``)."""

    rounds: tuple[HistoryRound, ...]
    points: tuple[HistoryPoint, ...]
    trend: tuple[tuple[str, tuple[float, ...], tuple[float, ...]], ...] = ()


@dataclass(frozen=True)
class ReportData:
    """Everything printed in one report; the renderer adds nothing but layout."""

    kind: str  # SUMMARY | PARTICIPANT
    provider: str
    comparison_code: str
    comparison_title: str
    report_number: str
    issue_date: datetime  # the run's finish time: fixed by the run, not by the clock
    status: str  # "final" | "preliminary"
    authorised_by: str  # "name, role"; empty when nobody has authorised the report yet
    coordinators: tuple[str, ...]
    software_version: str
    protocol_title: str
    protocol_description: str
    bench_descriptions: tuple[str, ...]
    frequencies_hz: tuple[float, ...]
    amplitudes: tuple[str, ...]
    devices: tuple[DeviceInfo, ...]
    participants: tuple[str, ...]
    reference_code: str | None
    points: tuple[PointInfo, ...]
    results: tuple[ResultRow, ...]
    assigned: tuple[AssignedRow, ...]
    scores: tuple[ScoreRow, ...]
    matrices: tuple[MatrixData, ...]
    en_limit: float = 1.0
    sigma_pt_description: str = "not used (En and ζ only)"
    traceability: str = ""
    stability: str = ""
    stability_rows: tuple[StabilityRow, ...] = ()
    # a round with kits: its drift and link (docs/domain.md §13, §14); None without kits
    kits: KitSection | None = None
    comments: str = ""
    conclusions: str = ""
    own_code: str | None = None
    chart_points: tuple[int, ...] = field(default=())
    # The round's figures; None: computed from ``results`` and ``scores`` (which then hold
    # every row).  A participant report of a large round carries its own rows only.
    stats: RoundStats | None = None
    # The summary of a large round: every result as columns (``results`` and ``scores``
    # are then empty and ``stats`` is given); None: the table lists ``results``.
    listing: ResultListing | None = None
    # The ISO 5725-2 tests; None: the run stored none (a run older than the tests).
    consistency: ConsistencySummary | None = None
    # The participant's own performance summary (a participant report) and every
    # participant's, without their largest scores (the summary report).
    performance: LabSummary | None = None
    performances: tuple[LabSummary, ...] = ()
    # The participant's history over the rounds up to this one (a participant report).
    history: ReportHistory | None = None
    # Mandel's h and k of the run (docs/domain.md §11.1); None: none drawn.
    mandel: MandelRound | None = None
    # The provider's furniture (docs/domain.md §9, the PT_PROVIDER_* settings), printed on
    # the title page; the logo is the path of a PNG or JPEG file ("" or missing: no logo).
    provider_address: str = ""
    provider_accreditation: str = ""
    provider_logo: str = ""

    @property
    def is_participant(self) -> bool:
        return self.kind == PARTICIPANT

    @property
    def round(self) -> RoundStats:
        """``stats``, or the figures of ``results`` and ``scores`` (computed once)."""
        if self.stats is not None:
            return self.stats
        cached = self.__dict__.get("_round")
        if cached is None:
            # here: analysis.reports.rounds imports this module (a cycle)
            from analysis.reports.rounds import stats_of_rows

            cached = stats_of_rows(self.points, self.results, self.scores, self.en_limit)
            object.__setattr__(self, "_round", cached)
        return cached
