"""Benchmark of the vectorised core against per-result Python loops and pt13528.

A synthetic round: 10,000 labs × 100 measurement points = 1,000,000 results
(seeded RNG; sensitivities ~420 D/(m/s²), standard uncertainties 2–6, 1 % outliers).
Times, each the median of a few repeats:

  (a) weighted-mean assigned value + all scores (D, z, z′, ζ, En) of the round
  (b) ISO 13528 Algorithm A for all 100 points
  (c) the pairwise lab × lab En matrix of one point with 2,000 labs

and the same work done (1) by a straightforward per-result Python loop and
(2) by pt13528 (scalar scores per result; Algorithm A per point).  Slow baselines
run on a subsample and are extrapolated linearly; the output says so.  The
baselines also serve as a check: their numbers must agree with the core's.

Run from the repository root:  .venv/bin/python bench/bench_core.py [--quick]
"""

from __future__ import annotations

import argparse
import math
import statistics
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import TypeVar

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import pt13528  # the test oracle: used only here and in tests

from analysis.core.assigned import weighted_mean
from analysis.core.compatibility import pairwise_en
from analysis.core.groups import Groups
from analysis.core.robust import algorithm_a
from analysis.core.scores import Scores, compute_scores

N_LABS, N_POINTS, MATRIX_LABS = 10_000, 100, 2_000
T = TypeVar("T")
TARGETS = {"scores": 0.5, "algorithm_a": 1.0, "matrix": 0.2}
MIN_SPEEDUP = 20.0
BASELINE_REPEATS = 3  # the (subsampled) baselines: median of 3 after one warm-up


def make_round(seed: int = 20240727) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """x, u and point index of every result (point-major order, as a results table)."""
    rng = np.random.default_rng(seed)
    level = rng.uniform(415.0, 430.0, N_POINTS)  # true sensitivity of each point
    index = np.repeat(np.arange(N_POINTS), N_LABS)
    u = rng.uniform(2.0, 6.0, index.size)
    x = level[index] + rng.normal(0.0, 1.0, index.size) * u
    outliers = rng.random(index.size) < 0.01
    x[outliers] += rng.normal(0.0, 40.0, int(outliers.sum()))
    return x, u, index


def median_time(fn: Callable[[], T], repeats: int) -> tuple[float, T]:
    """Median wall time of ``repeats`` calls, and the last call's result."""
    times = []
    out = fn()  # warm-up (imports, caches), not timed
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times), out


# ---------------------------------------------------------------- (a) scores


def core_scores(x: np.ndarray, u: np.ndarray, index: np.ndarray) -> Scores:
    """The timed unit: groups, weighted-mean assigned values and all scores of the round."""
    groups = Groups.from_index(index, N_POINTS)
    av = weighted_mean(x, u, groups)
    return compute_scores(
        x,
        u,
        2 * u,
        groups,
        av.value,
        av.standard_uncertainty,
        sigma_pt=0.01 * av.value,
        contributes=av.included,
    )


def score_columns(s: Scores) -> np.ndarray:
    return np.stack([s.en, s.zeta, s.z, s.z_prime, s.d_percent, s.en_flag, s.performance_flag])


def _flag_z(score: float) -> int:
    a = abs(score)
    return 0 if a <= 2.0 else 1 if a < 3.0 else 2


def loop_scores(x: list[float], u: list[float], points: list[int]) -> list[tuple]:
    """Per-result Python doing the core's job: weighted mean (every result contributes,
    Cox 2002 correction), then per result D%, z, z′, ζ, En and their flags."""
    out = []
    for p in points:
        lo, hi = p * N_LABS, (p + 1) * N_LABS
        sw = swx = 0.0
        for i in range(lo, hi):
            w = 1.0 / (u[i] * u[i])
            sw += w
            swx += w * x[i]
        y, u2_y = swx / sw, 1.0 / sw
        sigma = 0.01 * y
        use_zp = math.sqrt(u2_y) > 0.3 * sigma
        for i in range(lo, hi):
            d = x[i] - y
            ud = math.sqrt(u[i] * u[i] - u2_y)
            en, zeta, z = d / (2 * ud), d / ud, d / sigma
            zp = d / math.sqrt(sigma * sigma + u2_y)
            perf = zp if use_zp else z
            en_flag = 0 if abs(en) <= 1.0 else 2
            out.append((en, zeta, z, zp, 100 * d / y, en_flag, _flag_z(perf)))
    return out


