"""Kits in an analysis run: the drift of each kit (docs/domain.md §13) and the link of
every participant to one reference across kits and loops (§14).

A chunk of a run calls :func:`kit_prepare` on the results it loaded: in a round without
kits it returns them untouched (today's numbers, bit for bit).  Otherwise

* each result is on the kit of its participant's first slot (earliest start) whose kit
  holds the point's device, at the date its laboratory states, else at the midpoint of
  its holding of the kit, with that date's own uncertainty u_t (:mod:`analysis.kit_dates`);
* per kit and point the pilot's repeats (``KitMeasurement``, u = U/k for a change over
  time) are fitted by ``analysis.core.drift``; where the slope is significant every
  result on that kit is either corrected to the mean date t̄ of the pilot's repeats,
  x − b·(t − t̄) with u² + (t − t̄)²·u²(b) + b²·u_t² — the same D as the reference
  corrected to the participant's date — or keeps its value with u² + u_stab(t)² +
  b²·u_t², as the round's ``drift_treatment`` says; elsewhere nothing changes;
* with two kits or more, each point is linked by ``analysis.core.linking`` (see
  :mod:`analysis.kit_link`).

The rows to store (:class:`KitOutputs`) are written by the chunk in its own transaction
(:func:`kit_outputs_store`), after deleting any of its points' rows: a retry replaces.
"""

from __future__ import annotations

import dataclasses
import datetime as dt
from collections import defaultdict
from dataclasses import dataclass, field

import numpy as np

from analysis.core.drift import DriftFit, drift_fit
from analysis.core.groups import CoreInputError, Groups
from analysis.kit_dates import Turn, date_of, day_of, outside
from analysis.kit_dates import turns as kit_turns
from analysis.kit_link import LinkInput, link_point
from analysis.models import AnalysisRun, KitPointFit, KitScore
from analysis.selectors import LoadedRound
from common.errors import ValidationFailed
from common.quantities import is_circular
from labs.models import KitMeasurement, Result
from proficiency.models import Comparison, DriftTreatment, Kit, KitItem

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


