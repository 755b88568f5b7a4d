"""Measurements of a kit (docs/domain.md §13–§15): the pilot's repeats, from which each
point's drift is judged, and the measurements a linking laboratory makes of a kit of its
other loop, which link the two loops.

One CSV per kit, by column name: a line with ``lab`` empty is the pilot's repeat (U for a
change over time, its reproducibility); a line naming a participant's code is that
laboratory's measurement of this kit (its full U), and the participant must hold a slot
on this kit.  Every bad line is named and nothing is stored unless all are good.
"""

from __future__ import annotations

import csv
import datetime as dt
import io
import math
from dataclasses import dataclass

import numpy as np
from django.db import transaction
from django.db.models import Count

from analysis.core.drift import DriftFit, drift_fit
from analysis.core.groups import CoreInputError, Groups
from analysis.core.phase import circular_mean, unwrap_about, wrap
from common import quantities
from common.errors import ValidationFailed
from common.points import PointKey, point_label
from labs.importers.values import NUMBER_RE, RANGE_TEXT, in_range
from labs.kit_dates import day_of
from labs.kit_dates import turns as kit_turns
from labs.models import KitMeasurement, KitSlot, Participant, Result
from labs.selectors import comparison_table, current_submissions
from proficiency.models import Kit, KitItem, MeasurementPoint

MAX_MEASUREMENTS = 100_000
#: a kit's measurement lies within this many years of its round (:func:`_in_round`)
MEASURED_WITHIN_YEARS = 10
#: the columns of a kit's measurements (docs/domain.md §15): the first eight are required
MEASUREMENT_COLUMNS = ("device", "axis", "frequency_hz", "bench", "direction", "measured_on",
                       "sensitivity", "expanded_uncertainty", "coverage_factor", "lab")  # fmt: skip


def _finite(text: str, what: str, *, positive: bool = False) -> float:
    """A number as the results table reads one (docs/interfaces.md §1): ASCII digits with
    a decimal point, finite, and 0 or of a size the statistics can carry (a pilot's
    1e308 or a U of 1e-320 made the kit's drift, and the run, infinite or NaN)."""
    try:
        value = float(text)
    except ValueError:
        raise ValueError(f"{what} must be a number, got {text[:20]!r}") from None
    if not math.isfinite(value) or (positive and not value > 0):
        raise ValueError(f"{what} must be finite{' and > 0' if positive else ''}")
    if not NUMBER_RE.fullmatch(text):  # float() also reads "1_0" and other scripts' digits
        raise ValueError(f"{what} must be a number in ASCII digits, got {text[:20]!r}")
    if value != 0 and not in_range(abs(value)):
        size = "" if positive else "0 or of a size "
        raise ValueError(f"{what} must be {size}{RANGE_TEXT}, got {text[:20]}")
    return value


def _in_round(day: dt.date, kit: Kit) -> dt.date:
    """A measurement date within :data:`MEASURED_WITHIN_YEARS` of the round (its
    submission deadline, else the day it was created): a mistyped year (2205, 0202) would
    otherwise be a lever arm that decides the kit's drift alone (docs/domain.md §15)."""
    c = kit.comparison
    anchor = (c.submission_deadline or c.created_at).date()
    if abs(day.toordinal() - anchor.toordinal()) > 366 * MEASURED_WITHIN_YEARS:
        raise ValueError(
            f"measured_on {day} is more than {MEASURED_WITHIN_YEARS} years from the round "
            f"(its date {anchor}); check the year"
        )
    return day


def _quantity(text: str) -> str:
    """The optional quantity column (blank or absent: the magnitude)."""
    try:
        return quantities.parse(text)
    except ValueError as problem:
        raise ValueError(f"quantity {problem}") from None


