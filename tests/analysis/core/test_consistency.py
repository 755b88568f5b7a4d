"""ISO 5725-2 consistency statistics and the artefact stability check."""

from __future__ import annotations

import math
import tracemalloc

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from pt13528 import outliers as oracle

from analysis.core import consistency as c
from analysis.core.groups import CoreInputError, Groups


def test_single_grubbs_and_cochran_critical_values_match_pt13528() -> None:
    p = np.arange(3, 60)
    for alpha in (0.05, 0.01):
        ours = c.grubbs_critical(p, alpha)
        np.testing.assert_allclose(ours, [oracle.grubbs_critical(int(v), alpha) for v in p], 1e-12)
        for n in (2, 3, 5, 10):
            q = np.arange(2, 40)
            ref = [oracle.cochran_critical(int(v), n, alpha) for v in q]
            np.testing.assert_allclose(c.cochran_critical(q, n, alpha), ref, rtol=1e-12)


def test_critical_values_reproduce_iso_5725_2_tables() -> None:
    # Table 5 (Grubbs single), Table 4 (Cochran), Table 6 (Mandel h and k), printed values
    np.testing.assert_allclose(c.grubbs_critical([3, 10, 20], 0.01), [1.155, 2.482, 3.001], 0, 5e-4)
    np.testing.assert_allclose(c.grubbs_critical([3, 10, 20], 0.05), [1.155, 2.290, 2.709], 0, 1e-3)
    np.testing.assert_allclose(c.cochran_critical(3, 2, [0.01, 0.05][0]), 0.993, atol=5e-4)
    np.testing.assert_allclose(c.cochran_critical(3, 2, 0.05), 0.967, atol=5e-4)
    np.testing.assert_allclose(c.mandel_h_critical([3, 10], 0.01), [1.15, 2.18], atol=5e-3)
    np.testing.assert_allclose(c.mandel_h_critical([3, 10], 0.05), [1.15, 1.80], atol=5e-3)
    np.testing.assert_allclose(c.mandel_k_critical([3, 10], 2, 0.01), [1.71, 2.32], atol=5e-3)
    np.testing.assert_allclose(c.mandel_k_critical([3, 10], 2, 0.05), [1.65, 1.90], atol=5e-3)
    np.testing.assert_allclose(
        c.grubbs_double_critical([4, 10, 40], 0.05), [0.0002, 0.1864, 0.6445]
    )


def test_double_grubbs_table_agrees_with_simulation() -> None:
    # The table is two-sided: its 5 % (1 %) value is the one-sided 2.5 % (0.5 %) quantile.
    rng = np.random.default_rng(20240)
    for p in (5, 10, 25, 40):
        x = np.sort(rng.normal(size=(200_000, p)), axis=1)
        ss0 = ((x - x.mean(axis=1, keepdims=True)) ** 2).sum(axis=1)
        y = x[:, : p - 2]
        ratio = ((y - y.mean(axis=1, keepdims=True)) ** 2).sum(axis=1) / ss0
        q1, q5 = np.quantile(ratio, [0.005, 0.025])
        assert c.grubbs_double_critical(p, 0.01) == pytest.approx(q1, abs=0.006)
        assert c.grubbs_double_critical(p, 0.05) == pytest.approx(q5, abs=0.004)


def test_critical_value_input_errors() -> None:
    with pytest.raises(CoreInputError, match="p must be integers >= 3"):
        c.grubbs_critical(2, 0.05)
    with pytest.raises(CoreInputError, match="p <= 40"):
        c.grubbs_double_critical(41, 0.05)
    with pytest.raises(CoreInputError, match=r"alpha 0\.05 and 0\.01"):
        c.grubbs_double_critical(10, 0.1)
    with pytest.raises(CoreInputError, match="alpha"):
        c.cochran_critical(3, 2, 1.5)


values = st.lists(st.floats(-1e4, 1e4, allow_nan=False), min_size=3, max_size=45)