@dataclass(frozen=True)
class Drift:
    """The drift fits of the chunk's series, keyed by (kit index, point group)."""

    fit: DriftFit | None
    series: dict[tuple[int, int], int]
    one_date: list[tuple[int, int]]

    def shift(self, kit: np.ndarray, group: np.ndarray, day: np.ndarray, treatment: str,
              u_day: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
        """Per observation: the value added and the standard uncertainty added, the date's
        own uncertainty ``u_day`` (none: 0) included as b·u_t in either treatment."""
        shift, u_add = np.zeros(day.size), np.zeros(day.size)
        if self.fit is None:
            return shift, u_add
        s = np.array([self.series.get((int(k), int(g)), -1) for k, g in
                      zip(kit.tolist(), group.tolist(), strict=True)], dtype=np.intp)  # fmt: skip
        f, on = self.fit, s >= 0
        on[on] = f.linear[s[on]]
        dt_, b = day[on] - f.t_mean[s[on]], f.slope[s[on]]
        b_u_t = b * (0.0 if u_day is None else u_day[on])  # hypot(x, 0) is |x| exactly
        if treatment == DriftTreatment.U_STAB:
            u_add[on] = np.hypot(f.u_stab(s[on], day[on]), b_u_t)
        else:
            shift[on] = -b * dt_
            u_add[on] = np.hypot(dt_ * f.u_slope[s[on]], b_u_t)
        return shift, u_add


@dataclass(frozen=True)
class Repeats:
    """The pilot's repeats at the chunk's points: kit index, group, day, value, u."""

    kit: np.ndarray
    group: np.ndarray
    day: np.ndarray
    value: np.ndarray
    u: np.ndarray


def _repeats(rnd: Round, loaded: LoadedRound) -> Repeats:
    index = {k.pk: i for i, k in enumerate(rnd.kits)}
    # a phase lives on a circle: its drift and its link are not fitted on a line (below)
    group_of = {int(p.pk): g for g, p in enumerate(loaded.points) if not is_circular(p.quantity)}
    rows = (KitMeasurement.objects.filter(kit__in=rnd.kits,
                                          measurement_point_id__in=list(group_of))
            .order_by("kit", "measurement_point", "measured_on")
            .values_list("kit_id", "measurement_point_id", "measured_on", "value",
                         "expanded_uncertainty", "coverage_factor"))  # fmt: skip
    cols = list(zip(*rows, strict=True)) or [()] * 6
    return Repeats(
        kit=np.array([index[k] for k in cols[0]], dtype=np.intp),
        group=np.array([group_of[p] for p in cols[1]], dtype=np.intp),
        day=np.array([day_of(d) for d in cols[2]], dtype=np.float64),
        value=np.array(cols[3], dtype=np.float64),
        u=np.array(cols[4], dtype=np.float64) / np.array(cols[5], dtype=np.float64),
    )


def _drift(rep: Repeats) -> Drift:
    """Fit every (kit, point) series measured on two dates or more, all in one call."""
    keys = list(zip(rep.kit.tolist(), rep.group.tolist(), strict=True))
    dates: dict[tuple[int, int], set[float]] = defaultdict(set)
    for key, day in zip(keys, rep.day.tolist(), strict=True):
        dates[key].add(day)
    usable = sorted(k for k, d in dates.items() if len(d) >= 2)
    one = sorted(k for k, d in dates.items() if len(d) < 2)
    if not usable:
        return Drift(None, {}, one)
    series = {k: i for i, k in enumerate(usable)}
    rows = np.array([i for i, k in enumerate(keys) if k in series], dtype=np.intp)
    groups = Groups.from_index(np.array([series[keys[i]] for i in rows]), len(usable))
    try:
        fit = drift_fit(rep.day[rows], rep.value[rows], groups, rep.u[rows])
    except CoreInputError as exc:
        raise ValidationFailed(f"The pilot's repeat measurements cannot be fitted: {exc}") from None
    return Drift(fit, series, one)


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
    turn's (docs/domain.md §13, ``analysis.kit_dates``)."""
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


def _prepare(run: AnalysisRun, rnd: Round, loaded: LoadedRound) -> tuple[LoadedRound, KitOutputs]:
    rep = _repeats(rnd, loaded)
    drift = _drift(rep)
    dated = _result_turns(rnd, loaded)
    kit, day, several = dated.kit, dated.day, dated.several
    shift, u_add = drift.shift(kit, loaded.groups.index, day, rnd.treatment, dated.u_day)
    adjusted = _adjusted(loaded, shift, u_add)
    r_shift, r_u = drift.shift(rep.kit, rep.group, rep.day, rnd.treatment)
    pilot_obs = dataclasses.replace(rep, value=rep.value + r_shift, u=np.hypot(rep.u, r_u))
    outputs = KitOutputs()
    codes = loaded.table.lab
    # rows are loaded in point order (``load_round``): each point's rows are one slice
    order = np.argsort(loaded.groups.index, kind="stable")
    ends = np.cumsum(np.bincount(loaded.groups.index, minlength=len(loaded.points)))
    repeats_of = _rows_by_group(rep.group)
    for g, point in enumerate(loaded.points):
        rows = order[(ends[g - 1] if g else 0) : ends[g]]
        notes = _notes(rnd, drift, g, codes[rows], kit[rows], [several[i] for i in rows])
        notes += [dated.strays[i] for i in rows.tolist() if dated.strays[i]]
        fit = KitPointFit(run=run, measurement_point=point, drift=_drift_rows(rnd, drift, g),
                          notes=notes)  # fmt: skip
        linked = None
        if len(rnd.kits) >= 2 and is_circular(point.quantity):
            notes.append(
                "a phase is not linked across kits: its scores are against the "
                "round's assigned value (docs/domain.md §14)"
            )
        elif len(rnd.kits) >= 2:
            take = repeats_of.get(g, np.zeros(0, dtype=np.intp))
            linked = link_point(LinkInput(
                method=point.assigned_value_method or run.comparison.assigned_value_method,
                pilot=rnd.pilot, codes=codes[rows], kit=kit[rows],
                value=adjusted.table.value[rows],
                u=adjusted.table.standard_uncertainty[rows],
                pilot_kit=pilot_obs.kit[take], pilot_value=pilot_obs.value[take],
                pilot_u=pilot_obs.u[take], kit_names=[k.name for k in rnd.kits],
            ))  # fmt: skip
            fit.reference, fit.chi2, fit.dof = linked.reference, linked.chi2, linked.dof
            fit.kit_values, fit.unlinked = linked.kit_values, linked.unlinked
            fit.notes = notes + linked.notes
        outputs.fits.append(fit)
        for j, i in enumerate(rows.tolist()):
            outputs.scores.append(KitScore(
                run=run, result_id=int(loaded.result_id[i]),
                kit=rnd.kits[kit[i]] if kit[i] >= 0 else None,
                measured_on=date_of(day[i]) if kit[i] >= 0 else None,
                drift_correction=float(shift[i]), u_drift=float(u_add[i]),
                linked_d=linked.d[j] if linked else None,
                linked_u=linked.u_d[j] if linked else None,
                u_link=linked.u_link[j] if linked else None,
            ))  # fmt: skip
    return adjusted, outputs


def _rows_by_group(group: np.ndarray) -> dict[int, np.ndarray]:
    """The indexes of each group's rows, one sort for all."""
    if not group.size:
        return {}
    order = np.argsort(group, kind="stable")
    labels, starts = np.unique(group[order], return_index=True)
    return dict(zip(labels.tolist(), np.split(order, starts[1:]), strict=True))


def _adjusted(loaded: LoadedRound, shift: np.ndarray, u_add: np.ndarray) -> LoadedRound:
    """Values moved by ``shift`` and u² increased by ``u_add``² (U = k·u, the result's own
    k); results with neither keep their stored numbers exactly."""
    changed = (shift != 0) | (u_add != 0)
    if not changed.any():
        return loaded
    t = loaded.table
    u = np.hypot(t.standard_uncertainty, u_add)
    table = dataclasses.replace(
        t, value=np.where(changed, t.value + shift, t.value),
        expanded_uncertainty=np.where(changed, t.coverage_factor * u, t.expanded_uncertainty),
    )  # fmt: skip
    return dataclasses.replace(loaded, table=table)


def _drift_rows(rnd: Round, drift: Drift, g: int) -> list[dict]:
    f, out = drift.fit, []
    for (k, group), s in sorted(drift.series.items()):
        if group != g or f is None:
            continue
        p = float(f.p_value[s])
        out.append({
            "kit": rnd.kits[k].name, "n": int(f.n[s]), "model": f.model[s],
            "slope": float(f.slope[s]), "u_slope": float(f.u_slope[s]),
            "p_value": p if np.isfinite(p) else None, "t_mean": date_of(f.t_mean[s]).isoformat(),
            "value": float(f.value[s]), "u_value": float(f.u_value[s]),
        })  # fmt: skip
    return out


def _notes(rnd: Round, drift: Drift, g: int, codes: np.ndarray, kit: np.ndarray,
           several: list[bool]) -> list[str]:  # fmt: skip
    notes = [f"{rnd.kits[k].name}: the pilot measured it on one date only, no drift judged"
             for k, group in drift.one_date if group == g]  # fmt: skip
    for code, k, two in zip(codes.tolist(), kit.tolist(), several, strict=True):
        if two and code != rnd.pilot:
            notes.append(f"{code} holds slots on two kits: its result is taken on "
                         f"{rnd.kits[k].name}, its first slot (the results table has no kit "
                         "column)")  # fmt: skip
    return notes


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
