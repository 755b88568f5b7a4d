"""pt_compare on a whole national round (a script, not a test).

    .venv/bin/python bench/bench_pt_compare.py [--rows 200000] [--repeat 3] [--only a]

Writes one results table (docs/interfaces.md §1 with a lab column): ``--rows / 100`` laboratories
× 100 distinct measurement points (5 devices × X, Y × 10 frequencies, linear bench),
sensitivities in full precision, laboratory after laboratory, as ``bench_import.py``
does. Then runs, each as its own process, ``--repeat`` rounds of:

  (a) ``manage.py pt_compare FILE --assigned algorithm-a --format json --output OUT``
  (b) the straightforward pt13528 script: csv.DictReader, per point
      ``pt13528.robust.algorithm_a``, per result ``pt13528.scores.en_score`` with
      U(x_pt) = 2 · 1.25 s*/√p (u(x_pt) of ISO 13528 7.7.3, as the service), json.dump
  (c) the floor: pandas.read_csv of the same file, the same number of score records
      with the same keys as (a), written with (a)'s encoder (orjson)

and reports for each the best wall time, its CPU time (user + system, from ``wait4``:
less disturbed by other work on a shared machine) and the peak RSS (the child's own
``VmHWM``: ``ru_maxrss`` of a child started by vfork would include this process's peak).

Targets (200,000 rows): (a) ≤ 0.5 × (b), (a) ≤ 2 × (c), peak RSS of (a) ≤ 400 MB;
``--rows 1000000``: (a) under 1 GB.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
DEVICES, AXES, FREQUENCIES = 5, ("X", "Y"), range(10, 110, 10)
HEADER = "lab,device,axis,frequency_hz,bench,direction,sensitivity,expanded_uncertainty\n"

#: Runs a script in the child, then reports the child's own peak RSS on stderr.
CHILD = """
import runpy, sys
script, sys.argv = sys.argv[1], sys.argv[1:]
try:
    runpy.run_path(script, run_name="__main__")
finally:
    with open("/proc/self/status") as status:
        peak = next(int(x.split()[1]) for x in status if x.startswith("VmHWM:"))
    print("peak-rss-kib", peak, file=sys.stderr)
"""

NAIVE = '''
"""The straightforward pt13528 script: Algorithm A per point, En per result, json.dump."""
import csv, json, math, sys
from collections import defaultdict

from pt13528.robust import algorithm_a
from pt13528.scores import en_score

POINT = ("device", "axis", "frequency_hz", "bench", "direction")
groups = defaultdict(list)
with open(sys.argv[1], newline="", encoding="utf-8-sig") as f:
    for r in csv.DictReader(f):
        groups[tuple(r[k] for k in POINT)].append(r)
assigned, scores = [], []
for key, rows in groups.items():
    x = [float(r["sensitivity"]) for r in rows]
    a = algorithm_a(x)
    u_pt = 1.25 * a.scale / math.sqrt(len(x))
    point = dict(zip(POINT, key))
    point["frequency_hz"] = float(point["frequency_hz"])
    assigned.append(point | {"value": a.location, "standard_uncertainty": u_pt, "n": len(x)})
    for r, xi in zip(rows, x):
        big_u = float(r["expanded_uncertainty"])
        en = en_score(xi, a.location, big_u, 2 * u_pt)
        scores.append(point | {"lab": r["lab"], "value": xi, "expanded_uncertainty": big_u,
                               "en": en})
with open(sys.argv[2], "w") as f:
    json.dump({"assigned_values": assigned, "scores": scores}, f)
'''

FLOOR = '''
"""The floor: read the table with pandas, write as many score records with (a)'s keys."""
import sys

import orjson
import pandas as pd

KEYS = ("device", "axis", "frequency_hz", "bench", "direction", "lab", "value",
        "expanded_uncertainty", "d", "d_percent", "en", "zeta", "flag",
        "correlation_applied", "correlation_failed", "in_assigned_value")
df = pd.read_csv(sys.argv[1], dtype={"lab": str, "device": str, "axis": str, "bench": str,
                                     "direction": str})
n = len(df)
value = df["sensitivity"].tolist()
columns = [df[k].tolist() for k in ("device", "axis", "frequency_hz", "bench", "direction",
                                     "lab")]
columns += [value, df["expanded_uncertainty"].tolist(), value, value, value, value,
            ["satisfactory"] * n, [False] * n, [False] * n, [True] * n]
scores = [dict(zip(KEYS, row)) for row in zip(*columns)]
with open(sys.argv[2], "wb") as f:
    f.write(orjson.dumps({"assigned_values": [], "scores": scores, "compatibility": []}))