@settings(max_examples=120, deadline=None)
@given(st.lists(values, min_size=1, max_size=8))
def test_grubbs_matches_pt13528_and_naive_double(data: list[list[float]]) -> None:
    x = np.concatenate([np.asarray(d) for d in data])
    groups = Groups.from_index(np.repeat(np.arange(len(data)), [len(d) for d in data]))
    res = c.grubbs(x, groups)
    for g, d in enumerate(data):
        a = np.sort(np.asarray(d))
        if a.std(ddof=1) == 0 or a.max() == a.min():
            assert res.degenerate[g] and res.code_high[g] == 0
            continue
        hi, lo, crit = oracle.grubbs(d, 0.01)
        assert res.g_high[g] == pytest.approx(hi, rel=1e-9, abs=1e-9)
        assert res.g_low[g] == pytest.approx(lo, rel=1e-9, abs=1e-9)
        assert res.single_critical_1[g] == pytest.approx(crit, rel=1e-12)
        ss0 = ((a - a.mean()) ** 2).sum()
        if 4 <= a.size <= 40:
            two_hi, two_lo = a[:-2], a[2:]
            assert res.g_high2[g] == pytest.approx(
                ((two_hi - two_hi.mean()) ** 2).sum() / ss0, abs=1e-9
            )
            assert res.g_low2[g] == pytest.approx(
                ((two_lo - two_lo.mean()) ** 2).sum() / ss0, abs=1e-9
            )
        else:
            assert not res.double_tested[g] and res.code_high2[g] == 0


def test_grubbs_flags_a_gross_outlier_and_untestable_groups() -> None:
    x = [10.0, 10.1, 9.9, 10.05, 9.95, 10.02, 13.0, 1.0, 2.0]
    res = c.grubbs(x, Groups.from_index([0] * 7 + [1] * 2))
    assert res.code_high[0] == c.OUTLIER and res.code_low[0] == c.OK
    assert res.code_high2[0] in (c.OK, c.STRAGGLER, c.OUTLIER)
    assert not res.single_tested[1] and res.code_high[1] == 0
    assert math.isinf(res.single_critical_5[1]) and res.double_critical_5[1] == -math.inf


def test_classify_codes() -> None:
    codes = c.classify([1.0, 2.5, 3.5], 2.0, 3.0)
    assert list(codes) == [0, 1, 2]
    assert list(c.classify([0.5, 0.2, 0.05], 0.3, 0.1, lower=True)) == [0, 1, 2]
    assert list(c.classify([2.0, 3.0], 2.0, 3.0)) == [0, 1]  # at the critical value: not beyond


def _replicates(rng: np.random.Generator, n_groups: int, n_labs: int, n_rep: int):
    g = np.repeat(np.arange(n_groups), n_labs * n_rep)
    lab = np.tile(np.repeat(np.arange(n_labs), n_rep), n_groups)
    x = (
        rng.normal(100.0, 1.0, size=g.size)
        + rng.normal(0, 0.5, size=(n_groups, n_labs)).repeat(n_rep, axis=1).ravel()
    )
    return x, lab, Groups.from_index(g)


def test_mandel_h_k_against_naive_definition() -> None:
    rng = np.random.default_rng(11)
    x, lab, groups = _replicates(rng, 5, 8, 3)
    res = c.mandel(x, lab, groups)
    for gi in range(5):
        cells = [x[(groups.index == gi) & (lab == j)] for j in range(8)]
        means = np.array([v.mean() for v in cells])
        sds = np.array([v.std(ddof=1) for v in cells])
        h = (means - means.mean()) / means.std(ddof=1)
        k = sds * math.sqrt(8) / math.sqrt((sds**2).sum())
        sel = res.group == gi
        np.testing.assert_allclose(res.h[sel][np.argsort(res.lab[sel])], h, rtol=1e-10)
        np.testing.assert_allclose(res.k[sel][np.argsort(res.lab[sel])], k, rtol=1e-10)
    assert (res.p == 8).all() and (res.n == 3).all()
    np.testing.assert_allclose(res.h_critical_1, c.mandel_h_critical(8, 0.01))
    np.testing.assert_allclose(res.k_critical_5, c.mandel_k_critical(8, 3, 0.05))


