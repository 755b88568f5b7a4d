"""Output of the offline command ``pt_compare`` (docs/interfaces.md §4): table, JSON and CSV.

Numbers are kept at full precision in JSON and CSV; only the terminal table
rounds them for reading.  JSON (:mod:`analysis.offline_json`) and CSV are written a
chunk of results at a time: a national round's 200,000 or 1,000,000 scores never stand
in memory as one document.
"""

from __future__ import annotations

import csv
import io
import os
import tempfile
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from typing import Any, BinaryIO

import numpy as np

from analysis import consistency
from analysis.offline_json import CHUNK, json_parts
from analysis.pipeline import (
    Analysis,
    compatibility_records,
    json_value,
    point_method,
    score_columns,
    to_json,
)
from common.quantities import DEFAULT as DEFAULT_QUANTITY
from common.quantities import label_shown, shown_group, with_kind
from common.sizes import counted
from labs.importers import write_table
from labs.importers.values import escape_text

SCORE_COLUMNS = [
    "lab", "device", "axis", "frequency_hz", "bench", "direction", "quantity", "value",
    "expanded_uncertainty", "x_pt", "u_x_pt", "method", "d", "d_percent", "en", "zeta", "z",
    "z_prime", "flag", "z_flag", "correlation_applied", "correlation_failed", "in_assigned_value",
    "exhaustive",
]  # fmt: skip
MATRIX_COLUMNS = ["factor", "group", "level_i", "level_j", "en", "compatible"]


class Sink:
    """Where output goes: a binary file, or a text stream (standard output)."""

    def __init__(self, binary: BinaryIO | None = None, text: Any = None) -> None:
        self.binary, self.text = binary, text

    def write(self, data: bytes | str) -> None:
        if self.binary is not None:
            self.binary.write(data.encode() if isinstance(data, str) else data)
        else:  # Django's OutputWrapper adds a line ending unless told not to
            text = data.decode() if isinstance(data, bytes) else data
            if hasattr(self.text, "style_func"):
                self.text.write(text, ending="")
            else:
                self.text.write(text)


def write(analysis: Analysis, fmt: str, sink: Sink, *, indent: int | None = None) -> None:
    if fmt == "json":
        for chunk in json_parts(analysis, indent):
            sink.write(chunk)
    elif fmt == "csv":
        for part in csv_parts(analysis):
            sink.write(part)
    else:
        sink.write(render_table(to_json(analysis)))


def render(analysis: Analysis, fmt: str, *, indent: int | None = None) -> str:
    """The whole output as one string (small tables, tests)."""
    buffer = io.BytesIO()
    write(analysis, fmt, Sink(binary=buffer), indent=indent)
    return buffer.getvalue().decode()


@contextmanager
def output_sink(path: str | None, stdout: Any) -> Iterator[Sink]:
    """Standard output, or ``path`` written under a temporary name and renamed when complete:
    on an error nothing is left at ``path``."""
    if not path:
        yield Sink(text=stdout)
        return
    folder = os.path.dirname(os.path.abspath(path))
    handle, temporary = tempfile.mkstemp(prefix=".pt_compare-", dir=folder)
    try:
        with os.fdopen(handle, "wb", buffering=2**20) as f:
            yield Sink(binary=f)
        os.chmod(temporary, 0o666 & ~_umask())
        os.replace(temporary, path)
    except BaseException:
        os.unlink(temporary)
        raise


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


# --- CSV -------------------------------------------------------------------------------------


def csv_parts(analysis: Analysis) -> Iterator[str]:
    """Scores joined with their point's assigned value, one row per result; the
    compatibility matrices follow after one blank line in long form (one row per pair),
    then after another the consistency tests in long form.
    Cells as :func:`labs.importers.write_table` writes them (full precision, text escaped
    against formula execution), built a column and a chunk at a time."""
    buffer = io.StringIO(newline="")
    writer = csv.writer(buffer, lineterminator="\r\n")
    writer.writerow(SCORE_COLUMNS)
    columns, has_sigma = _score_table(analysis)
    for start in range(0, has_sigma.size, CHUNK):
        rows = slice(start, start + CHUNK)
        cells = [_cells(values[rows]) for values in columns]
        for name in ("z", "z_prime", "z_flag"):  # only where the point has a σ_pt
            column = cells[SCORE_COLUMNS.index(name)]
            for i in np.flatnonzero(~has_sigma[rows]).tolist():
                column[i] = ""
        writer.writerows(zip(*cells, strict=True))
        yield buffer.getvalue()
        buffer.seek(0)
        buffer.truncate()
    yield buffer.getvalue()
    limits = [m.limit for m in analysis.compatibility]
    pairs = _matrix_pairs(compatibility_records(analysis.compatibility), limits)
    if pairs:
        yield "\n" + write_table(pairs, columns=MATRIX_COLUMNS, bom=False).decode()
    yield from consistency_csv(analysis)


