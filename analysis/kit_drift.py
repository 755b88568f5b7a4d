"""The drift of the kits in an analysis run (docs/domain.md §13): the kits' measurements
at a chunk's points, the fit of every (kit, point) series of the pilot's repeats, and the
shift and u it gives each observation at its date.  Read from the database and applied by
:mod:`analysis.kit_run`."""

from __future__ import annotations

import dataclasses
import datetime as dt
from collections import defaultdict
from dataclasses import dataclass

import numpy as np

from analysis.core.drift import DriftFit, drift_fit
from analysis.core.groups import CoreInputError, Groups
from analysis.core.phase import wrap
from analysis.kit_link import Measurements
from common.errors import ValidationFailed
from proficiency.models import DriftTreatment


@dataclass(frozen=True)
class Repeats:
    """The kits' measurements at the chunk's points: kit index, group, day, value, u, and
    the linking laboratory's code ('' for the pilot's repeats)."""

    kit: np.ndarray
    group: np.ndarray
    day: np.ndarray
    value: np.ndarray
    u: np.ndarray
    lab: np.ndarray

    def take(self, rows: np.ndarray) -> Repeats:
        return Repeats(*(getattr(self, f.name)[rows] for f in dataclasses.fields(self)))

    def at(self, rows: np.ndarray) -> Measurements:
        return Measurements(self.kit[rows], self.value[rows], self.u[rows], self.lab[rows])


@dataclass(frozen=True)
class Drift:
    """The drift fits of the chunk's series, keyed by (kit index, point group)."""

    fit: DriftFit | None
    series: dict[tuple[int, int], int]
    one_date: list[tuple[int, int]]

    def shift(self, kit: np.ndarray, group: np.ndarray, day: np.ndarray, treatment: str,
              u_day: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
        """Per observation: the value added and the standard uncertainty added, the date's
        own uncertainty ``u_day`` (none: 0) included as b·u_t in either treatment
        (docs/domain.md §13)."""
        shift, u_add = np.zeros(day.size), np.zeros(day.size)
        if self.fit is None:
            return shift, u_add
        s = np.array([self.series.get((int(k), int(g)), -1) for k, g in
                      zip(kit.tolist(), group.tolist(), strict=True)], dtype=np.intp)  # fmt: skip
        on = s >= 0
        shift[on], u_add[on] = self.fit.at_date(
            s[on], day[on], None if u_day is None else u_day[on],
            correct=treatment != DriftTreatment.U_STAB,
        )  # fmt: skip
        return shift, u_add

    def rows(self, kit_names: list[str], g: int, circular: bool) -> list[dict]:
        """Point ``g``'s fits as stored (``KitPointFit.drift``); a phase's value wrapped."""
        f, out = self.fit, []
        for (k, group), s in sorted(self.series.items()):
            if group != g or f is None:
                continue
            p = float(f.p_value[s])
            # t̄ as a date: the day of its number, whose noon stands for the date
            t_mean = dt.date.fromordinal(int(np.floor(f.t_mean[s])))
            out.append({
                "kit": kit_names[k], "n": int(f.n[s]), "model": f.model[s],
                "slope": float(f.slope[s]), "u_slope": float(f.u_slope[s]),
                "p_value": p if np.isfinite(p) else None, "t_mean": t_mean.isoformat(),
                "value": float(wrap(f.value[s]) if circular else f.value[s]),
                "u_value": float(f.u_value[s]),
            })  # fmt: skip
        return out


def drift_of(rep: Repeats) -> Drift:
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
