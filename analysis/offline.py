"""Output of the offline command ``pt_compare`` (formats.md §4): table, JSON and CSV.

Numbers are kept at full precision in JSON and CSV; only the terminal table
rounds them for reading.
"""

from __future__ import annotations

import io
import json
from collections.abc import Sequence
from typing import Any

from analysis.pipeline import Analysis, to_json
from labs.importers import write_table

SCORE_COLUMNS = [
    "lab", "device", "axis", "frequency_hz", "bench", "direction", "value",
    "expanded_uncertainty", "x_pt", "u_x_pt", "method", "d", "d_percent", "en", "zeta", "z",
    "z_prime", "flag", "z_flag", "correlation_applied", "correlation_failed", "in_assigned_value",
    "exhaustive",
]  # fmt: skip
MATRIX_COLUMNS = ["factor", "group", "level_i", "level_j", "en", "compatible"]


def render(analysis: Analysis, fmt: str) -> str:
    doc = to_json(analysis)
    if fmt == "json":
        return json.dumps(doc, indent=2, ensure_ascii=False) + "\n"
    if fmt == "csv":
        return render_csv(doc)
    return render_table(doc)


def render_csv(doc: dict[str, list[dict[str, Any]]]) -> str:
    """Scores joined with their point's assigned value, one row per result; the
    compatibility matrices follow after one blank line in long form (one row per pair)."""
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


_MATRIX_KEYS = {
    "factor", "levels", "value", "expanded_uncertainty", "en", "incompatible_pairs",
}  # fmt: skip


def _group_label(m: dict[str, Any]) -> str:
    parts = [f"{k}={_fmt(v)}" for k, v in m.items() if k not in _MATRIX_KEYS]
    return ", ".join(parts) or "all results"


def _fmt(v: Any, digits: int = 4) -> str:
    if v is None:
        return "—"
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, float):
        return f"{v:.{digits}f}" if abs(v) < 1e6 else f"{v:.{digits}g}"
    return str(v)


def _table(headers: Sequence[str], rows: Sequence[Sequence[Any]]) -> str:
    cells = [[_fmt(c) for c in r] for r in rows]
    widths = [max([len(h)] + [len(r[i]) for r in cells]) for i, h in enumerate(headers)]
    line = "  ".join(h.ljust(w) for h, w in zip(headers, widths, strict=True)).rstrip()
    out = [line, "  ".join("-" * w for w in widths)]
    numeric = [all(_is_number(r[i]) for r in rows) for i in range(len(headers))]
    out += [
        "  ".join(
            c.rjust(w) if num else c.ljust(w) for c, w, num in zip(r, widths, numeric, strict=True)
        ).rstrip()
        for r in cells
    ]
    return "\n".join(out)


def _is_number(v: Any) -> bool:
    return isinstance(v, int | float) and not isinstance(v, bool)


def approximate_points(analysis: Analysis) -> int:
    """Points whose largest consistent subset is the sequential approximation."""
    exhaustive = analysis.assigned.diagnostics.get("exhaustive")
    return 0 if exhaustive is None else sum(1 for e in exhaustive.tolist() if e is False)


def approximate_warning(n: int) -> str:
    """What to say about ``n`` points whose subset is not the exact one."""
    return (
        f"warning: {n} measurement point(s) have too many results for the exact largest "
        "consistent subset; their subset is the sequential approximation and can be smaller "
        "than the largest (exhaustive: false)"
    )


def render_table(doc: dict[str, list[dict[str, Any]]]) -> str:
    parts = ["ASSIGNED VALUES"]
    if n := sum(1 for a in doc["assigned_values"] if a.get("exhaustive") is False):
        parts.append(approximate_warning(n).capitalize())
    parts.append(_table(
        ["device", "axis", "f/Hz", "bench", "direction", "x_pt", "u(x_pt)", "n", "method"],
        [[a["device"], a["axis"], f"{a['frequency_hz']:g}", a["bench"], a["direction"], a["value"],
          a["standard_uncertainty"], a["n"], a["method"]] for a in doc["assigned_values"]],
    ))  # fmt: skip
    parts += ["", "SCORES (flag from En)"]
    with_z = any("z" in s for s in doc["scores"])
    headers = ["lab", "device", "axis", "f/Hz", "bench", "direction", "value", "U", "d", "En",
               "zeta"] + (["z"] if with_z else []) + ["flag"]  # fmt: skip
    parts.append(_table(headers, [
        [s["lab"], s["device"], s["axis"], f"{s['frequency_hz']:g}", s["bench"], s["direction"],
         s["value"], s["expanded_uncertainty"], s["d"], s["en"], s["zeta"]]
        + ([s.get("z")] if with_z else []) + [s["flag"]]
        for s in doc["scores"]
    ]))  # fmt: skip
    for m in doc["compatibility"]:
        parts += ["", f"COMPATIBILITY of {m['factor']} ({_group_label(m)}): "
                  f"{m['incompatible_pairs']} incompatible pair(s)"]  # fmt: skip
        levels = [str(v) for v in m["levels"]]
        rows = [
            [lvl, m["value"][i], m["expanded_uncertainty"][i], *m["en"][i]]
            for i, lvl in enumerate(levels)
        ]
        parts.append(_table(["level", "mean", "U(k=2)", *[f"En vs {v}" for v in levels]], rows))
    return "\n".join(parts) + "\n"


def write_output(text: str, path: str | None, stdout: io.TextIOBase | Any) -> None:
    if path:
        with open(path, "w", encoding="utf-8", newline="") as f:
            f.write(text)
    else:
        stdout.write(text)