'''


@dataclass
class Run:
    wall: float
    cpu: float
    peak_mib: float
    status: int
    stderr: str


def write_file(path: Path, n_labs: int) -> None:
    rng = np.random.default_rng(13528)
    points = [(d, a, f) for d in range(1, DEVICES + 1) for a in AXES for f in FREQUENCIES]
    values = 415 + rng.normal(0, 2, (n_labs, len(points)))
    values[rng.random(values.shape) < 0.01] += 40  # 1 % outliers
    uncertainties = values * rng.uniform(0.01, 0.03, values.shape)
    with open(path, "w", encoding="utf-8", newline="") as out:
        out.write(HEADER)
        for lab, vs, us in zip(range(n_labs), values.tolist(), uncertainties.tolist(), strict=True):
            out.writelines(
                f"L{lab:05d},MEMS {d},{a},{f},linear,vertical,{v!r},{u!r}\n"
                for (d, a, f), v, u in zip(points, vs, us, strict=True)
            )


def run(argv: list[str]) -> Run:
    """One child process: wall time, CPU time, its own peak RSS."""
    env = {**os.environ, "PYTHONHASHSEED": "0"}
    started = time.perf_counter()
    proc = subprocess.Popen(
        [sys.executable, "-c", CHILD, *argv], cwd=ROOT, env=env,
        stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    stderr = proc.stderr.read() if proc.stderr else ""
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - started
    proc.returncode = os.waitstatus_to_exitcode(status)
    lines = stderr.splitlines()
    peak = next((int(x.split()[1]) for x in lines if x.startswith("peak-rss-kib")), 0)
    rest = "\n".join(x for x in lines if not x.startswith("peak-rss-kib"))
    return Run(wall, usage.ru_utime + usage.ru_stime, peak / 1024, proc.returncode, rest)


def check_outputs(a_path: Path, b_path: Path, n_rows: int) -> str:
    """(a) has a record per result; its En agrees with pt13528's (b), same rows."""
    import orjson

    a, b = orjson.loads(a_path.read_bytes()), orjson.loads(b_path.read_bytes())
    assert len(a["scores"]) == len(b["scores"]) == n_rows

    def key(s: dict) -> tuple:
        return (s["lab"], s["device"], s["axis"], float(s["frequency_hz"]))

    en_b = {key(s): s["en"] for s in b["scores"]}
    diff = max(abs(s["en"] - en_b[key(s)]) for s in a["scores"])
    assert diff < 1e-6, diff
    return f"outputs checked: {n_rows:,} score records each, max |En(a) - En(b)| = {diff:.1e}"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--rows", type=int, default=200_000, help="results (100 per lab)")
    parser.add_argument("--repeat", type=int, default=3, help="rounds; the best is reported")
    parser.add_argument("--only", choices=["a", "b", "c"], action="append",
                        help="run only these processes (repeatable)")  # fmt: skip
    args = parser.parse_args()
    n_labs = max(args.rows // 100, 1)
    only = args.only or ["a", "b", "c"]
    with tempfile.TemporaryDirectory(prefix="bench-pt-compare-") as tmp:
        folder = Path(tmp)
        table = folder / "round.csv"
        started = time.perf_counter()
        write_file(table, n_labs)
        n_rows = n_labs * 100
        print(f"file: {n_labs:,} labs × 100 points = {n_rows:,} rows, "
              f"{table.stat().st_size / 2**20:.1f} MiB, written in "
              f"{time.perf_counter() - started:.1f} s")  # fmt: skip
        (folder / "naive.py").write_text(NAIVE)
        (folder / "floor.py").write_text(FLOOR)
        out = {k: folder / f"out-{k}.json" for k in "abc"}
        commands = {
            "a": ["manage.py", "pt_compare", str(table), "--assigned", "algorithm-a",
                  "--format", "json", "--output", str(out["a"])],
            "b": [str(folder / "naive.py"), str(table), str(out["b"])],
            "c": [str(folder / "floor.py"), str(table), str(out["c"])],
        }  # fmt: skip
        runs: dict[str, list[Run]] = {k: [] for k in only}
        for r in range(args.repeat):
            for k in only:  # interleaved: each round sees the same load
                result = run(commands[k])
                if result.status != 0:
                    sys.exit(f"({k}) failed with status {result.status}:\n{result.stderr}")
                runs[k].append(result)
                print(f"  round {r + 1} ({k}): {result.wall:.2f} s wall, {result.cpu:.2f} s CPU, "
                      f"peak RSS {result.peak_mib:.0f} MiB")  # fmt: skip
        if runs.get("a") and runs["a"][0].stderr:
            print(f"  (a) wrote on stderr: {runs['a'][0].stderr[:200]!r}")
        if "a" in only and "b" in only and n_rows <= 300_000:
            print("  " + check_outputs(out["a"], out["b"], n_rows))
        report(runs, n_rows)


def report(runs: dict[str, list[Run]], n_rows: int) -> None:
    names = {"a": "(a) manage.py pt_compare", "b": "(b) pt13528 script",
             "c": "(c) floor: pandas + orjson"}  # fmt: skip
    best = {k: min(v, key=lambda r: r.wall) for k, v in runs.items()}
    cpu = {k: min(r.cpu for r in v) for k, v in runs.items()}
    peak = {k: max(r.peak_mib for r in v) for k, v in runs.items()}
    print(f"\n{n_rows:,} rows, best of {len(next(iter(runs.values())))}:")
    for k in runs:
        print(f"  {names[k]:30} {best[k].wall:6.2f} s wall  {cpu[k]:6.2f} s CPU  "
              f"peak RSS {peak[k]:5.0f} MiB")  # fmt: skip
    if "a" in runs and "b" in runs:
        verdict = "PASS" if best["a"].wall <= 0.5 * best["b"].wall else "FAIL"
        print(f"  (a)/(b) = {best['a'].wall / best['b'].wall:.2f} wall, "
              f"{cpu['a'] / cpu['b']:.2f} CPU   target ≤ 0.5: {verdict}")  # fmt: skip
    if "a" in runs and "c" in runs:
        verdict = "PASS" if best["a"].wall <= 2 * best["c"].wall else "FAIL"
        print(f"  (a)/(c) = {best['a'].wall / best['c'].wall:.2f} wall, "
              f"{cpu['a'] / cpu['c']:.2f} CPU   target ≤ 2: {verdict}")  # fmt: skip
    if "a" in runs:
        limit = 400 if n_rows <= 200_000 else 1024
        verdict = "PASS" if peak["a"] <= limit else "FAIL"
        print(f"  peak RSS of (a) {peak['a']:.0f} MiB   target ≤ {limit} MiB: {verdict}")


if __name__ == "__main__":
    main()
