"""ISO 5725-2 consistency tools per measurement point of a results table (docs/domain.md §6).

Plain Python over :mod:`analysis.core.consistency` (no ORM), used by ``pt_compare`` and by
the analysis runs, so both report the same verdicts.  Each laboratory's result at a point
is its cell: the value is the cell mean; ``repeat_sd`` and ``n_repeats`` (interfaces.md §1,
optional) are its within-laboratory standard deviation and number of repeats.

* Mandel's h (per laboratory, from the cell means) and Grubbs' single and double tests
  (on the cell means) need the results only.  As in ISO 5725-2 §7.3.4 the double test
  applies where the single test finds no outlier; this is one pass (nothing is removed
  and tested again);
* Mandel's k (per laboratory) and Cochran's C (the largest variance) need the repeat data,
  from at least two laboratories, all with the **same** number of repeats: the critical
  values of ISO 5725-2 Tables 4 and 6 hold for equal n only, so with unequal n both are
  "not applicable" (rather than the standard's rule of thumb of the most frequent n).

Every test is judged at 5 % (straggler) and 1 % (outlier); a test the data do not allow is
"not applicable" with its reason, never a number.  All points are computed at once by the
core; only the records (one per point, one entry per laboratory) are built in Python.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any

import numpy as np

from analysis import circular as circ
from analysis.core import consistency as iso
from analysis.core.groups import Groups
from common.points import POINT_FIELDS
from common.quantities import with_kind

if TYPE_CHECKING:
    from analysis.pipeline import Analysis, ResultTable

VERDICTS = ("correct", "straggler", "outlier")
NA = "not applicable"
TESTS = ("grubbs_single", "grubbs_double", "cochran", "mandel_h", "mandel_k")
_DOUBLE_MAX = 40  # ISO 5725-2 Table 5 stops at 40 laboratories


@dataclass(frozen=True)
class Consistency:
    """The core's answers for every point (``groups``) and result, with what applies.

    ``codes``: the laboratories' codes, sorted; ``lab`` per result its index in ``codes``
    (the core's lab index); ``has_repeats`` per result; ``reasons`` per test and point
    ("" where the test applies); ``extremes`` per point the result indexes of the lowest,
    second lowest, second highest and highest value; ``worst_h`` / ``worst_k`` per point
    the worst code of a laboratory's h / k."""

    mandel: iso.Mandel
    grubbs: iso.Grubbs
    cochran: iso.Cochran
    codes: np.ndarray
    lab: np.ndarray
    has_repeats: np.ndarray
    reasons: dict[str, np.ndarray]
    extremes: np.ndarray
    worst_h: np.ndarray
    worst_k: np.ndarray


def compute(table: ResultTable, groups: Groups) -> Consistency:
    """Mandel h and k, Grubbs single and double, Cochran for all points at once."""
    has = np.isfinite(table.repeat_sd) & (table.n_repeats >= 2)
    codes, lab = np.unique(table.lab, return_inverse=True)
    lab = lab.reshape(-1)
    n = np.where(has, table.n_repeats, 1)
    sd = np.where(has, table.repeat_sd, 0.0)
    cells = iso.cells_from_summaries(table.value, sd, n, lab, groups)
    mandel, grubbs = iso.mandel_cells(cells), iso.grubbs(table.value, groups)
    why = _reasons(grubbs, mandel, has, n, groups)
    h_ok = (why["mandel_h"] == "")[groups.index]
    k_ok = (why["mandel_k"] == "")[groups.index] & has
    worst_h, worst_k = np.zeros(groups.n_groups, np.intp), np.zeros(groups.n_groups, np.intp)
    np.maximum.at(worst_h, groups.index[h_ok], mandel.h_code[h_ok])
    np.maximum.at(worst_k, groups.index[k_ok], mandel.k_code[k_ok])
    return Consistency(mandel, grubbs, iso.cochran_cells(cells), codes, lab, has, why,
                       _extremes(table.value, groups), worst_h, worst_k)  # fmt: skip


def _reasons(
    grubbs: iso.Grubbs, mandel: iso.Mandel, has: np.ndarray, n: np.ndarray, groups: Groups
) -> dict[str, np.ndarray]:
    """Per test and point, why the test is not applicable ("" where it is)."""
    p = groups.counts()
    equal = np.where(grubbs.degenerate, "all laboratory values are equal", "")
    single = np.where(p < 3, _join("fewer than 3 laboratories (p = ", p, ")"), equal)
    double = np.where(p < 4, _join("fewer than 4 laboratories (p = ", p, ")"), equal)
    double = np.where(p > _DOUBLE_MAX, _join(f"more than {_DOUBLE_MAX} laboratories (p = ", p,
                      f"; ISO 5725-2 Table 5 ends at {_DOUBLE_MAX})"), double)  # fmt: skip
    found = (single == "") & (np.maximum(grubbs.code_high, grubbs.code_low) == iso.OUTLIER)
    after = "the single test found an outlier (ISO 5725-2 §7.3.4 applies the double test only "
    double = np.where(found & (double == ""), after + "when it finds none)", double)
    h = np.where(mandel.degenerate_h & (p >= 3), "all laboratory values are equal", single)
    p_rep = np.bincount(groups.index[has], minlength=groups.n_groups)
    lo = np.full(groups.n_groups, np.iinfo(np.int64).max)
    hi = np.zeros(groups.n_groups, dtype=np.int64)
    np.minimum.at(lo, groups.index[has], n[has])
    np.maximum.at(hi, groups.index[has], n[has])
    unequal = _join("unequal numbers of repeats (n from ", lo, " to ", hi,
                    "); the test needs the same n in every laboratory")  # fmt: skip
    rep = np.where(lo != hi, unequal, "")
    rep = np.where(p_rep == 1, "repeat data (repeat_sd, n_repeats) from one laboratory only", rep)
    rep = np.where(p_rep == 0, "no repeat data (repeat_sd, n_repeats)", rep)
    return {"grubbs_single": single, "grubbs_double": double, "cochran": rep, "mandel_h": h,
            "mandel_k": rep}  # fmt: skip


def _join(*parts: object) -> np.ndarray:
    """Element-wise text of strings and integer arrays, one entry per point."""
    out: np.ndarray = np.asarray("", dtype=np.str_)
    for part in parts:
        out = np.char.add(out, np.asarray(part).astype(np.str_))
    return out


def _extremes(value: np.ndarray, groups: Groups) -> np.ndarray:
    """Per point the result indexes of the lowest, second lowest, second highest and highest
    value (the laboratories Grubbs' statistics are about); -1 where a point has too few."""
    order = np.lexsort((value, groups.index))
    counts = groups.counts()
    start = np.cumsum(counts) - counts
    picks = np.stack([start, start + 1, start + counts - 2, start + counts - 1], axis=1)
    ok = np.stack([counts >= 1, counts >= 2, counts >= 2, counts >= 1], axis=1)
    return np.where(ok, order[np.clip(picks, 0, max(order.size - 1, 0))], -1)


# --- records ---------------------------------------------------------------------------------


def consistency_records(analysis: Analysis) -> list[dict[str, Any]]:
    """One record per measurement point (interfaces.md §4 ``consistency``), full precision."""
    return list(iter_records(analysis))


def iter_records(analysis: Analysis) -> Iterator[dict[str, Any]]:
    """:func:`consistency_records` one point at a time: a writer that streams them never
    holds the records of a whole round (one entry per result) at once."""
    return point_records(analysis.table, analysis.groups, analysis.points)


def point_records(
    table: ResultTable, groups: Groups, points: Sequence[tuple[Any, ...]]
) -> Iterator[dict[str, Any]]:
    if table.circular.any():  # phases tested as unwrapped about their centre (domain.md §12)
        linear = circ.linear_values(table.value, table.circular, groups)[0]
        table = replace(table, value=linear)
    c = compute(table, groups)
    by_point = np.lexsort((c.lab, groups.index))  # each point's labs in code order
    bounds = np.concatenate(([0], np.cumsum(groups.counts())))
    labs = _LabColumns(table, c)
    for g, point in enumerate(points):
        rec: dict[str, Any] = dict(zip(POINT_FIELDS, point, strict=True))
        rec |= _point_tests(table, c, g)
        rec["labs"] = labs.entries(by_point[bounds[g] : bounds[g + 1]])
        rec["signals"] = _signals(rec)
        yield rec


def _point_tests(table: ResultTable, c: Consistency, g: int) -> dict[str, Any]:
    m, gr, co, why = c.mandel, c.grubbs, c.cochran, c.reasons
    low, low2, high2, high = (str(table.lab[i]) for i in c.extremes[g])
    cochran_lab = str(c.codes[co.lab[g]]) if co.lab[g] >= 0 else ""
    return {
        "p": int(gr.n[g]),
        "p_repeats": int(co.p[g]),
        "n_repeats": None if why["cochran"][g] else int(co.n[g]),
        "grubbs_single": _test(why["grubbs_single"][g], gr.single_critical_5[g],
                               gr.single_critical_1[g],
                               high=_side([high], gr.g_high[g], gr.code_high[g]),
                               low=_side([low], gr.g_low[g], gr.code_low[g])),
        "grubbs_double": _test(why["grubbs_double"][g], gr.double_critical_5[g],
                               gr.double_critical_1[g],
                               high=_side([high2, high], gr.g_high2[g], gr.code_high2[g]),
                               low=_side([low, low2], gr.g_low2[g], gr.code_low2[g])),
        "cochran": _test(why["cochran"][g], co.critical_5[g], co.critical_1[g],
                         **_side([cochran_lab], co.c[g], co.code[g])),
        "mandel_h": _test(why["mandel_h"][g], m.h_critical_5[g], m.h_critical_1[g],
                          verdict=VERDICTS[c.worst_h[g]]),
        "mandel_k": _test(why["mandel_k"][g], m.k_critical_5[g], m.k_critical_1[g],
                          verdict=VERDICTS[c.worst_k[g]]),
    }  # fmt: skip


def _side(labs: list[Any], statistic: float, code: int) -> dict[str, Any]:
    return {"labs": [str(v) for v in labs], "statistic": float(statistic),
            "verdict": VERDICTS[int(code)]}  # fmt: skip


def _test(reason: str, critical_5: float, critical_1: float, **parts: Any) -> dict[str, Any]:
    """A test at one point: its critical values and verdict, or why it does not apply."""
    if reason:
        return {"applicable": False, "verdict": NA, "reason": str(reason)}
    rec: dict[str, Any] = {"applicable": True, "critical_5": float(critical_5),
                           "critical_1": float(critical_1)}  # fmt: skip
    rec |= parts
    sides = [v["verdict"] for v in parts.values() if isinstance(v, dict)]
    if sides:
        rec["verdict"] = max(sides, key=VERDICTS.index)
    return rec


_FLAGS = (*VERDICTS, NA)  # code 3: not applicable


class _LabColumns:
    """Per result the laboratory's h and k (NaN where they do not apply, also k without
    repeat data) and their flag codes (3: not applicable), as entries of a point's record."""

    def __init__(self, table: ResultTable, c: Consistency) -> None:
        m, why, g = c.mandel, c.reasons, c.mandel.group
        h_ok = (why["mandel_h"] == "")[g]
        k_ok = (why["mandel_k"] == "")[g] & c.has_repeats
        self.lab, self.h, self.k = (
            table.lab,
            np.where(h_ok, m.h, np.nan),
            np.where(k_ok, m.k, np.nan),
        )
        self.hf, self.kf = np.where(h_ok, m.h_code, 3), np.where(k_ok, m.k_code, 3)

    def entries(self, rows: np.ndarray) -> list[dict[str, Any]]:
        flag = _FLAGS
        columns = (a[rows].tolist() for a in (self.lab, self.h, self.hf, self.k, self.kf))
        return [
            {"lab": lab, "h": None if x != x else x, "h_flag": flag[a],
             "k": None if y != y else y, "k_flag": flag[b]}
            for lab, x, a, y, b in zip(*columns, strict=True)
        ]  # fmt: skip


def _signals(rec: dict[str, Any]) -> bool:
    """Whether a test or a laboratory's h or k is a straggler or an outlier at the point."""
    return any(rec[t]["verdict"] in ("straggler", "outlier") for t in TESTS)


# --- text for people and spreadsheets ---------------------------------------------------------


def statistic_text(value: float | None) -> str:
    """A test statistic or critical value as a metrologist writes it: 3 significant digits,
    trailing zeros kept (2.290, 0.0500); "–" for none."""
    if value is None:
        return "–"
    return f"{value:#.3g}".rstrip(".").replace("e+0", "e+").replace("e-0", "e-")


CSV_COLUMNS = ["device", "axis", "frequency_hz", "bench", "direction", "quantity", "test", "side",
               "lab", "statistic", "critical_5", "critical_1", "verdict", "reason"]  # fmt: skip
_NO_REPEATS = "no repeat data from this laboratory"


def csv_rows(records: Sequence[dict[str, Any]]) -> list[dict[str, Any]]:
    """The consistency records in long form: per point, one row per side of each Grubbs
    test, one for Cochran, one per laboratory for Mandel h and k; a test that does not
    apply is one row with its reason."""
    return [dict(zip(CSV_COLUMNS, row, strict=True)) for rec in records for row in csv_tuples(rec)]


def csv_tuples(rec: dict[str, Any]) -> Iterator[tuple[Any, ...]]:
    """:func:`csv_rows` of one record as tuples in :data:`CSV_COLUMNS` order (None: empty)."""
    point = tuple(rec[k] for k in POINT_FIELDS)
    for name in TESTS:
        t = rec[name]
        if not t["applicable"]:
            yield (*point, name, None, None, None, None, None, NA, t["reason"])
            continue
        crit = (t["critical_5"], t["critical_1"])
        if name.startswith("grubbs"):
            for side in ("high", "low"):
                s = t[side]
                yield (*point, name, side, " ".join(s["labs"]), s["statistic"], *crit,
                       s["verdict"], None)  # fmt: skip
        elif name == "cochran":
            yield (*point, name, None, " ".join(t["labs"]), t["statistic"], *crit, t["verdict"],
                   None)  # fmt: skip
        else:
            key, flag = name[-1], f"{name[-1]}_flag"  # mandel_h -> h, mandel_k -> k
            for lab in rec["labs"]:
                value = lab[key]
                yield (*point, name, None, lab["lab"], value, *crit, lab[flag],
                       _NO_REPEATS if value is None else None)  # fmt: skip


def verdict_text(test: dict[str, Any], *, who: bool = True) -> str:
    """One test's verdict in words: "correct", "outlier: L03 high (G = 3.21)", or "not
    applicable: <reason>"."""
    if not test["applicable"]:
        return f"{NA}: {test['reason']}"
    if test["verdict"] == "correct" or not who:
        return str(test["verdict"])
    if "high" not in test and "labs" not in test:  # Mandel: the laboratories say more
        return str(test["verdict"])
    if "labs" in test:  # Cochran
        c = statistic_text(test["statistic"])
        return f"{test['verdict']}: {', '.join(test['labs'])} (C = {c})"
    sides = [s for s in ("high", "low") if test[s]["verdict"] != "correct"]
    return "; ".join(
        f"{test[s]['verdict']}: {', '.join(test[s]['labs'])} {s} "
        f"(G = {statistic_text(test[s]['statistic'])})"
        for s in sides
    )


def detail_text(test: dict[str, Any]) -> str:
    """A Grubbs or Cochran test's statistics with the laboratories they are about:
    "high L04, G = 2.44; low L09, G = 0.759", "largest variance L07, C = 0.861"; or why the
    test does not apply."""
    if not test["applicable"]:
        return f"{NA}: {test['reason']}"
    if "labs" in test:
        return (
            f"largest variance {', '.join(test['labs'])}, C = {statistic_text(test['statistic'])}"
        )
    return "; ".join(
        f"{s} {', '.join(test[s]['labs'])}, G = {statistic_text(test[s]['statistic'])}"
        for s in ("high", "low")
    )


def flagged_labs(rec: dict[str, Any], key: str) -> str:
    """The laboratories whose h (``key`` "h") or k is a straggler or an outlier, e.g.
    "L03 outlier (h = 3.12), L07 straggler (h = -2.01)"; "none"; or "not applicable"."""
    if not rec[f"mandel_{key}"]["applicable"]:
        return NA
    found = [
        f"{lab['lab']} {lab[f'{key}_flag']} ({key} = {statistic_text(lab[key])})"
        for lab in rec["labs"]
        if lab[f"{key}_flag"] in ("straggler", "outlier")
    ]
    return ", ".join(found) or "none"


def not_applicable(rec: dict[str, Any]) -> str:
    """The reasons of the tests that do not apply at the point, tests sharing a reason
    named together ("Cochran, Mandel k: no repeat data (repeat_sd, n_repeats)")."""
    by_reason: dict[str, list[str]] = {}
    for name in TESTS:
        if not rec[name]["applicable"]:
            by_reason.setdefault(rec[name]["reason"], []).append(TEST_NAMES[name])
    return "; ".join(f"{', '.join(names)}: {why}" for why, names in by_reason.items())


TEST_NAMES = {"grubbs_single": "Grubbs", "grubbs_double": "double Grubbs",
              "cochran": "Cochran", "mandel_h": "Mandel h", "mandel_k": "Mandel k"}  # fmt: skip


def table_lines(records: Sequence[dict[str, Any]]) -> tuple[list[str], list[list[str]]]:
    """The terminal table of ``pt_compare``: headers and one row per point."""
    headers = ["device", "axis", "f/Hz", "bench", "direction", "p", "Grubbs", "double Grubbs",
               "Cochran", "Mandel h", "Mandel k", "not applicable"]  # fmt: skip
    rows = [
        [r["device"], r["axis"], f"{r['frequency_hz']:g}", r["bench"],
         with_kind(r["direction"], r.get("quantity")),
         str(r["p"]), *(verdict_text(r[t], who=True) if r[t]["applicable"] else "n/a"
                         for t in ("grubbs_single", "grubbs_double", "cochran")),
         *(flagged_labs(r, key) if r[f"mandel_{key}"]["applicable"] else "n/a"
           for key in ("h", "k")), not_applicable(r) or "–"]
        for r in records
    ]  # fmt: skip
    return headers, rows


def signal_rows(rec: dict[str, Any]) -> list[dict[str, Any]]:
    """The findings at one point, one per signalling side of a Grubbs test, Cochran, or
    laboratory with a straggling or outlying h or k: ``test``, ``labs``, ``statistic``,
    ``critical_5``, ``critical_1``, ``verdict`` (what the summary report lists)."""
    bad = ("straggler", "outlier")
    out = []
    for name in TESTS:
        t = rec[name]
        if not t["applicable"]:
            continue
        crit = {"critical_5": t["critical_5"], "critical_1": t["critical_1"]}
        if name.startswith("grubbs"):
            out += [{"test": f"{TEST_NAMES[name]} ({side})", "labs": ", ".join(t[side]["labs"]),
                     "statistic": t[side]["statistic"], **crit, "verdict": t[side]["verdict"]}
                    for side in ("high", "low") if t[side]["verdict"] in bad]  # fmt: skip
        elif name == "cochran" and t["verdict"] in bad:
            out.append({"test": TEST_NAMES[name], "labs": ", ".join(t["labs"]),
                        "statistic": t["statistic"], **crit, "verdict": t["verdict"]})  # fmt: skip
        elif name.startswith("mandel"):
            key = name[-1]
            out += [{"test": TEST_NAMES[name], "labs": lab["lab"], "statistic": lab[key], **crit,
                     "verdict": lab[f"{key}_flag"]}
                    for lab in rec["labs"] if lab[f"{key}_flag"] in bad]  # fmt: skip
    return out


def reason_kind(reason: str) -> str:
    """A reason without its numbers, to count points alike: "unequal numbers of repeats"."""
    return reason.split(" (")[0]
