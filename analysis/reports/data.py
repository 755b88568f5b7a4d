"""The plain data a PT report needs (domain.md §9): frozen dataclasses, no ORM objects."""

from __future__ import annotations

from dataclasses import dataclass, field
from datetime import datetime

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

    @property
    def label(self) -> str:
        return f"{self.axis}, {self.frequency_hz:g} Hz, {self.bench} {self.direction}"

    @property
    def full_label(self) -> str:
        return f"{self.device}, {self.label}"


@dataclass(frozen=True)
class ResultRow:
    point: int
    lab: str
    value: float
    expanded_uncertainty: float
    coverage_factor: float


@dataclass(frozen=True)
class AssignedRow:
    """x_pt, u(x_pt), the method and σ_pt of one point (domain.md §5)."""

    point: int
    value: float
    standard_uncertainty: float
    method: str
    sigma_pt: float | None
    notes: str = ""


@dataclass(frozen=True)
class ScoreRow:
    """Scores of one result (domain.md §4); ``z`` holds z or z′ (``z_kind`` says which)."""

    point: int
    lab: str
    d: float
    d_percent: float
    en: float
    zeta: float
    z: float | None
    z_kind: str
    flag: str
    z_flag: str
    correlation_applied: bool


@dataclass(frozen=True)
class StabilityRow:
    """The pilot's mean before and after circulation at one point (domain.md §7):
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
    """Pairwise En between the levels of one factor within one group (domain.md §6)."""

    factor: str
    group: str
    levels: tuple[str, ...]
    values: tuple[float, ...]
    expanded_uncertainties: tuple[float, ...]
    en: tuple[tuple[float, ...], ...]
    incompatible_pairs: int


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
    comments: str = ""
    conclusions: str = ""
    own_code: str | None = None
    chart_points: tuple[int, ...] = field(default=())

    @property
    def is_participant(self) -> bool:
        return self.kind == PARTICIPANT
