"""Kits in an analysis run: the drift of each kit (docs/domain.md §13) and the link of
every participant to one reference across kits and loops (§14).

A chunk of a run calls :func:`kit_prepare` on the results it loaded: in a round without
kits it returns them untouched (today's numbers, bit for bit).  Otherwise

* each result is on the kit of its participant's first slot (earliest start) whose kit
  holds the point's device, at the date its laboratory states, else at the midpoint of
  its holding of the kit, with that date's own uncertainty u_t (:mod:`labs.kit_dates`);
* per kit and point the pilot's repeats (``KitMeasurement`` without a participant, u =
  U/k for a change over time) are fitted by ``analysis.core.drift``; where the slope is
  significant every result on that kit is either corrected to the mean date t̄ of the
  pilot's repeats, x − b·(t − t̄) with u² + (t − t̄)²·u²(b) + b²·u_t² — the same D as the
  reference corrected to the participant's date — or keeps its value with u² +
  u_stab(t)² + b²·u_t², as the round's ``drift_treatment`` says (a linking laboratory's
  measurement of a kit the same, at its stated date: u_t = 0); elsewhere nothing changes;
* with two kits or more, each point is linked by ``analysis.core.linking`` (see
  :mod:`analysis.kit_link`);
* a phase point is drift-fitted and linked on its observations unwrapped about their
  circular mean, and wrapped back (:mod:`analysis.kit_phase`).

The rows to store (:class:`KitOutputs`) are written by the chunk in its own transaction
(:func:`kit_outputs_store`), after deleting any of its points' rows: a retry replaces.
"""

from __future__ import annotations

import dataclasses
import datetime as dt
from dataclasses import dataclass, field

import numpy as np

from analysis.core.phase import wrap
from analysis.kit_drift import Drift, Repeats, drift_of
from analysis.kit_link import LinkInput, PointLink, link_point
from analysis.kit_phase import OnLine, on_line, wrap_link
from analysis.models import AnalysisRun, KitPointFit, KitScore
from analysis.selectors import LoadedRound
from common.quantities import is_circular
from labs.kit_dates import Turn, date_of, day_of, outside
from labs.kit_dates import turns as kit_turns
from labs.models import KitMeasurement, Result
from proficiency.models import Comparison, Kit, KitItem, MeasurementPoint

__all__ = ["KitOutputs", "kit_outputs_delete", "kit_outputs_store", "kit_prepare"]


@dataclass
class KitOutputs:
    """The rows a chunk stores for its points (``run`` set, not saved yet)."""

    fits: list[KitPointFit] = field(default_factory=list)
    scores: list[KitScore] = field(default_factory=list)


@dataclass(frozen=True)
class Round:
    """What the run needs to know about a round's kits."""

    kits: list[Kit]
    holds: set[tuple[int, int]]  # (kit index, device id)
    turns: dict[str, list[Turn]]  # participant code -> its turns, first first
    pilot: str | None
    treatment: str


def _pilot(comparison: Comparison, turns: dict[str, list[Turn]], n_kits: int) -> str | None:
    """The reference laboratory where one is marked; else the participant holding the first
    slot of every kit (the loop starts with the pilot, docs/domain.md §15)."""
    marked = (comparison.participants.filter(is_reference=True).order_by("code")
              .values_list("code", flat=True).first())  # fmt: skip
    if marked:
        return marked
    firsts = [c for c, ts in turns.items() if {t.kit for t in ts if t.position == 1} ==
              set(range(n_kits))]  # fmt: skip
    return sorted(firsts)[0] if firsts else None


def _round(run: AnalysisRun) -> Round | None:
    comparison = run.comparison
    kits = list(Kit.objects.filter(comparison=comparison).order_by("name", "pk"))
    if not kits:
        return None
    index = {k.pk: i for i, k in enumerate(kits)}
    holds = {(index[k], d) for k, d in
             KitItem.objects.filter(kit__in=kits).values_list("kit_id", "device_id")}  # fmt: skip
    turns = kit_turns(comparison, index)
    treatment = run.parameters.get("drift_treatment") or comparison.drift_treatment
    return Round(kits, holds, turns, _pilot(comparison, turns, len(kits)), treatment)


