"""Benchmark of the exact largest consistent subset (Cox 2007) on one measurement point.

For each round size N: N − 10 results from one normal population and 10 outliers 9 σ
away (seeded RNG, u uniform in 0.5–1.5), inconsistent as a whole. Times, each the
median of a few repeats:

  * ``sequential``: the sequential approximation (the baseline, measured in the same run);
  * ``exact``: the sweep of ``analysis.core.assigned._sweep_row`` (the default up to
    ``EXACT_MAX`` results), with its ratio to the baseline;
  * ``enumerate``: every subset (only at 20 results; the default up to ``EXHAUSTIVE_MAX``).

The sizes of the subsets found are printed too (the exact one is never smaller).

Run from the repository root:  .venv/bin/python bench/bench_lcs.py [--quick]
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from analysis.core.assigned import EXACT_MAX, largest_consistent_subset
from analysis.core.groups import Groups


def _median_time(fn, repeats: int) -> tuple[float, object]:
    times, out = [], None
    for _ in range(repeats):
        t = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t)
    return statistics.median(times), out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--quick", action="store_true", help="fewer sizes and repeats")
    args = parser.parse_args()
    sizes = (20, 100, 200) if args.quick else (20, 50, 100, 200, 300, 400, EXACT_MAX)
    repeats = 1 if args.quick else 3
    print(f"{'N':>5} {'sequential':>11} {'exact':>9} {'ratio':>7} {'enumerate':>10}  kept")
    for n in sizes:
        rng = np.random.default_rng(n)
        x = np.concatenate([rng.normal(0, 1, n - 10), rng.normal(9, 1, 10)])
        u = rng.uniform(0.5, 1.5, n)
        g = Groups.from_index(np.zeros(n, dtype=int))
        t_seq, seq = _median_time(
            lambda x=x, u=u, g=g: largest_consistent_subset(x, u, g, exhaustive_max=0, exact_max=0),
            repeats,
        )
        t_exact, exact = _median_time(
            lambda x=x, u=u, g=g: largest_consistent_subset(x, u, g, exhaustive_max=0), repeats
        )
        enum = "-"
        if n <= 20:
            t_enum, _ = _median_time(
                lambda x=x, u=u, g=g: largest_consistent_subset(x, u, g, exhaustive_max=20), repeats
            )
            enum = f"{t_enum:.4f} s"
        kept = f"{int(exact.included.sum())} (sequential {int(seq.included.sum())})"  # type: ignore[attr-defined]
        print(
            f"{n:>5} {t_seq:>9.4f} s {t_exact:>7.4f} s {t_exact / t_seq:>6.0f}x {enum:>10}  {kept}",
            flush=True,
        )


if __name__ == "__main__":
    main()