def pt_scores(x: np.ndarray, u: np.ndarray, points: list[int]) -> list[tuple]:
    """pt13528 has no weighted mean: numpy per point, then its scalar scores per result."""
    sc = pt13528.scores
    code = {"acceptable": 0, "warning": 1, "action": 2}
    out = []
    for p in points:
        xs, us = x[p * N_LABS : (p + 1) * N_LABS], u[p * N_LABS : (p + 1) * N_LABS]
        w = 1.0 / us**2
        y, u_y = float(np.sum(w * xs) / np.sum(w)), float(1.0 / math.sqrt(np.sum(w)))
        sigma = 0.01 * y
        use_zp = not sc.uncertainty_negligible(u_y, sigma_pt=sigma)
        for xi, ui in zip(xs.tolist(), us.tolist(), strict=True):
            uc = math.sqrt(ui * ui - u_y * u_y)  # pt13528 has no Cox correction: pass u(d)
            en = sc.en_score(xi, y, 2 * uc, 0.0)
            z, zp = sc.z_score(xi, y, sigma), sc.z_prime_score(xi, y, sigma, u_y)
            # pt13528 flags En at |En| >= 1 (ISO 9.7.2), the service at |En| > 1: same here
            en_flag = 0 if abs(en) <= 1.0 else 2
            perf = code[sc.classify_z(zp if use_zp else z)]
            pct = sc.percent_difference(xi, y)
            out.append((en, sc.zeta_score(xi, y, uc, 0.0), z, zp, pct, en_flag, perf))
    return out


# ----------------------------------------------------------- (b) Algorithm A


def core_algorithm_a(x: np.ndarray, index: np.ndarray) -> np.ndarray:
    av = algorithm_a(x, Groups.from_index(index, N_POINTS))
    return np.stack([av.value, av.diagnostics["s_star"]])