def _repeats(rnd: Round, loaded: LoadedRound) -> Repeats:
    index = {k.pk: i for i, k in enumerate(rnd.kits)}
    group_of = {int(p.pk): g for g, p in enumerate(loaded.points)}
    rows = (KitMeasurement.objects.filter(kit__in=rnd.kits,
                                          measurement_point_id__in=list(group_of))
            .order_by("kit", "measurement_point", "measured_on", "participant__code")
            .values_list("kit_id", "measurement_point_id", "measured_on", "value",
                         "expanded_uncertainty", "coverage_factor",
                         "participant__code"))  # fmt: skip
    cols = list(zip(*rows, strict=True)) or [()] * 7
    return Repeats(
        kit=np.array([index[k] for k in cols[0]], dtype=np.intp),
        group=np.array([group_of[p] for p in cols[1]], dtype=np.intp),
        day=np.array([day_of(d) for d in cols[2]], dtype=np.float64),
        value=np.array(cols[3], dtype=np.float64),
        u=np.array(cols[4], dtype=np.float64) / np.array(cols[5], dtype=np.float64),
        lab=np.array([c or "" for c in cols[6]], dtype=object),
    )


@dataclass(frozen=True)
class Dated:
    """Per result: its kit index (−1: none holds the device for it), its day (NaN) and
    that day's standard uncertainty u_t, whether its participant holds turns on two kits
    or more holding the device, and the note on a stated date outside its holding."""

    kit: np.ndarray
    day: np.ndarray
    u_day: np.ndarray
    several: list[bool]
    strays: list[str]


def _stated(loaded: LoadedRound) -> dict[int, dt.date]:
    """The dates the chunk's results state as measured on, by result id."""
    rows = Result.objects.filter(
        submission_id__in=loaded.submission_ids.tolist(),
        measurement_point_id__in=loaded.point_ids.tolist(), measured_on__isnull=False,
    ).values_list("pk", "measured_on")  # fmt: skip
    return {pk: on for pk, on in rows if on is not None}


def _result_turns(rnd: Round, loaded: LoadedRound) -> Dated:
    """Each result's kit and date: the date its laboratory states (u_t = 0), else its
    turn's (docs/domain.md §13, ``labs.kit_dates``)."""
    stated = _stated(loaded)
    device = np.array([p.device_id for p in loaded.points])[loaded.groups.index]
    n = device.size
    out = Dated(np.full(n, -1), np.full(n, np.nan), np.zeros(n), [], [])
    for i, (code, dev, rid) in enumerate(zip(loaded.table.lab.tolist(), device.tolist(),
                                             loaded.result_id.tolist(), strict=True)):  # fmt: skip
        turns = [t for t in rnd.turns.get(code, []) if (t.kit, dev) in rnd.holds]
        out.several.append(len({t.kit for t in turns}) > 1)
        out.strays.append("")
        if not turns:
            continue
        first, on = turns[0], stated.get(rid)
        out.kit[i] = first.kit
        if on is None:
            out.day[i], out.u_day[i] = first.day, first.u_day
            continue
        out.day[i] = day_of(on)
        held = [t.held for t in turns if t.kit == first.kit]
        if outside(on, held):
            out.strays[i] = _stray(code, on, rnd.kits[first.kit].name, held)
    return out


def _stray(code: str, on: dt.date, kit: str, held: list[tuple[float, float]]) -> str:
    spans = " and ".join(f"{date_of(a)} to {date_of(b)}" for a, b in held)
    return (f"{code} states it measured on {on}, outside its holding of {kit} ({spans}): "
            "the stated date is used")  # fmt: skip


def kit_prepare(run: AnalysisRun, loaded: LoadedRound) -> tuple[LoadedRound, KitOutputs | None]:
    """The chunk's results with the drift handled, and the rows to store; a round without
    kits: the results untouched and None."""
    rnd = _round(run)
    if rnd is None:
        return loaded, None
    # an overflowing result is named by the run's own check of its numbers
    # (``analysis.services._compute_checked``), never stopped here by a warning
    with np.errstate(all="ignore"):
        return _prepare(run, rnd, loaded)


@dataclass(frozen=True)
class Observed:
    """The chunk's observations with the drift handled: per result its kit, day and their
    notes (``Dated``), shift and added u, its value on the line (a phase unwrapped,
    docs/domain.md §14) and u; the kits' measurements the same; and what was fitted."""

    dated: Dated
    shift: np.ndarray
    u_add: np.ndarray
    values: np.ndarray
    u: np.ndarray
    measured: Repeats
    line: OnLine
    drift: Drift