@dataclass(frozen=True)
class _Context:
    """What every line of one kit's file is checked against."""

    kit: Kit
    points: dict[PointKey, int]
    participants: dict[str, int]  # code -> id, of the round
    on_kit: set[int]  # participant ids holding a slot on the kit

    @classmethod
    def of(cls, kit: Kit) -> _Context:
        codes = Participant.objects.filter(comparison_id=kit.comparison_id)
        return cls(
            kit=kit, points=comparison_table(kit.comparison).point_ids,
            participants=dict(codes.values_list("code", "pk")),
            on_kit=set(KitSlot.objects.filter(kit=kit).values_list("participant_id", flat=True)),
        )  # fmt: skip

    def participant(self, code: str) -> int | None:
        """The linking laboratory of a line (None: the pilot's repeat)."""
        if not code:
            return None
        pk = self.participants.get(code)
        if pk is None:
            raise ValueError(f"lab: no participant {code[:40]!r} in this round")
        if pk not in self.on_kit:
            raise ValueError(
                f"lab: {code} holds no slot on {self.kit.name}, so it cannot have measured "
                "it (only the laboratories of its loop do)"
            )
        return pk


def _measurement(ctx: _Context, row: dict[str, str]) -> KitMeasurement:
    def cell(name: str) -> str:
        return (row.get(name) or "").strip()

    text = cell("amplitude_m_s2")
    amplitude = _finite(text, "amplitude_m_s2", positive=True) if text else None
    frequency = _finite(cell("frequency_hz"), "frequency_hz", positive=True)
    key = PointKey(cell("device"), cell("axis"), frequency, cell("bench"), cell("direction"),
                   amplitude, _quantity(cell("quantity")))  # fmt: skip
    point = ctx.points.get(key)
    if point is None:
        raise ValueError(f"{point_label(key)} is not a measurement point of this round")
    try:
        measured_on = dt.date.fromisoformat(cell("measured_on"))
    except ValueError:
        raise ValueError(
            f"measured_on must be a date YYYY-MM-DD, got {cell('measured_on')[:20]!r}"
        ) from None
    _in_round(measured_on, ctx.kit)
    k = cell("coverage_factor")
    return KitMeasurement(
        kit=ctx.kit, measurement_point_id=point, measured_on=measured_on,
        participant_id=ctx.participant(cell("lab")),
        value=quantities.stored_value(key.quantity, _finite(
            cell("sensitivity"), "sensitivity", positive=quantities.kind(key.quantity).positive)),
        expanded_uncertainty=_finite(cell("expanded_uncertainty"), "expanded_uncertainty",
                                     positive=True),
        coverage_factor=_finite(k, "coverage_factor", positive=True) if k else 2.0,
    )  # fmt: skip


@transaction.atomic
def kit_measurements_replace(*, kit: Kit, text: str) -> int:
    """Replace the measurements of ``kit`` with the CSV ``text``: a header line naming the
    columns (:data:`MEASUREMENT_COLUMNS`, in any order; ``amplitude_m_s2`` for points that
    have one, ``coverage_factor`` optional, ``quantity`` optional: blank or absent is the
    magnitude, a phase is stored wrapped into (−180°, 180°]; ``lab`` optional: blank or
    absent is the pilot's repeat, a code that linking laboratory's measurement), then one
    line per measurement.  Every bad line is named and nothing is stored unless all are
    good."""
    try:
        return _measurements_store(kit, csv.DictReader(io.StringIO(text)))
    except csv.Error as exc:  # a field over csv's limit, a broken quote: say so, store nothing
        raise ValidationFailed(f"The measurements are not a readable CSV: {exc}.") from None


