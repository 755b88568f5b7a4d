"""Artefact stability for the report (docs/domain.md §7): the pilot's before/after results per
measurement point, checked with :func:`analysis.core.consistency.stability_check`."""

from __future__ import annotations

from collections import defaultdict

import numpy as np

from analysis.core.consistency import stability_check
from analysis.core.groups import Groups
from analysis.reports.data import AssignedRow, StabilityRow
from proficiency.models import Comparison, ReferenceValue

# With no σ_pt the 0.3·σ_pt criterion cannot hold: a tiny positive σ_pt leaves En ≤ 1 alone.
NO_SIGMA = 1e-300
Src = ReferenceValue.Source


def stability_rows(
    comparison: Comparison, index: dict[int, int], assigned: tuple[AssignedRow, ...]
) -> tuple[StabilityRow, ...]:
    """One row per point with pilot results both before and after circulation."""
    found: dict[int, dict[str, list[tuple[float, float]]]] = defaultdict(lambda: defaultdict(list))
    rows = ReferenceValue.objects.filter(
        measurement_point__comparison=comparison,
        source__in=(Src.STABILITY_BEFORE, Src.STABILITY_AFTER),
    ).values_list("measurement_point_id", "source", "value", "standard_uncertainty")
    for pid, source, value, u in rows:
        found[index[pid]][source].append((value, u))
    points = sorted(p for p, by in found.items() if len(by) == 2)
    if not points:
        return ()
    sigma = {a.point: a.sigma_pt for a in assigned}
    before = [v for p in points for v in found[p][Src.STABILITY_BEFORE]]
    after = [v for p in points for v in found[p][Src.STABILITY_AFTER]]
    g_b = _groups(points, found, Src.STABILITY_BEFORE)
    g_a = _groups(points, found, Src.STABILITY_AFTER)
    sig = np.array([sigma.get(p) or NO_SIGMA for p in points])
    check = stability_check(
        [v for v, _ in before],
        [u for _, u in before],
        [v for v, _ in after],
        [u for _, u in after],
        sig,
        (g_b, g_a),
    )
    ybar_b, ybar_a = g_b.mean([v for v, _ in before]), g_a.mean([v for v, _ in after])
    return tuple(
        StabilityRow(
            point=p,
            before=float(ybar_b[i]),
            after=float(ybar_a[i]),
            delta=float(check.delta[i]),
            en=float(check.en[i]),
            limit=0.3 * s if (s := sigma.get(p)) else None,
            stable=bool(check.stable[i]),
            u_stab=float(check.u_stab[i]),
        )
        for i, p in enumerate(points)
    )


def _groups(points: list[int], found: dict, source: str) -> Groups:
    return Groups.from_index(
        [i for i, p in enumerate(points) for _ in found[p][source]], n_groups=len(points)
    )