def _observed(rnd: Round, loaded: LoadedRound) -> tuple[Observed, LoadedRound]:
    """The observations, and the results as the scores see them (a phase wrapped back)."""
    rep = _repeats(rnd, loaded)
    circular = np.array([is_circular(p.quantity) for p in loaded.points], dtype=bool)
    line = on_line(loaded.table.value, loaded.groups.index, rep.value, rep.group, circular)
    rep = dataclasses.replace(rep, value=line.measurements)
    # the drift: the pilot's repeats only, a phase's on its line (none where it is refused)
    drift = drift_of(rep.take((rep.lab == "") & ~line.refused[rep.group]))
    dated = _result_turns(rnd, loaded)
    shift, u_add = drift.shift(dated.kit, loaded.groups.index, dated.day, rnd.treatment,
                               dated.u_day)  # fmt: skip
    values = line.results + shift
    adjusted = _adjusted(loaded, _wrapped(values, circular[loaded.groups.index]), shift, u_add)
    r_shift, r_u = drift.shift(rep.kit, rep.group, rep.day, rnd.treatment)
    measured = dataclasses.replace(rep, value=rep.value + r_shift, u=np.hypot(rep.u, r_u))
    return Observed(dated, shift, u_add, values, adjusted.table.standard_uncertainty,
                    measured, line, drift), adjusted  # fmt: skip


def _prepare(run: AnalysisRun, rnd: Round, loaded: LoadedRound) -> tuple[LoadedRound, KitOutputs]:
    o, adjusted = _observed(rnd, loaded)
    outputs = KitOutputs()
    # rows are loaded in point order (``load_round``): each point's rows are one slice
    order = np.argsort(loaded.groups.index, kind="stable")
    ends = np.cumsum(np.bincount(loaded.groups.index, minlength=len(loaded.points)))
    measured_at = _rows_by_group(o.measured.group)
    kit = o.dated.kit
    for g, point in enumerate(loaded.points):
        rows = order[(ends[g - 1] if g else 0) : ends[g]]
        take = measured_at.get(g, np.zeros(0, dtype=np.intp))
        fit, linked = _point_fit(run, rnd, loaded.table.lab[rows], o, g, point, rows, take)
        outputs.fits.append(fit)
        for j, i in enumerate(rows.tolist()):
            outputs.scores.append(KitScore(
                run=run, result_id=int(loaded.result_id[i]),
                kit=rnd.kits[kit[i]] if kit[i] >= 0 else None,
                measured_on=date_of(o.dated.day[i]) if kit[i] >= 0 else None,
                drift_correction=float(o.shift[i]), u_drift=float(o.u_add[i]),
                linked_d=linked.d[j] if linked else None,
                linked_u=linked.u_d[j] if linked else None,
                u_link=linked.u_link[j] if linked else None,
            ))  # fmt: skip
    return adjusted, outputs


def _point_fit(run: AnalysisRun, rnd: Round, codes: np.ndarray, o: Observed, g: int,
               point: MeasurementPoint, rows: np.ndarray,
               take: np.ndarray) -> tuple[KitPointFit, PointLink | None]:  # fmt: skip
    """One point's drift, notes and link (two kits or more, a phase on its line)."""
    circular = bool(o.line.circular[g])
    measured = o.measured.take(take)
    notes = _notes(rnd, o, g, point.device_id, codes, rows, measured)
    fit = KitPointFit(run=run, measurement_point=point, notes=notes,
                      drift=o.drift.rows([k.name for k in rnd.kits], g, circular))  # fmt: skip
    if len(rnd.kits) < 2 or o.line.refused[g]:
        return fit, None
    pilot = measured.lab == ""
    linked = link_point(LinkInput(
        method=point.assigned_value_method or run.comparison.assigned_value_method,
        pilot=rnd.pilot, codes=codes, kit=o.dated.kit[rows], value=o.values[rows], u=o.u[rows],
        repeats=measured.at(pilot), linking=measured.at(~pilot),
        kit_names=[k.name for k in rnd.kits],
    ))  # fmt: skip
    if circular:
        wrap_link(linked)
    fit.reference, fit.chi2, fit.dof = linked.reference, linked.chi2, linked.dof
    fit.kit_values, fit.unlinked = linked.kit_values, linked.unlinked
    fit.doe_covariance = linked.covariance
    fit.notes = notes + linked.notes
    return fit, linked


