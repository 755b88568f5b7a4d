"""A laboratory's history across rounds (docs/domain.md §4.1): its scores at comparable
points in every published round it took part in, the proportion of satisfactory results per
round, and the combined scores RSZ and RLP of the z that counts per comparable point.

Only published rounds count, each with its published run (the run of its succeeded
publication; a round published without a publication job, its latest succeeded run, which
the participants' results pages show), and only the laboratory's own participations: its
code in each round, never another laboratory's.  Read in a fixed number of queries whatever
the number of rounds: the participations, the published runs (one more where a round has no
publication job) and the scores.  Plain dataclasses out, for the pages and the reports.
"""

from __future__ import annotations

import datetime as dt
import math
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

import numpy as np
from django.db.models import Q, QuerySet

from analysis.core.scores import FLAG_LABELS, rlp, rsz
from analysis.models import AnalysisRun, Publication, Score
from analysis.selectors import with_z_used
from common.numbers import significant
from common.points import format_number
from labs.models import Laboratory, Participant
from proficiency.models import Comparison, ComparisonStatus

SATISFACTORY, WARNING, ACTION, _ = FLAG_LABELS
SCORED = (SATISFACTORY, WARNING, ACTION)
#: frequencies (and amplitudes) closer than this, relatively, are the same (a value typed
#: as 10 in one round and computed as 9.99999999 in another)
RELATIVE_TOLERANCE = 1e-6
_FIELDS = (
    "run_id", "en", "flag", "z_used", "z_is_prime", "z_flag",
    "result__submission__participant_id", "result__measurement_point__device__name",
    "result__measurement_point__device__model", "result__measurement_point__bench",
    "result__measurement_point__direction", "result__measurement_point__axis",
    "result__measurement_point__frequency_hz", "result__measurement_point__amplitude_m_s2",
)  # fmt: skip


@dataclass(frozen=True)
class ComparableKey:
    """What makes points of different rounds one measurand: the device's model (its name
    where no model is given), bench, direction, axis, frequency and excitation amplitude."""

    model: str
    bench: str
    direction: str
    axis: str
    frequency_hz: float
    amplitude_m_s2: float | None

    @property
    def label(self) -> str:
        """``LSM6DSR, X, 5 Hz, linear vertical, 10 m/s²`` (the amplitude where one is set, to
        four significant digits: the curvilinear bench's are computed, 49.78229978 m/s²)."""
        parts = [self.model, self.axis, f"{format_number(self.frequency_hz)} Hz",
                 f"{self.bench} {self.direction}"]  # fmt: skip
        if self.amplitude_m_s2 is not None:
            parts.append(f"{significant(self.amplitude_m_s2, 4)} m/s²")
        return ", ".join(parts)


@dataclass(frozen=True)
class Entry:
    """The laboratory's score at one point of one round (z: the z that counts, or None
    where the point has no σ_pt; ``z_used``: ``z`` or ``z_prime``)."""

    round_code: str
    round_date: dt.datetime
    own_code: str
    device: str
    en: float
    flag: str
    z: float | None
    z_used: str | None
    z_flag: str


@dataclass(frozen=True)
class Combined:
    """RSZ = Σz/√n and RLP = √(Σz²/n) of the z that counts (docs/domain.md §4), n the
    number of z scores at the comparable point, missed rounds left out."""

    rsz: float
    rsz_flag: str
    rlp: float
    rlp_flag: str
    n: int


@dataclass(frozen=True)
class PointHistory:
    key: ComparableKey
    entries: list[Entry]
    combined: Combined | None  # None: no z at this point in any round

    @property
    def n_rounds(self) -> int:
        return len({e.round_code for e in self.entries})


@dataclass(frozen=True)
class RoundSummary:
    """One published round: the laboratory's code there and its satisfactory shares."""

    code: str
    date: dt.datetime
    own_code: str
    run_id: int
    en_satisfactory: int
    en_scored: int
    z_satisfactory: int
    z_scored: int

    @property
    def en_share(self) -> float | None:
        return self.en_satisfactory / self.en_scored if self.en_scored else None

    @property
    def z_share(self) -> float | None:
        return self.z_satisfactory / self.z_scored if self.z_scored else None


@dataclass(frozen=True)
class LabHistory:
    laboratory: str  # its name
    rounds: list[RoundSummary]
    points: list[PointHistory]


Trend = tuple[list[str], list[list[float]], list[list[float]]]