def consistency_csv(analysis: Analysis) -> Iterator[str]:
    """The consistency tests in long form (``analysis.consistency.csv_tuples``) after one
    blank line like the matrices, a point at a time; cells as ``write_table`` writes them,
    each distinct text escaped once."""
    buffer = io.StringIO(newline="")
    writer = csv.writer(buffer, lineterminator="\r\n")
    buffer.write("\n")
    writer.writerow(consistency.CSV_COLUMNS)
    text: dict[object, str] = {}

    def cell(value: object) -> str:
        if type(value) is float:
            return repr(value)
        found = text.get(value)
        if found is None:
            found = text[value] = _cell(value)
        return found

    for rec in consistency.iter_records(analysis):
        writer.writerows([[cell(v) for v in row] for row in consistency.csv_tuples(rec)])
        if buffer.tell() > 2**20:
            yield buffer.getvalue()
            buffer.seek(0)
            buffer.truncate()
    yield buffer.getvalue()


def _score_table(analysis: Analysis) -> tuple[list[np.ndarray], np.ndarray]:
    """Every column of the score rows in :data:`SCORE_COLUMNS` order (the point's values
    joined to each result), and whether each result's point has a σ_pt."""
    columns, has_sigma = score_columns(analysis)
    a, index = analysis.assigned, analysis.groups.index
    n_points = analysis.groups.n_groups
    methods = np.array([point_method(analysis, g) for g in range(n_points)])
    columns |= {
        "x_pt": _finite_or_none(a.value)[index],
        "u_x_pt": _finite_or_none(a.standard_uncertainty)[index],
        "method": methods.astype(object)[index],
        "exhaustive": _point_diagnostic(a.diagnostics.get("exhaustive"), n_points)[index],
        # a phase has no D% (docs/domain.md §12): an empty cell, as a missing x_pt
        "d_percent": _finite_or_none(columns["d_percent"]),
    }
    return [columns[name] for name in SCORE_COLUMNS], has_sigma


def _point_diagnostic(values: np.ndarray | None, n_points: int) -> np.ndarray:
    """A per-point diagnostic as its assigned-value record has it (None where absent)."""
    out = np.full(n_points, None, dtype=object)
    if values is not None:
        out[:] = [json_value(v) for v in values]
    return out


def _finite_or_none(values: np.ndarray) -> np.ndarray:
    """As ``json_value``: the assigned value's non-finite numbers are left empty."""
    out = values.astype(object)
    out[~np.isfinite(values)] = None
    return out


def _cells(values: np.ndarray) -> list[Any]:
    """``write_table``'s cell for each value: repr of a float, TRUE/FALSE, escaped text,
    empty for None."""
    if values.dtype.kind == "f":
        return list(map(repr, values.tolist()))
    if values.dtype.kind == "b":
        return ["TRUE" if v else "FALSE" for v in values.tolist()]
    items = values.tolist()
    text = {v: _cell(v) for v in set(items)}
    return [text[v] for v in items]


def _cell(value: Any) -> Any:
    if value is None:
        return ""
    if isinstance(value, bool):
        return str(value).upper()
    if isinstance(value, float):
        return repr(value)
    return escape_text(str(value))


def _matrix_pairs(matrices: list[dict[str, Any]], limits: list[float]) -> list[dict[str, Any]]:
    """The matrices in long form; ``compatible`` is En ≤ the run's limit (``--en-limit``)."""
    return [
        {
            "factor": m["factor"],
            "group": _group_label(m),
            "level_i": li,
            "level_j": lj,
            "en": m["en"][i][j],
            "compatible": m["en"][i][j] <= limit,
        }
        for m, limit in zip(matrices, limits, strict=True)
        for i, li in enumerate(m["levels"])
        for j, lj in enumerate(m["levels"])
        if j > i
    ]