def loop_algorithm_a(x: list[float], points: list[int], rtol: float = 1e-10) -> list[tuple]:
    """Per-result Python Algorithm A (ISO 13528 C.3.1), same stopping rule as the core."""
    out = []
    for p in points:
        xs = x[p * N_LABS : (p + 1) * N_LABS]
        n = len(xs)
        srt = sorted(xs)
        xm = (srt[n // 2] + srt[(n - 1) // 2]) / 2
        dev = sorted(abs(v - xm) for v in xs)
        s = 1.483 * (dev[n // 2] + dev[(n - 1) // 2]) / 2
        for _ in range(500):
            lo, hi = xm - 1.5 * s, xm + 1.5 * s
            clipped = [lo if v < lo else hi if v > hi else v for v in xs]
            new_x = sum(clipped) / n
            new_s = 1.134 * math.sqrt(sum((v - new_x) ** 2 for v in clipped) / (n - 1))
            done = abs(new_x - xm) < rtol * new_s and abs(new_s - s) < rtol * new_s
            xm, s = new_x, new_s
            if done:
                break
        out.append((xm, s))
    return out


def pt_algorithm_a(x: np.ndarray, points: list[int]) -> list[tuple]:
    out = []
    for p in points:
        r = pt13528.robust.algorithm_a(x[p * N_LABS : (p + 1) * N_LABS])
        out.append((r.location, r.scale))
    return out


# -------------------------------------------------------- (c) pairwise matrix


def loop_matrix(x: list[float], big_u: list[float], rows: int) -> list[list[float]]:
    return [
        [abs(x[i] - x[j]) / math.sqrt(big_u[i] ** 2 + big_u[j] ** 2) for j in range(len(x))]
        for i in range(rows)
    ]


def pt_matrix(x: list[float], big_u: list[float], rows: int) -> list[list[float]]:
    en = pt13528.scores.en_score  # lab i against lab j as "reference" (its 10.7.1)
    return [[abs(en(x[i], x[j], big_u[i], big_u[j])) for j in range(len(x))] for i in range(rows)]


# ------------------------------------------------------------------ driver


def report(name: str, core_t: float, baselines: list[tuple[str, float, str]]) -> bool:
    """Absolute target, and the 20x target against the per-point baseline (pt13528 called
    point by point, the last baseline); the per-result loop ratio is printed for reference."""
    target = TARGETS[name]
    ok = core_t < target
    print(
        f"  core (vectorised)            {core_t * 1e3:10.1f} ms   target < {target:.1f} s: "
        f"{'PASS' if ok else 'FAIL'}"
    )
    for i, (label, t, note) in enumerate(baselines):
        ratio = t / core_t
        judged = i == len(baselines) - 1
        passed = ratio >= MIN_SPEEDUP
        ok &= passed or not judged
        verdict = f"target >= {MIN_SPEEDUP:.0f}x: {'PASS' if passed else 'FAIL'}"
        print(f"  {label:<28} {t * 1e3:10.1f} ms   {note}")
        print(f"  {'':<28} speed-up {ratio:8.1f}x   {verdict if judged else '(reference)'}")
    return ok


def bench_scores(x: np.ndarray, u: np.ndarray, index: np.ndarray, sub: int, reps: int) -> bool:
    print(f"(a) weighted mean + D%, z, z', zeta, En, flags: {x.size:,} results, {N_POINTS} points")
    t_core, core = median_time(lambda: core_scores(x, u, index), reps)
    groups = Groups.from_index(index, N_POINTS)
    t_wm, av = median_time(lambda: weighted_mean(x, u, groups), reps)
    t_sc, _ = median_time(
        lambda: compute_scores(
            x,
            u,
            2 * u,
            groups,
            av.value,
            av.standard_uncertainty,
            sigma_pt=0.01 * av.value,
            contributes=av.included,
        ),
        reps,
    )
    print(
        f"  parts (Groups prebuilt): weighted_mean {t_wm * 1e3:.1f} ms, "
        f"compute_scores {t_sc * 1e3:.1f} ms"
    )
    pts = list(range(sub))
    xl, ul = x.tolist(), u.tolist()
    t_loop, loop = median_time(lambda: loop_scores(xl, ul, pts), BASELINE_REPEATS)
    t_pt, pt = median_time(lambda: pt_scores(x, u, pts), BASELINE_REPEATS)
    n = sub * N_LABS
    for label, other in (("loop", loop), ("pt13528", pt)):
        diff = np.abs(np.asarray(other).T - score_columns(core)[:, :n]).max()
        print(f"  check: core vs {label} on {n:,} results, max |diff| = {diff:.2e}")
        assert diff < 1e-8, f"core and {label} scores disagree"
    f = N_POINTS / sub
    note = f"(measured on {sub} of {N_POINTS} points, extrapolated x{f:g})"
    return report(
        "scores",
        t_core,
        [
            ("per-result Python loop", t_loop * f, note),
            ("pt13528, result by result", t_pt * f, note),
        ],
    )


def bench_algorithm_a(x: np.ndarray, index: np.ndarray, sub: int, reps: int) -> bool:
    print(f"(b) Algorithm A at {N_POINTS} points x {N_LABS:,} labs")
    t_core, core = median_time(lambda: core_algorithm_a(x, index), reps)
    t_pt, pt = median_time(lambda: pt_algorithm_a(x, list(range(N_POINTS))), BASELINE_REPEATS)
    xl = x.tolist()
    t_loop, loop = median_time(lambda: loop_algorithm_a(xl, list(range(sub))), BASELINE_REPEATS)
    c = np.asarray(core)
    print(
        f"  check: core vs pt13528, max |diff| x* = {np.abs(np.asarray(pt).T - c).max():.2e}"
        f"; core vs loop = {np.abs(np.asarray(loop).T - c[:, :sub]).max():.2e}"
    )
    assert np.allclose(np.asarray(pt).T, c, rtol=1e-8), "core and pt13528 Algorithm A disagree"
    f = N_POINTS / sub
    return report(
        "algorithm_a",
        t_core,
        [
            (
                "per-result Python loop",
                t_loop * f,
                f"(measured on {sub} of {N_POINTS} points, extrapolated x{f:g})",
            ),
            ("pt13528, point by point", t_pt, f"(all {N_POINTS} points)"),
        ],
    )


def bench_matrix(x: np.ndarray, u: np.ndarray, rows: int, reps: int) -> bool:
    print(f"(c) pairwise En matrix, one point, {MATRIX_LABS:,} x {MATRIX_LABS:,} labs")
    xs, big_u = x[:MATRIX_LABS].copy(), 2 * u[:MATRIX_LABS]
    t_core, core = median_time(lambda: pairwise_en(xs, big_u), reps)
    xl, ul = xs.tolist(), big_u.tolist()
    t_loop, loop = median_time(lambda: loop_matrix(xl, ul, rows), BASELINE_REPEATS)
    t_pt, pt = median_time(lambda: pt_matrix(xl, ul, rows), BASELINE_REPEATS)
    c = np.asarray(core)[:rows]
    print(
        f"  check: max |diff| core vs loop = {np.abs(np.asarray(loop) - c).max():.2e}, "
        f"vs pt13528 = {np.abs(np.asarray(pt) - c).max():.2e}"
    )
    assert np.allclose(loop, c, rtol=1e-12) and np.allclose(pt, c, rtol=1e-12)
    f = MATRIX_LABS / rows
    note = f"(measured on {rows} of {MATRIX_LABS} rows, extrapolated x{f:g})"
    return report(
        "matrix",
        t_core,
        [
            ("per-pair Python loop", t_loop * f, note),
            ("pt13528 en_score per pair", t_pt * f, note),
        ],
    )


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="smaller baseline subsamples")
    ap.add_argument("--repeats", type=int, default=5, help="repeats of the core timings")
    args = ap.parse_args()
    sub_points, alg_points, rows = (2, 1, 50) if args.quick else (10, 5, 200)
    print(
        f"python {sys.version.split()[0]}, numpy {np.__version__}, "
        f"pt13528 {pt13528.__version__}; median of {args.repeats} repeats (core) and "
        f"{BASELINE_REPEATS} (baselines), each after one untimed warm-up call\n"
    )
    t0 = time.perf_counter()
    x, u, index = make_round()
    print(f"round generated: {x.size:,} results in {time.perf_counter() - t0:.2f} s\n")
    ok = bench_scores(x, u, index, sub_points, args.repeats)
    print()
    ok &= bench_algorithm_a(x, index, alg_points, args.repeats)
    print()
    ok &= bench_matrix(x, u, rows, args.repeats)
    print(f"\noverall: {'PASS' if ok else 'FAIL'}")
    return 0 if ok else 1


if __name__ == "__main__":
    raise SystemExit(main())