def trend_series(rounds: list[RoundSummary], points: list[PointHistory]) -> Trend:
    """The trend chart's data (``analysis.history_chart``): the rounds' codes in order and,
    per round, the laboratory's En and its z (the one that counts) at every point; drawn
    from the same numbers on ``/lab/history/``, the coordinator's view and the report."""
    codes = [r.code for r in rounds]
    en: dict[str, list[float]] = {c: [] for c in codes}
    z: dict[str, list[float]] = {c: [] for c in codes}
    for point in points:
        for e in point.entries:
            en[e.round_code].append(e.en)
            if e.z is not None:
                z[e.round_code].append(e.z)
    return codes, [en[c] for c in codes], [z[c] for c in codes]


def round_date(comparison: Comparison) -> dt.datetime:
    """The date a round is known by in a history: its submission deadline, else its
    creation."""
    return comparison.submission_deadline or comparison.created_at


def lab_history(
    laboratory: Laboratory,
    *,
    until: dt.datetime | None = None,
    within: QuerySet[Comparison] | None = None,
    run: AnalysisRun | None = None,
) -> LabHistory:
    """``laboratory``'s history over the published rounds it took part in, dated on or
    before ``until`` (every one when None), among ``within`` (a coordinator's rounds).

    ``run``: its round counts too, with this run, published or not: a participant report
    is rendered from its run before its round is published (the final reports are rendered
    first), so ``lab_history(lab, until=round_date(c), run=run)`` is its history up to it."""
    found = lab_histories([laboratory.pk], until=until, within=within, run=run)
    return LabHistory(laboratory.name, *found.get(laboratory.pk, ([], [])))


def lab_histories(
    laboratory_ids: Iterable[int],
    *,
    until: dt.datetime | None = None,
    within: QuerySet[Comparison] | None = None,
    run: AnalysisRun | None = None,
) -> dict[int, tuple[list[RoundSummary], list[PointHistory]]]:
    """:func:`lab_history` of several laboratories at once, in the same fixed number of
    queries (a batch of participant reports): laboratory id → its rounds and points, each
    laboratory's built from its own participations only (missing: none)."""
    participations = _participations(list(laboratory_ids), until, within, run)
    runs = published_runs({p.comparison_id for p in participations})
    if run is not None:
        runs[run.comparison_id] = run.pk
    participations = [p for p in participations if p.comparison_id in runs]
    rows = _score_rows(runs.values(), [p.pk for p in participations])
    rows_of: dict[int, list[tuple[Any, ...]]] = {}
    for r in rows:
        rows_of.setdefault(r[_PARTICIPANT], []).append(r)
    rounds: dict[int, list[RoundSummary]] = {}
    entries: dict[int, list[tuple[ComparableKey, Entry]]] = {}
    for p in participations:
        mine = rows_of.get(p.pk, [])
        rounds.setdefault(p.laboratory_id, []).append(_round(p, runs[p.comparison_id], mine))
        entries.setdefault(p.laboratory_id, []).extend((_key(r), _entry(r, p)) for r in mine)
    return {lab: (found, _points(entries[lab])) for lab, found in rounds.items()}


def _participations(
    laboratory_ids: list[int],
    until: dt.datetime | None,
    within: QuerySet[Comparison] | None,
    run: AnalysisRun | None,
) -> list[Participant]:
    rounds = Q(comparison__status=ComparisonStatus.PUBLISHED)
    if within is not None:
        rounds &= Q(comparison__in=within)
    if run is not None:
        rounds |= Q(comparison_id=run.comparison_id)
    found = Participant.objects.filter(rounds, laboratory_id__in=laboratory_ids).select_related(
        "comparison"
    )
    kept = [p for p in found if until is None or round_date(p.comparison) <= until]
    return sorted(kept, key=lambda p: (round_date(p.comparison), p.comparison.code))


def published_runs(comparison_ids: Iterable[int]) -> dict[int, int]:
    """Comparison id → id of its published run: the run of its latest succeeded publication,
    or, for a round published without a publication job, its latest succeeded run."""
    ids = list(comparison_ids)
    if not ids:
        return {}
    found: dict[int, int] = {}
    jobs = Publication.objects.filter(comparison_id__in=ids, status=Publication.Status.SUCCEEDED)
    for comparison_id, run_id in jobs.order_by("-finished_at", "-pk").values_list(
        "comparison_id", "run_id"
    ):
        found.setdefault(comparison_id, run_id)
    missing = [i for i in ids if i not in found]
    if missing:
        runs = AnalysisRun.objects.filter(
            comparison_id__in=missing, status=AnalysisRun.Status.SUCCEEDED
        ).order_by("-finished_at", "-pk")
        for comparison_id, run_id in runs.values_list("comparison_id", "pk"):
            found.setdefault(comparison_id, run_id)
    return found