def test_mandel_flags_a_biased_and_a_noisy_lab() -> None:
    rng = np.random.default_rng(5)
    x, lab, groups = _replicates(rng, 1, 10, 4)
    x = x.copy()
    x[lab == 3] += 10.0
    x[lab == 7] += rng.normal(0, 20.0, size=4)
    res = c.mandel(x, lab, groups)
    assert res.h_code[res.lab == 3][0] == c.OUTLIER
    assert res.k_code[res.lab == 7][0] == c.OUTLIER


def test_mandel_degenerate_and_untestable() -> None:
    x = [1.0, 1.0, 1.0, 1.0, 2.0, 2.0]
    res = c.mandel(x, [0, 0, 1, 1, 0, 1], Groups.from_index([0, 0, 0, 0, 1, 1]))
    assert res.degenerate_h[0] and res.degenerate_k[0]
    assert (res.h == 0).all() and (res.k == 0).all()
    assert not res.h_tested.any()  # only two labs per point
    assert (res.h_code == 0).all()


def test_cochran_matches_pt13528() -> None:
    rng = np.random.default_rng(2)
    x, lab, groups = _replicates(rng, 6, 7, 4)
    noisy = (lab == 2) & (groups.index == 0)
    x[noisy] += rng.normal(0.0, 15.0, size=int(noisy.sum()))
    res = c.cochran(x, lab, groups)
    for gi in range(6):
        var = [x[(groups.index == gi) & (lab == j)].var(ddof=1) for j in range(7)]
        for alpha, crit in ((0.01, res.critical_1), (0.05, res.critical_5)):
            ref_c, ref_crit, ref_i = oracle.cochran(var, 4, alpha)
            assert res.c[gi] == pytest.approx(ref_c, rel=1e-10)
            assert crit[gi] == pytest.approx(ref_crit, rel=1e-12)
            assert res.lab[gi] == ref_i
    assert res.code[0] == c.OUTLIER


def test_cochran_unbalanced_uses_most_frequent_cell_size() -> None:
    x = [1.0, 2.0, 1.0, 1.5, 3.0, 1.0, 1.2, 1.0, 1.1, 9.0]
    lab = [0, 0, 1, 1, 1, 2, 2, 3, 3, 4]
    res = c.cochran(x, lab, Groups.from_index([0] * 10))
    assert res.n[0] == 2 and res.p[0] == 4  # lab 4 has one result: no variance
    assert res.tested[0]


def test_consistency_bad_input() -> None:
    with pytest.raises(CoreInputError, match=r"x\[1\] must be finite"):
        c.mandel([1.0, np.nan], [0, 1], Groups.from_index([0, 0]))
    with pytest.raises(CoreInputError, match="no results"):
        c.cochran([1.0, 2.0], [0, 1], Groups.from_index([0, 0], n_groups=2))
    with pytest.raises(CoreInputError, match="same length"):
        c.mandel([1.0, 2.0], [0], Groups.from_index([0, 0]))


def test_stability_per_point() -> None:
    res = c.stability_check(
        before=[100.0, 100.0, 100.0],
        u_before=[0.1, 0.1, 0.1],
        after=[100.05, 100.2, 101.0],
        u_after=[0.1, 0.1, 0.1],
        sigma_pt=[0.2, 0.2, 0.2],
    )
    np.testing.assert_allclose(res.delta, [0.05, 0.2, 1.0], atol=1e-12)
    np.testing.assert_allclose(res.en, np.array([0.05, 0.2, 1.0]) / (2 * math.sqrt(0.02)))
    assert list(res.stable) == [True, True, False]  # 2nd: |D| > 0.3 sigma but En <= 1
    np.testing.assert_allclose(res.u_stab, [0.0, 0.0, 1.0 / math.sqrt(3)], atol=1e-12)


