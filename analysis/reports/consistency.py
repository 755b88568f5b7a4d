"""The ISO 5725-2 consistency tests of a run for its reports, read from the stored records
(``AssignedValue.consistency``, written by the run: ``analysis.consistency``)."""

from __future__ import annotations

from collections import Counter

from analysis.consistency import TEST_NAMES, TESTS, reason_kind, signal_rows
from analysis.models import AnalysisRun, AssignedValue
from analysis.reports.data import ConsistencyRow, ConsistencySummary

_TEST_RANK = {name: i for i, name in enumerate(TEST_NAMES.values())}


def consistency_summary(run: AnalysisRun, index: dict[int, int]) -> ConsistencySummary | None:
    """Counts over every point, the findings of the points where a test signals; None for a
    run stored before the tests existed.  Only the reasons are read for every point (JSON
    keys), the whole record (with each laboratory's h and k) only where a test signals."""
    found = AssignedValue.objects.filter(run=run).order_by()
    keys = ["consistency__signals", *(f"consistency__{t}__reason" for t in TESTS)]
    n_points = n_tested = n_signalling = 0
    counts: Counter[tuple[str, str]] = Counter()
    for signals, *why in found.values_list(*keys):
        n_points += 1
        if signals is None:  # no record at this point
            continue
        n_tested += 1
        n_signalling += bool(signals)
        counts.update((TEST_NAMES[t], reason_kind(r)) for t, r in zip(TESTS, why, strict=True) if r)
    if not n_tested:
        return None
    # read even when no point signals: the queries of a report do not depend on its data
    signalling = found.filter(consistency__signals=True)
    rows = [
        ConsistencyRow(index[pid], **r)
        for pid, rec in signalling.values_list("measurement_point_id", "consistency")
        for r in signal_rows(rec)
    ]
    rows.sort(key=lambda r: (r.point, _TEST_RANK[r.test.split(" (")[0]], r.test, r.labs))
    not_applicable = sorted(((t, why, n) for (t, why), n in counts.items()),
                            key=lambda x: (_TEST_RANK[x[0]], x[1]))  # fmt: skip
    return ConsistencySummary(
        n_points=n_points,
        n_signalling=n_signalling,
        not_applicable=tuple(not_applicable),
        rows=tuple(rows),
    )