def _rows_by_group(group: np.ndarray) -> dict[int, np.ndarray]:
    """The indexes of each group's rows, one sort for all."""
    if not group.size:
        return {}
    order = np.argsort(group, kind="stable")
    labels, starts = np.unique(group[order], return_index=True)
    return dict(zip(labels.tolist(), np.split(order, starts[1:]), strict=True))


def _wrapped(values: np.ndarray, circular: np.ndarray) -> np.ndarray:
    """Values with a phase's wrapped back into (−180°, 180°] (docs/domain.md §12)."""
    if not circular.any():
        return values
    return np.where(circular, wrap(np.where(circular, values, 0.0)), values)


def _adjusted(loaded: LoadedRound, moved: np.ndarray, shift: np.ndarray,
              u_add: np.ndarray) -> LoadedRound:  # fmt: skip
    """Values ``moved`` where ``shift`` is not 0 and u² increased by ``u_add``² (U = k·u,
    the result's own k); results with neither keep their stored numbers exactly."""
    changed = (shift != 0) | (u_add != 0)
    if not changed.any():
        return loaded
    t = loaded.table
    u = np.hypot(t.standard_uncertainty, u_add)
    table = dataclasses.replace(
        t, value=np.where(shift != 0, moved, t.value),
        expanded_uncertainty=np.where(changed, t.coverage_factor * u, t.expanded_uncertainty),
    )  # fmt: skip
    return dataclasses.replace(loaded, table=table)


def _notes(rnd: Round, o: Observed, g: int, device: int, codes: np.ndarray, rows: np.ndarray,
           measured: Repeats) -> list[str]:  # fmt: skip
    notes = [f"{rnd.kits[k].name}: the pilot measured it on one date only, no drift judged"
             for k, group in o.drift.one_date if group == g]  # fmt: skip
    refused = o.line.note(g, len(rnd.kits))
    notes += [refused] if refused else []
    pairs = set(zip(measured.lab.tolist(), measured.kit.tolist(), strict=True))
    for code, i in zip(codes.tolist(), rows.tolist(), strict=True):
        if o.dated.several[i] and code != rnd.pilot:
            mine = {k for c, k in pairs if c == code}
            notes.append(_on_two_kits(rnd, code, device, int(o.dated.kit[i]), mine))
    return notes + [o.dated.strays[i] for i in rows.tolist() if o.dated.strays[i]]


def _on_two_kits(rnd: Round, code: str, device: int, k: int, measured: set[int]) -> str:
    """What the run did with a laboratory holding slots on several kits (docs/domain.md
    §14): its result is on its first kit; its measurements of the others link them."""
    others = sorted({t.kit for t in rnd.turns[code] if (t.kit, device) in rnd.holds} - {k})
    n = {1: "two", 2: "three"}.get(len(others), str(len(others) + 1))
    said = (f"{code} holds slots on {n} kits: its result is taken on {rnd.kits[k].name}, "
            "its first slot")  # fmt: skip
    missing = [rnd.kits[j].name for j in others if j not in measured]
    if not missing:
        names = " and ".join(rnd.kits[j].name for j in others)
        return f"{said}, and its measurement of {names} links the kits"
    return (f"{said} (the results table has no kit column); its measurement of "
            f"{' and '.join(missing)} here, stored with that kit's measurements under lab "
            f"{code}, would link the kits")  # fmt: skip


def kit_outputs_delete(run_id: int, first_point_id: int | None = None,
                       last_point_id: int | None = None) -> None:  # fmt: skip
    """Delete the run's kit rows (of the points ``first..last`` when given)."""
    fits = KitPointFit.objects.filter(run_id=run_id)
    scores = KitScore.objects.filter(run_id=run_id)
    if first_point_id is not None:
        span = {"gte": first_point_id, "lte": last_point_id}
        fits = fits.filter(**{f"measurement_point_id__{op}": v for op, v in span.items()})
        scores = scores.filter(**{f"result__measurement_point_id__{op}": v
                                  for op, v in span.items()})  # fmt: skip
    scores.delete()
    fits.delete()


def kit_outputs_store(run: AnalysisRun, first_point_id: int, last_point_id: int,
                      outputs: KitOutputs | None) -> None:  # fmt: skip
    """Replace the chunk's kit rows (inside its transaction): never duplicated."""
    if outputs is None:
        return
    kit_outputs_delete(run.pk, first_point_id, last_point_id)
    KitPointFit.objects.bulk_create(outputs.fits, batch_size=2000)
    KitScore.objects.bulk_create(outputs.scores, batch_size=5000)
