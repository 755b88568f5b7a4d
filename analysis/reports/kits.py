"""The data of the "Linking and drift" part of the reports (docs/domain.md §9, §13, §14):
what the run did with the round's kits, the drift judged per kit and point, and the
degrees of equivalence against the one reference with their link uncertainty — every
participant's by code in the summary, the reader's own only in a participant report.
Drawn by ``analysis.reports.kit_section``."""

from __future__ import annotations

import math

from analysis.kit_results import MATRIX_MAX, kit_covariances, kit_fits, kit_scores
from analysis.models import AnalysisRun
from analysis.reports.data import KitCorrelations, KitDrift, KitLink, KitSection
from common.sizes import counted

_DATE = (
    "; t is the date the laboratory stated, else the middle of its holding of the kit, whose "
    "own uncertainty u_t (the holding's length over √12) adds b·u_t"
)
_TREATMENT = {
    "correct": "each result on a drifting kit was corrected to the mean date t̄ of the "
    "pilot's repeats, x − b·(t − t̄), with |t − t̄|·u(b) added to its uncertainty (the "
    "reference corrected to the participant's date)" + _DATE,
    "u_stab": "a drifting kit kept its constant value and each result on it had u_stab(t) = "
    "|b·(t − t̄)|/√3 added to its uncertainty" + _DATE,
}


def kit_section_of_run(run: AnalysisRun, index: dict[int, int]) -> KitSection | None:
    """Every participant's kit rows and the run's drift fits (None: no kits), read once
    per run; :func:`for_reader` keeps what one report may print."""
    fits = list(kit_fits(run))
    if not fits:
        return None
    drift = tuple(
        KitDrift(
            index[f.measurement_point_id],
            d["kit"],
            d["n"],
            d["model"],
            d["slope"],
            d["u_slope"],
            d.get("p_value"),
        )
        for f in fits
        for d in f.drift
    )
    notes = tuple(dict.fromkeys(n for f in fits for n in f.notes))
    linked = [f for f in fits if f.reference]
    links = tuple(
        KitLink(
            k.result.submission.participant.code,
            index[k.result.measurement_point_id],
            k.kit.name if k.kit else "–",
            k.drift_correction,
            k.u_drift,
            k.linked_d,
            None if k.linked_u is None else 2 * k.linked_u,
            k.u_link,
        )
        for k in kit_scores(run)
    )
    treatment = str(run.parameters.get("drift_treatment") or run.comparison.drift_treatment)
    drifting = sum(d.model == "linear" for d in drift)
    text = (
        f"The pilot's repeat measurements judged {counted(len(drift), 'series', 'series')} "
        "of one kit at one point, each a line where its slope is significant at 5 %: "
        f"{drifting} drifting. Where a kit "
        f"drifts, {_TREATMENT.get(treatment, treatment)}; elsewhere nothing changed."
    )
    if linked:
        refs = {f.reference for f in linked}
        ref = " and ".join(
            "the pilot" if r == "pilot" else "the weighted mean of the laboratories"
            for r in sorted(refs)
        )
        text += (
            f" Every participant's degree of equivalence d against one reference, "
            f"{ref}, across the kits was found by least squares over the kits and loops "
            f"at {counted(len(linked), 'point')} (the pilot's repeats and the linking "
            "laboratories' measurements of their other kits linking the kits, the phases "
            "laid on a line about their circular mean); "
            "U(d) = 2·u(d), and u_link is the part of u(d) that is not the laboratory's "
            f"own. {counted(len(fits) - len(linked), 'point')} could not be linked."
        )
    correlations = _correlations(run, index)
    return KitSection(text, drift, notes, links, bool(linked), correlations, _CORRELATED)


_CORRELATED = (
    "Two participants' degrees of equivalence are correlated through the kit values and "
    "the reference they share: r = cov(d<sub>a</sub>, d<sub>b</sub>)/(u(d<sub>a</sub>)·"
    "u(d<sub>b</sub>)), given per point as a matrix for at most "
    f"{MATRIX_MAX} participants, else as the largest |r| (the pilot, whose d is 0, is in "
    "none). The difference of two participants has u²(d<sub>a</sub> − d<sub>b</sub>) = "
    "u²(d<sub>a</sub>) + u²(d<sub>b</sub>) − 2·cov(d<sub>a</sub>, d<sub>b</sub>); every "
    "covariance is in the coordinators' archive (doe_covariance.csv)."
)


def _correlations(run: AnalysisRun, index: dict[int, int]) -> tuple[KitCorrelations, ...]:
    out = []
    for c in kit_covariances(run):
        point, n = index[c.point.pk], len(c.codes)
        if n <= MATRIX_MAX:
            rows = tuple(tuple(x if math.isfinite(x) else None for x in row)
                         for row in c.correlation.tolist())  # fmt: skip
            out.append(KitCorrelations(point, n, tuple(c.codes), rows))
        else:
            out.append(KitCorrelations(point, n, pairs=tuple(c.largest())))
    return tuple(out)


def for_reader(section: KitSection | None, own_code: str | None) -> KitSection | None:
    """The summary keeps every link (by code) and the correlations; a participant report
    its own links only, the run's messages without other participants' codes, and no
    correlation (each is a pair of laboratories)."""
    if section is None or own_code is None:
        return section
    own = tuple(k for k in section.links if k.code == own_code)
    notes = tuple(n for n in section.notes if own_code in n)
    return KitSection(section.text, section.drift, notes, own, section.linked_round)