def _point(rec: dict[str, Any]) -> tuple[Any, ...]:
    return (rec["device"], rec["axis"], rec["frequency_hz"], rec["bench"], rec["direction"],
            rec.get("quantity", DEFAULT_QUANTITY))  # fmt: skip


def _direction(rec: dict[str, Any]) -> str:
    """The direction column of the text table, with the kind's label where it is not the
    magnitude (``tangential, sensitivity phase``): JSON and CSV keep its name (``phase``)."""
    return with_kind(rec["direction"], rec.get("quantity"))


_MATRIX_KEYS = {
    "factor", "levels", "value", "expanded_uncertainty", "en", "incompatible_pairs",
}  # fmt: skip


def _group_label(m: dict[str, Any], *, words: bool = False) -> str:
    """``device=MEMS 1, axis=X``: the group's keys, the quantity only where it is not the
    magnitude (a table of magnitudes reads as before kinds existed): ``quantity=phase`` in
    the CSV's ``group`` column, the kind's label in the text table (``words``:
    ``device=MEMS 1, axis=X, sensitivity phase``)."""
    group = shown_group({k: v for k, v in m.items() if k not in _MATRIX_KEYS})
    parts = [
        label_shown(str(v)) if words and k == "quantity" else f"{k}={_fmt(v)}"
        for k, v in group.items()
    ]
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
        f"warning: {counted(n, 'measurement point')} {'has' if n == 1 else 'have'} too many "
        "results for the exact largest "
        "consistent subset; their subset is the sequential approximation and can be smaller "
        "than the largest (exhaustive: false)"
    )


def render_table(doc: dict[str, list[dict[str, Any]]]) -> str:
    parts = ["ASSIGNED VALUES"]
    if n := sum(1 for a in doc["assigned_values"] if a.get("exhaustive") is False):
        parts.append(approximate_warning(n).capitalize())
    parts.append(_table(
        ["device", "axis", "f/Hz", "bench", "direction", "x_pt", "u(x_pt)", "n", "method"],
        [[a["device"], a["axis"], f"{a['frequency_hz']:g}", a["bench"], _direction(a), a["value"],
          a["standard_uncertainty"], a["n"], a["method"]] for a in doc["assigned_values"]],
    ))  # fmt: skip
    parts += ["", "SCORES (flag from En)"]
    with_z = any("z" in s for s in doc["scores"])
    headers = ["lab", "device", "axis", "f/Hz", "bench", "direction", "value", "U", "d", "En",
               "zeta"] + (["z"] if with_z else []) + ["flag"]  # fmt: skip
    parts.append(_table(headers, [
        [s["lab"], s["device"], s["axis"], f"{s['frequency_hz']:g}", s["bench"], _direction(s),
         s["value"], s["expanded_uncertainty"], s["d"], s["en"], s["zeta"]]
        + ([s.get("z")] if with_z else []) + [s["flag"]]
        for s in doc["scores"]
    ]))  # fmt: skip
    for m in doc["compatibility"]:
        parts += ["", f"COMPATIBILITY of {m['factor']} ({_group_label(m, words=True)}): "
                  f"{counted(m['incompatible_pairs'], 'incompatible pair')}"]  # fmt: skip
        levels = [str(v) for v in m["levels"]]
        rows = [
            [lvl, m["value"][i], m["expanded_uncertainty"][i], *m["en"][i]]
            for i, lvl in enumerate(levels)
        ]
        parts.append(_table(["level", "mean", "U(k=2)", *[f"En vs {v}" for v in levels]], rows))
    parts += ["", "CONSISTENCY (ISO 5725-2: straggler beyond the 5 % and outlier beyond the 1 % "
              "critical value)", _table(*consistency.table_lines(doc["consistency"]))]  # fmt: skip
    return "\n".join(parts) + "\n"


def write_output(text: str, path: str | None, stdout: io.TextIOBase | Any) -> None:
    if path:
        with open(path, "w", encoding="utf-8", newline="") as f:
            f.write(text)
    else:
        stdout.write(text)