def _measurements_store(kit: Kit, reader: csv.DictReader[str]) -> int:
    header = {(c or "").strip() for c in reader.fieldnames or []}
    missing = [c for c in MEASUREMENT_COLUMNS[:8] if c not in header]
    if missing:
        raise ValidationFailed(
            f"The first line must name the columns {', '.join(MEASUREMENT_COLUMNS)} "
            f"(amplitude_m_s2 where a point has one); missing: {', '.join(missing)}."
        )
    rows = [r for r in reader if any((v or "").strip() for v in r.values() if isinstance(v, str))]
    if len(rows) > MAX_MEASUREMENTS:
        raise ValidationFailed(f"At most {MAX_MEASUREMENTS} measurements per kit.")
    ctx = _Context.of(kit)
    found, errors, seen = [], [], set()
    for n, row in enumerate(rows, start=2):
        try:
            if None in row:
                raise ValueError("more fields than the header names")
            m = _measurement(ctx, {k.strip(): v for k, v in row.items()})
            if "\x00" in "".join(v for v in row.values() if isinstance(v, str)):
                raise ValueError("a NUL character in the line")
        except ValueError as exc:
            errors.append({"row": n, "message": str(exc)})
            continue
        once = (m.measurement_point_id, m.measured_on, m.participant_id)
        if once in seen:
            errors.append({"row": n, "message": "a second measurement of this point that day"
                           + (" by this lab" if m.participant_id else "")})  # fmt: skip
        seen.add(once)
        found.append(m)
    if errors:
        raise ValidationFailed(f"The measurements of {kit.name} have errors.",
                               errors=errors[:100])  # fmt: skip
    KitMeasurement.objects.filter(kit=kit).delete()
    KitMeasurement.objects.bulk_create(found, batch_size=5000)
    return len(found)


def kit_linking_counts(kit: Kit) -> list[tuple[str, int]]:
    """The linking laboratories that measured ``kit``: (code, number of measurements)."""
    rows = (KitMeasurement.objects.filter(kit=kit, participant__isnull=False)
            .values_list("participant__code").annotate(n=Count("pk"))
            .order_by("participant__code"))  # fmt: skip
    return [(code, n) for code, n in rows]


@dataclass(frozen=True)
class DriftRow:
    """One point of a kit: the pilot's repeats, the model chosen and what it means for the
    loop: the largest u the drift adds to an observation on this kit, were it not
    corrected (√(u_stab(t)² + b²·u_t²) at each date the analysis gives one, ``u_stab_max``),
    and the unit of the point's values (``unit``, as stored; the slope's is per day)."""

    label: str
    n: int
    first: dt.date
    last: dt.date
    model: str
    value: float
    u_value: float
    slope_per_day: float
    u_slope: float
    p_value: float
    u_stab_max: float
    unit: str = ""

    @property
    def slope_unit(self) -> str:
        return quantities.per_day(self.unit)


def _series_values(series: list[KitMeasurement]) -> list[float]:
    """A series' values on a line: a phase unwrapped about its circular mean (§14)."""
    values = [m.value for m in series]
    if not quantities.is_circular(series[0].measurement_point.quantity):
        return values
    centre = circular_mean(values, Groups.from_index(np.zeros(len(values), dtype=np.intp)))
    return [float(v) for v in unwrap_about(values, centre.mean[0])]


