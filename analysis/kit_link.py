"""One measurement point of a round with several kits linked to one reference
(docs/domain.md §14, ``analysis.core.linking``), from the results of a run's chunk.

Observations: every participant's result on its kit (drift handled as the round says),
the linking laboratories' measurements of the kits of their other loops, and the pilot's
repeat measurements of every kit.  A linking laboratory's measurement carries that
laboratory's own bias (the same unknown as its result), so the laboratory ties its two
kits together; one of a laboratory without a result on a kit at the point, or of the kit
its result is on, is noted and ignored.  The repeats enter as a *transfer series* with an
offset of its own, left out of any weighted mean: they carry the pilot's reproducibility
(the u of a change over time), so they fix how the kits differ, never the level; the level
comes from the pilot's result with its full uncertainty (pilot reference) or from the
laboratories' weighted mean.  With one kit the transfer offset takes up the repeats
entirely and the pilot reference gives today's reference-laboratory numbers.

The reference follows the round's assigned-value method at the point: ``reference`` and
``nominal`` → the pilot (b_pilot = 0; a nominal value is no laboratory, and the pilot is
the one that measured every kit), every consensus method → the weighted mean of the
laboratories.  A participant outside the reference's connected part of the lab–kit graph
is named, not scored.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from analysis.core.groups import CoreInputError
from analysis.core.linking import PILOT, WEIGHTED_MEAN, Linked, lab_components, link
from proficiency.models import AssignedValueMethod

_PILOT_METHODS = {AssignedValueMethod.REFERENCE, AssignedValueMethod.NOMINAL}


@dataclass(frozen=True)
class Measurements:
    """Measurements of kits at one point: kit index, value, u (the pilot's repeats), and
    for a linking laboratory's its code."""

    kit: np.ndarray
    value: np.ndarray
    u: np.ndarray
    codes: np.ndarray | None = None


@dataclass(frozen=True)
class LinkInput:
    """One point: the results (codes, kit index or −1, value, u), the pilot's repeats and
    the linking laboratories' measurements."""

    method: str
    pilot: str | None
    codes: np.ndarray
    kit: np.ndarray
    value: np.ndarray
    u: np.ndarray
    repeats: Measurements
    linking: Measurements
    kit_names: list[str]


@dataclass
class PointLink:
    """The link at one point; ``d``, ``u_d``, ``u_link`` per result (None: not linked);
    ``covariance``: the covariance of the linked participants' d, factored
    (:func:`covariance_record`; empty: not linked)."""

    reference: str = ""
    chi2: float | None = None
    dof: int | None = None
    kit_values: list[dict] = field(default_factory=list)
    unlinked: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    d: list[float | None] = field(default_factory=list)
    u_d: list[float | None] = field(default_factory=list)
    u_link: list[float | None] = field(default_factory=list)
    covariance: dict = field(default_factory=dict)


def reference_of(method: str) -> str:
    return PILOT if method in _PILOT_METHODS else WEIGHTED_MEAN


def link_point(x: LinkInput) -> PointLink:
    """Link one point (module docstring); never raises for the data: what cannot be linked
    is said in ``notes`` and ``unlinked``."""
    n = x.codes.size
    out = PointLink(d=[None] * n, u_d=[None] * n, u_link=[None] * n)
    reference = reference_of(x.method)
    on_kit = x.kit >= 0
    no_kit = sorted(x.codes[~on_kit].tolist())
    if no_kit:
        out.notes.append(f"not on any kit holding this device: {', '.join(no_kit)}")
    if reference == PILOT and (x.pilot is None or x.pilot not in x.codes[on_kit].tolist()):
        who = (
            "the round has no pilot"
            if x.pilot is None
            else f"the pilot {x.pilot} has no result on a kit here"
        )
        out.notes.append(f"not linked: {who}")
        out.unlinked = sorted(x.codes.tolist())
        return out
    rows = np.flatnonzero(on_kit)
    n_labs = rows.size  # laboratory j is result rows[j]; the transfer series is n_labs
    obs = _observations(x, rows, out.notes)
    comp = lab_components(obs.kit, obs.lab)
    if reference == PILOT:
        anchor = comp[int(np.flatnonzero(x.codes[rows] == x.pilot)[0])]
    elif x.repeats.kit.size:
        anchor = comp[n_labs]
    else:  # the part holding the most laboratories, the first of equals
        labels, counts = np.unique(comp[:n_labs], return_counts=True)
        anchor = labels[int(np.argmax(counts))]
    keep_lab = comp == anchor
    apart = rows[~keep_lab[:n_labs]]
    out.unlinked = sorted(x.codes[apart].tolist() + no_kit)
    if apart.size:
        out.notes.append("not linked to the reference by any kit: "
                         + ", ".join(sorted(x.codes[apart].tolist())))  # fmt: skip
    return _solve(x, out, reference, rows, obs, keep_lab)


@dataclass(frozen=True)
class _Observations:
    """The rows of the model: laboratory index (the transfer series last), kit, y, u."""

    lab: np.ndarray
    kit: np.ndarray
    value: np.ndarray
    u: np.ndarray


def _observations(x: LinkInput, rows: np.ndarray, notes: list[str]) -> _Observations:
    """The results on a kit (laboratory j is result ``rows[j]``), the linking laboratories'
    measurements with their laboratory's index, the pilot's repeats as laboratory
    ``rows.size``; what is ignored is said in ``notes``."""
    n_labs, link = rows.size, x.linking
    lab_of = {c: j for j, c in enumerate(x.codes[rows].tolist())}
    codes = link.codes.tolist() if link.codes is not None else []
    lab = np.array([lab_of.get(c, -1) for c in codes], dtype=np.intp)
    own = np.zeros(lab.size, dtype=bool)
    own[lab >= 0] = x.kit[rows[lab[lab >= 0]]] == link.kit[lab >= 0]
    ignored = [f"{c}'s measurement of {x.kit_names[k]} is ignored: "
               + ("it has no result on a kit here" if j < 0 else "its result is on that kit")
               for c, k, j, mine in zip(codes, link.kit.tolist(), lab.tolist(), own.tolist(),
                                        strict=True) if j < 0 or mine]  # fmt: skip
    notes.extend(dict.fromkeys(ignored))  # one note per laboratory and kit, not per date
    take = (lab >= 0) & ~own
    return _Observations(
        lab=np.concatenate([np.arange(n_labs), lab[take],
                            np.full(x.repeats.kit.size, n_labs)]).astype(np.intp),
        kit=np.concatenate([x.kit[rows], link.kit[take], x.repeats.kit]).astype(np.intp),
        value=np.concatenate([x.value[rows], link.value[take], x.repeats.value]),
        u=np.concatenate([x.u[rows], link.u[take], x.repeats.u]),
    )  # fmt: skip


def _solve(
    x: LinkInput, out: PointLink, reference: str, rows: np.ndarray, obs: _Observations,
    keep_lab: np.ndarray,
) -> PointLink:  # fmt: skip
    n_labs = rows.size
    keep = keep_lab[obs.lab]
    y, u = obs.value[keep], obs.u[keep]
    kits, kit_idx = np.unique(obs.kit[keep], return_inverse=True)
    labs, lab_idx = np.unique(obs.lab[keep], return_inverse=True)
    in_mean = labs < n_labs
    pilot = 0
    if reference == PILOT:
        pilot = int(np.flatnonzero(labs == int(np.flatnonzero(x.codes[rows] == x.pilot)[0]))[0])
    try:
        with np.errstate(all="ignore"):  # too large a value: said below, never a warning
            linked = link(y, u, kit_idx, lab_idx, reference=reference, pilot=pilot,
                          in_mean=in_mean)  # fmt: skip
        numbers = (linked.doe, linked.doe_covariance, linked.u_link, linked.kit_value,
                   linked.doe_factor, linked.doe_core)  # fmt: skip
        if not all(np.isfinite(a).all() for a in numbers):
            raise CoreInputError("the results there are too large or their uncertainties "
                                 "too small to compute with")  # fmt: skip
    except (CoreInputError, np.linalg.LinAlgError) as exc:
        out.notes.append(f"not linked: {exc}")
        out.unlinked = sorted(x.codes.tolist())
        return out
    out.reference, out.chi2, out.dof = reference, float(linked.chi2), int(linked.dof)
    out.kit_values = [{"kit": x.kit_names[int(k)], "value": float(v), "u": float(s)}
                      for k, v, s in zip(kits, linked.kit_value, linked.u_kit_value,
                                         strict=True)]  # fmt: skip
    u_d = linked.u_doe
    for j, lab in enumerate(labs.tolist()):
        if lab < n_labs:
            i = int(rows[lab])
            out.d[i], out.u_d[i] = float(linked.doe[j]), float(u_d[j])
            out.u_link[i] = float(linked.u_link[j])
    shown = [(str(x.codes[rows[lab]]), j) for j, lab in enumerate(labs.tolist())
             if lab < n_labs and not (reference == PILOT and j == pilot)]  # fmt: skip
    out.covariance = covariance_record(linked, sorted(shown))
    return out


def covariance_record(linked: Linked, shown: list[tuple[str, int]]) -> dict:
    """The covariance of the degrees of equivalence of the participants ``shown`` (code,
    index in ``linked``), as a run stores it (``KitPointFit.doe_covariance``,
    docs/domain.md §14): ``codes`` in order, ``own`` (each one's own part, 1/Σ(1/u²)),
    ``factor`` (a row of kits + 1 numbers each) and ``core`` ((kits + 1)², row by row), so
    that cov = diag(own) + factor·core·factorᵀ exactly — n·(kits + 2) + (kits + 1)²
    numbers rather than n(n + 1)/2.  The pilot under the pilot reference (d = 0 exactly,
    no uncertainty) and the pilot's repeats (no participant) are not in it."""
    if not shown:
        return {}
    idx = np.array([j for _, j in shown], dtype=np.intp)
    return {
        "codes": [c for c, _ in shown],
        "own": linked.doe_own[idx].tolist(),
        "factor": linked.doe_factor[idx].tolist(),
        "core": linked.doe_core.tolist(),
    }