def test_stability_with_repeated_results_per_point() -> None:
    before = Groups.from_index([0, 0, 1, 1])
    after = Groups.from_index([0, 1, 1])
    res = c.stability_check(
        [1.0, 3.0, 10.0, 10.0], [0.1] * 4, [2.5, 10.0, 12.0], [0.1] * 3, 2.0, (before, after)
    )
    np.testing.assert_allclose(res.delta, [0.5, 1.0])
    assert list(res.stable) == [True, False]
    with pytest.raises(CoreInputError, match="u_before"):
        c.stability_check([1.0], [0.0], [1.0], [0.1], 1.0)
    with pytest.raises(CoreInputError, match="sigma_pt"):
        c.stability_check([1.0], [0.1], [1.0], [0.1], np.nan)


def test_combine_assigned_uncertainty() -> None:
    np.testing.assert_allclose(
        c.combine_assigned_uncertainty([3.0, 1.0], 4.0), [5.0, math.sqrt(17)]
    )
    np.testing.assert_allclose(c.combine_assigned_uncertainty(0.3, 0.0, [0.4]), [0.5])
    with pytest.raises(CoreInputError, match="u_hom"):
        c.combine_assigned_uncertainty(1.0, -1.0)


def test_grubbs_identical_values_are_degenerate_despite_rounding() -> None:
    """Found by hypothesis: three equal values whose float mean is off by one ulp."""
    v = 2731.352202471765
    res = c.grubbs(np.array([v, v, v]), Groups.from_index([0, 0, 0]))
    assert res.degenerate[0]
    assert res.g_high[0] == 0.0 and res.code_high[0] == 0 and res.code_low[0] == 0


@settings(max_examples=200, deadline=None)
@given(
    st.lists(st.tuples(st.integers(0, 4), st.integers(1, 9), st.booleans()), min_size=1,
             max_size=40)
)  # fmt: skip
def test_cell_mode_is_the_most_frequent_size_smallest_on_a_tie(
    cells_given: list[tuple[int, int, bool]],
) -> None:
    """Against a count in plain Python: per group, the n that occurs most often among the
    masked cells (the smallest on a tie; 0 where a group has none)."""
    group = np.array([g for g, _, _ in cells_given], dtype=np.intp)
    n = np.array([k for _, k, _ in cells_given], dtype=np.intp)
    mask = np.array([m for _, _, m in cells_given])
    cells = c.Cells(group, np.arange(group.size), n, np.zeros(group.size),
                    np.zeros(group.size), 5)  # fmt: skip
    expected = []
    for g in range(5):
        sizes = [int(k) for k, gg, m in zip(n, group, mask, strict=True) if gg == g and m]
        counts = {k: sizes.count(k) for k in sizes}
        expected.append(min(counts, key=lambda k: (-counts[k], k)) if counts else 0)
    assert c._cell_mode(cells, mask).tolist() == expected


def test_a_billion_repeats_cost_no_memory() -> None:
    """n up to 10⁹ is a valid number of repeats (docs/interfaces.md §1): the mode of the
    cell sizes is taken over the distinct sizes, never a table up to the largest (which
    asked numpy for 134 GiB in a service run)."""
    groups = Groups.from_index([0, 0, 0, 1, 1, 1])
    cells = c.cells_from_summaries(
        [1.0, 1.1, 1.2, 2.0, 2.1, 2.2], [0.1, 0.2, 0.1, 0.1, 0.3, 0.2],
        [10**9, 5, 5, 10**9, 10**9, 5], [0, 1, 2, 0, 1, 2], groups,
    )  # fmt: skip
    tracemalloc.start()  # numpy reports its buffers to tracemalloc
    try:
        mode = c._cell_mode(cells, np.ones(6, dtype=bool))
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert mode.tolist() == [5, 10**9]
    assert peak < 1_000_000  # bytes: a few small arrays (the table was 16 GB here)
    assert c.mandel_cells(cells).k.size == 6
