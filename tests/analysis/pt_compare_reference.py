"""The per-result output code of pt_compare before it was built column-wise (main at
ead3082), kept verbatim as the oracle of the column-wise version: same records, same
CSV text."""

from __future__ import annotations

from typing import Any

import numpy as np

from analysis.core.scores import FLAG_LABELS
from analysis.offline import MATRIX_COLUMNS, SCORE_COLUMNS, _group_label
from analysis.pipeline import Analysis, assigned_records, compatibility_records
from labs.importers import write_table


def score_records(analysis: Analysis) -> list[dict[str, Any]]:
    t, s = analysis.table, analysis.scores
    has_sigma = np.isfinite(analysis.sigma_pt)[analysis.groups.index]
    included, applies = analysis.in_assigned_value
    out = []
    for i in range(t.value.size):
        rec: dict[str, Any] = {
            "device": t.device[i],
            "axis": t.axis[i],
            "frequency_hz": float(t.frequency_hz[i]),
            "bench": t.bench[i],
            "direction": t.direction[i],
            "quantity": t.quantity[i],  # the one key added since (docs/interfaces.md §4)
            "lab": t.lab[i],
            "value": float(t.value[i]),
            "expanded_uncertainty": float(t.expanded_uncertainty[i]),
            "d": float(s.d[i]),
            "d_percent": float(s.d_percent[i]),
            "en": float(s.en[i]),
            "zeta": float(s.zeta[i]),
        }
        if has_sigma[i]:
            rec["z"] = float(s.z[i])
            rec["z_prime"] = float(s.z_prime[i])
            rec["z_flag"] = FLAG_LABELS[s.performance_flag[i]]
        rec["flag"] = FLAG_LABELS[s.en_flag[i]]
        rec["correlation_applied"] = bool(s.correlation_applied[i])
        rec["correlation_failed"] = bool(s.correlation_failed[i])
        rec["in_assigned_value"] = bool(included[i]) if applies[i] else None
        out.append(rec)
    return out


def to_json(analysis: Analysis) -> dict[str, list[dict[str, Any]]]:
    return {
        "assigned_values": assigned_records(analysis),
        "scores": score_records(analysis),
        "compatibility": compatibility_records(analysis.compatibility),
    }


def render_csv(doc: dict[str, list[dict[str, Any]]]) -> str:
    by_point = {_point(a): a for a in doc["assigned_values"]}
    rows = []
    for s in doc["scores"]:
        a = by_point[_point(s)]
        rows.append(
            s | {"x_pt": a["value"], "u_x_pt": a["standard_uncertainty"], "method": a["method"],
                 "exhaustive": a.get("exhaustive")}
        )  # fmt: skip
    out = write_table(rows, columns=SCORE_COLUMNS, bom=False).decode()
    pairs = [
        {
            "factor": m["factor"],
            "group": _group_label(m),
            "level_i": li,
            "level_j": lj,
            "en": m["en"][i][j],
            "compatible": m["en"][i][j] <= 1.0,
        }
        for m in doc["compatibility"]
        for i, li in enumerate(m["levels"])
        for j, lj in enumerate(m["levels"])
        if j > i
    ]
    if pairs:
        out += "\n" + write_table(pairs, columns=MATRIX_COLUMNS, bom=False).decode()
    return out


def _point(rec: dict[str, Any]) -> tuple[Any, ...]:
    return (rec["device"], rec["axis"], rec["frequency_hz"], rec["bench"], rec["direction"])
