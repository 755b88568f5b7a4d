"""Round-wide figures a report prints, computed once per run from columns (pure, no Django).

A participant report of a large round prints its own rows plus figures about every result
of the round: the spread per point, the point charts (every lab's result at a point), the
largest |En| per lab, the median against frequency and the count of compatible results.
:func:`round_stats` computes them once from numpy columns, so that each of the thousands
of participant reports of a run neither reads nor loops over the whole round; it gives the
same numbers as looping over :class:`~analysis.reports.data.ResultRow` /
:class:`~analysis.reports.data.ScoreRow` tuples (:func:`stats_of_rows`), bit for bit.
"""

from __future__ import annotations

from collections import defaultdict
from collections.abc import Sequence

import numpy as np

from analysis.reports.data import (
    PointInfo,
    PointScores,
    PointValues,
    ResultRow,
    RoundStats,
    ScoreRow,
    SpreadRow,
)


def _median(sorted_values: np.ndarray) -> float:
    """``statistics.median`` of already sorted values (same arithmetic)."""
    n = len(sorted_values)
    mid = n // 2
    if n % 2:
        return float(sorted_values[mid])
    return (float(sorted_values[mid - 1]) + float(sorted_values[mid])) / 2


def _slices(keys: np.ndarray) -> list[tuple[int, int]]:
    """(start, end) of each run of equal values in sorted ``keys``."""
    if not len(keys):
        return []
    cuts = (np.flatnonzero(np.diff(keys)) + 1).tolist()
    return list(zip([0, *cuts], [*cuts, len(keys)], strict=True))


def round_stats(
    points: Sequence[PointInfo],
    codes: Sequence[str],
    results: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray],
    scores: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray],
    en_limit: float,
    doe: tuple[np.ndarray, np.ndarray] | None = None,
) -> RoundStats:
    """The figures of a round from columns: ``results`` = (point index, lab index into
    ``codes``, value, expanded uncertainty), ``scores`` = (point index, lab index, En, z
    or z′ as it counts, NaN for none); ``doe`` = (standard uncertainty U/k, inside x_pt
    with the correlation correction) of each result, the degrees of equivalence's data."""
    rank = np.empty(len(codes), dtype=np.int64)
    rank[sorted(range(len(codes)), key=codes.__getitem__)] = np.arange(len(codes))
    r_point, r_lab, value, unc = (np.asarray(a) for a in results)
    s_point, s_lab, en, z = (np.asarray(a) for a in scores)
    r_point, r_lab = r_point.astype(np.int64), r_lab.astype(np.int64)
    s_point, s_lab = s_point.astype(np.int64), s_lab.astype(np.int64)
    order = np.lexsort((rank[r_lab], r_point))
    r_point, r_lab, value, unc = r_point[order], r_lab[order], value[order], unc[order]
    standard, inside = (None, None) if doe is None else (np.asarray(a)[order] for a in doe)
    bad_at = np.abs(np.asarray(en, dtype=float)) > en_limit
    bad_per_point = np.bincount(s_point[bad_at], minlength=len(points))
    spread, by_point, sorted_values = [], {}, {}
    for start, end in _slices(r_point):
        p = int(r_point[start])
        v = np.sort(value[start:end])
        sorted_values[p] = v
        spread.append(
            SpreadRow(p, end - start, float(v[0]), _median(v), float(v[-1]), int(bad_per_point[p]))
        )
        by_point[p] = PointValues(
            tuple(codes[i] for i in r_lab[start:end].tolist()),
            tuple(value[start:end].tolist()),
            tuple(unc[start:end].tolist()),
            () if standard is None else tuple(standard[start:end].tolist()),
            () if inside is None else tuple(bool(b) for b in inside[start:end].tolist()),
        )
    largest = np.zeros(len(codes))
    np.maximum.at(largest, s_lab, np.abs(np.asarray(en, dtype=float)))
    scored = sorted({int(i) for i in np.unique(s_lab)}, key=codes.__getitem__)
    return RoundStats(
        n_results=len(r_point),
        n_scores=len(s_point),
        n_bad=int(np.count_nonzero(bad_at)),
        spread=tuple(spread),
        point_values=by_point,
        largest_en=tuple((codes[i], float(largest[i])) for i in scored),
        frequency=_frequency(points, sorted_values),
        point_scores=_point_scores(codes, rank, s_point, s_lab, en, z),
    )


def _point_scores(
    codes: Sequence[str],
    rank: np.ndarray,
    point: np.ndarray,
    lab: np.ndarray,
    en: np.ndarray,
    z: np.ndarray,
) -> dict[int, PointScores]:
    """Per point, every lab's En and z in code order."""
    order = np.lexsort((rank[lab], point))
    point, lab = point[order], lab[order]
    en, z = np.asarray(en, dtype=float)[order], np.asarray(z, dtype=float)[order]
    return {
        int(point[start]): PointScores(
            tuple(codes[i] for i in lab[start:end].tolist()), en[start:end], z[start:end]
        )
        for start, end in _slices(point)
    }


def _frequency(
    points: Sequence[PointInfo], sorted_values: dict[int, np.ndarray]
) -> tuple[tuple[str, str, str, tuple[tuple[str, tuple[float, ...], tuple[float, ...]], ...]], ...]:
    """Per device and quantity kind (sorted; a phase or an angular rate is not in its
    device's unit and is never pooled with its magnitude): the device, the kind, the unit
    and, per line "bench direction axis" (sorted), the frequencies and the median of every
    result at them (points of one frequency and line pooled)."""
    pooled: dict[tuple[str, str, str], dict[str, dict[float, list[np.ndarray]]]] = defaultdict(dict)
    for p, v in sorted_values.items():
        info = points[p]
        chart = (info.device, info.quantity, info.unit)
        line = pooled[chart].setdefault(f"{info.bench} {info.direction} {info.axis}", {})
        line.setdefault(info.frequency_hz, []).append(v)
    out = []
    for chart in sorted(pooled):
        series = []
        for label, by_f in sorted(pooled[chart].items()):
            freqs = tuple(sorted(by_f))
            medians = tuple(_median(np.sort(np.concatenate(by_f[f]))) for f in freqs)
            series.append((label, freqs, medians))
        out.append((*chart, tuple(series)))
    return tuple(out)


def stats_of_rows(
    points: Sequence[PointInfo],
    results: Sequence[ResultRow],
    scores: Sequence[ScoreRow],
    en_limit: float,
) -> RoundStats:
    """:func:`round_stats` of row tuples (a summary, a small round, a test's data)."""
    codes = sorted({r.lab for r in results} | {s.lab for s in scores})
    lab = {c: i for i, c in enumerate(codes)}
    corrected = {(s.point, s.lab) for s in scores if s.correlation_applied or s.correlation_failed}
    r_cols = (
        np.array([r.point for r in results], dtype=np.int64),
        np.array([lab[r.lab] for r in results], dtype=np.int64),
        np.array([r.value for r in results], dtype=float),
        np.array([r.expanded_uncertainty for r in results], dtype=float),
    )
    s_cols = (
        np.array([s.point for s in scores], dtype=np.int64),
        np.array([lab[s.lab] for s in scores], dtype=np.int64),
        np.array([s.en for s in scores], dtype=float),
        np.array([np.nan if s.z is None else s.z for s in scores], dtype=float),
    )
    doe = (
        np.array([r.expanded_uncertainty / r.coverage_factor for r in results], dtype=float),
        np.array([(r.point, r.lab) in corrected for r in results], dtype=bool),
    )
    return round_stats(points, codes, r_cols, s_cols, en_limit, doe)