def kit_drift(kit: Kit) -> tuple[list[DriftRow], list[str]]:
    """The drift of every point the pilot measured at least twice on two dates
    (analysis.core.drift; u of a change over time = U/k of each repeat; a phase on its
    values unwrapped about their circular mean, docs/domain.md §14), and notes for the
    points it could not judge.  A linking laboratory's measurements are no repeats.  The
    u_stab shown is the analysis run's for the same data (:func:`_loop_dates`, the one rule
    of ``DriftFit.at_date``, docs/domain.md §13)."""
    rows = list(KitMeasurement.objects.filter(kit=kit)
                .select_related("measurement_point__device", "participant")
                .order_by("measurement_point", "measured_on"))  # fmt: skip
    by_point: dict[int, list[KitMeasurement]] = {}
    for m in rows:
        if m.participant_id is None:
            by_point.setdefault(m.measurement_point_id, []).append(m)
    notes, usable = [], []
    for series in by_point.values():
        label = str(series[0].measurement_point)
        if len({m.measured_on for m in series}) < 2:
            notes.append(f"{label}: measured on one date only, no drift can be judged")
        else:
            usable.append(series)
    if not usable:
        return [], notes
    flat = [m for series in usable for m in series]
    groups = Groups.from_index(np.repeat(np.arange(len(usable)), [len(s) for s in usable]))
    try:
        u = [m.expanded_uncertainty / m.coverage_factor for m in flat]
        days = np.array([day_of(m.measured_on) for m in flat], dtype=np.float64)
        values = [v for series in usable for v in _series_values(series)]
        fit: DriftFit = drift_fit(days, values, groups, u)
    except CoreInputError as exc:
        raise ValidationFailed(str(exc)) from None
    linking = [m for m in rows if m.participant_id is not None]
    dated = _loop_dates(kit, [s[0].measurement_point for s in usable], linking)
    return [_drift_row(fit, g, series, dated[g]) for g, series in enumerate(usable)], notes


#: per point, the days at which the analysis sees a kit and each day's own u_t
LoopDates = tuple[list[float], list[float]]


def _loop_dates(kit: Kit, points: list[MeasurementPoint],
                linking: list[KitMeasurement]) -> list[LoopDates]:  # fmt: skip
    """Per point: the dates (days) and their own standard uncertainties u_t at which the
    analysis run sees this kit (docs/domain.md §13, §14): each participant whose result is
    on it (its first slot on a kit holding the point's device) at the date its current
    accepted result states (u_t = 0), else at its turn's (``labs.kit_dates``: the midpoint
    of its holding, late dispatch clamped); each linking laboratory's measurement of it at
    its own date (u_t = 0)."""
    comparison = kit.comparison
    kits = list(Kit.objects.filter(comparison=comparison).order_by("name", "pk"))
    index = {k.pk: i for i, k in enumerate(kits)}
    mine = index[kit.pk]
    holds = set(KitItem.objects.filter(kit__in=kits).values_list("kit_id", "device_id"))
    turns = kit_turns(comparison, index)
    stated = dict(
        ((code, pid), on) for code, pid, on in Result.objects.filter(
            submission__in=current_submissions(comparison), measured_on__isnull=False,
            measurement_point__in=points,
        ).values_list("submission__participant__code", "measurement_point_id", "measured_on")
    )  # fmt: skip
    out = []
    for point in points:
        days: list[float] = []
        u_days: list[float] = []
        for code, listed in turns.items():
            held = [t for t in listed if (kits[t.kit].pk, point.device_id) in holds]
            if not held or held[0].kit != mine:
                continue
            on = stated.get((code, point.pk))
            days.append(held[0].day if on is None else day_of(on))
            u_days.append(held[0].u_day if on is None else 0.0)
        for m in linking:
            if m.measurement_point_id == point.pk:
                days.append(day_of(m.measured_on))
                u_days.append(0.0)
        out.append((days, u_days))
    return out


def _drift_row(fit: DriftFit, g: int, series: list[KitMeasurement],
               dated: LoopDates) -> DriftRow:  # fmt: skip
    days, u_days = dated
    _, u_add = fit.at_date(np.full(len(days), g), days, u_days, correct=False)
    value = float(fit.value[g])
    point = series[0].measurement_point
    if quantities.is_circular(point.quantity):
        value = float(wrap(value))
    return DriftRow(
        label=str(point), n=int(fit.n[g]),
        first=series[0].measured_on, last=series[-1].measured_on, model=fit.model[g],
        value=value, u_value=float(fit.u_value[g]), slope_per_day=float(fit.slope[g]),
        u_slope=float(fit.u_slope[g]), p_value=float(fit.p_value[g]),
        u_stab_max=float(u_add.max()) if days else 0.0, unit=point.value_unit,
    )  # fmt: skip