_RUN, _EN, _FLAG, _Z, _PRIME, _Z_FLAG, _PARTICIPANT, _DEVICE, _MODEL = range(9)


def _score_rows(run_ids: Iterable[int], participant_ids: list[int]) -> list[tuple[Any, ...]]:
    """The laboratory's scores in the published runs, as tuples of ``_FIELDS``."""
    if not participant_ids:
        return []
    scores = Score.objects.filter(
        run_id__in=list(run_ids), result__submission__participant_id__in=participant_ids
    )
    return list(with_z_used(scores).order_by().values_list(*_FIELDS))


def _key(row: tuple[Any, ...]) -> ComparableKey:
    bench, direction, axis, frequency, amplitude = row[_MODEL + 1 :]
    return ComparableKey(row[_MODEL] or row[_DEVICE], bench, direction, axis, frequency, amplitude)


def _entry(row: tuple[Any, ...], participant: Participant) -> Entry:
    z = row[_Z]
    used = None if z is None else ("z_prime" if row[_PRIME] else "z")
    c = participant.comparison
    return Entry(c.code, round_date(c), participant.code, row[_DEVICE], row[_EN], row[_FLAG],
                 z, used, row[_Z_FLAG])  # fmt: skip


def _round(participant: Participant, run_id: int, rows: list[tuple[Any, ...]]) -> RoundSummary:
    mine = [r for r in rows if r[_PARTICIPANT] == participant.pk]
    en = [r[_FLAG] for r in mine if r[_FLAG] in SCORED]
    z = [r[_Z_FLAG] for r in mine if r[_Z_FLAG] in SCORED]
    c = participant.comparison
    return RoundSummary(
        c.code, round_date(c), participant.code, run_id,
        en_satisfactory=en.count(SATISFACTORY), en_scored=len(en),
        z_satisfactory=z.count(SATISFACTORY), z_scored=len(z),
    )  # fmt: skip


def _close(a: float | None, b: float | None) -> bool:
    if a is None or b is None:
        return a is b
    return math.isclose(a, b, rel_tol=RELATIVE_TOLERANCE)


def comparable(a: ComparableKey, b: ComparableKey) -> bool:
    """The comparable points rule (docs/domain.md §4.1): the same model, bench, direction and
    axis, the frequency and the amplitude equal to ``RELATIVE_TOLERANCE`` (no amplitude is
    comparable only with no amplitude)."""
    return (
        (a.model, a.bench, a.direction, a.axis) == (b.model, b.bench, b.direction, b.axis)
        and _close(a.frequency_hz, b.frequency_hz)
        and _close(a.amplitude_m_s2, b.amplitude_m_s2)
    )


def _points(entries: list[tuple[ComparableKey, Entry]]) -> list[PointHistory]:
    """Entries grouped by comparable key, each group named by its first key in frequency
    order, its entries in round order."""
    groups: dict[tuple[str, ...], list[tuple[ComparableKey, list[Entry]]]] = {}
    order = sorted(entries, key=lambda e: (e[0].frequency_hz, e[0].amplitude_m_s2 or 0.0))
    for key, entry in order:
        same = groups.setdefault((key.model, key.bench, key.direction, key.axis), [])
        group = next((g for g in same if comparable(g[0], key)), None)
        if group is None:
            same.append((key, [entry]))
        else:
            group[1].append(entry)
    out = []
    for key, found in (g for same in groups.values() for g in same):
        found.sort(key=lambda e: (e.round_date, e.round_code, e.device))
        out.append(PointHistory(key, found, combined([e.z for e in found])))
    out.sort(key=lambda p: (p.key.model, p.key.bench, p.key.direction, p.key.axis,
                            p.key.frequency_hz, p.key.amplitude_m_s2 or 0.0))  # fmt: skip
    return out


def combined(z: list[float | None]) -> Combined | None:
    """RSZ and RLP (``analysis.core.scores``) of the scores given, None left out; None when
    there is no z at all."""
    values = np.array([np.nan if v is None else v for v in z], dtype=float)
    if not np.isfinite(values).any():
        return None
    s, r = rsz(values), rlp(values)
    return Combined(float(s.value[0]), FLAG_LABELS[int(s.flag[0])], float(r.value[0]),
                    FLAG_LABELS[int(r.flag[0])], int(s.n_rounds[0]))  # fmt: skip
