"""Pooling per-point moments gives the §3 aggregates and matrices of the results themselves
(``analysis.core.pooled`` against ``analysis.core.compatibility``); no database."""

import itertools
import math

import numpy as np
import pytest

from analysis.core.compatibility import compatibility_matrices
from analysis.core.groups import CoreInputError, Groups
from analysis.core.pooled import (
    aggregate_moments,
    compatibility_matrices_pooled,
    moments,
    pool,
)


def test_two_points_pooled_by_hand():
    # point A: 1, 3 (u 0.1, 0.3); point B: 5 (u 0.2); one level holding both points
    x, u = np.array([1.0, 3.0, 5.0]), np.array([0.1, 0.3, 0.2])
    parts = moments(x, u, Groups.from_index([0, 0, 1], 2))
    assert parts.n.tolist() == [2, 1] and parts.m2.tolist() == [2.0, 0.0]
    agg = aggregate_moments(pool(parts, Groups.from_index([0, 0], 1)), k=2)
    # x̄ = 3, ū = 0.2, s² = (4 + 0 + 4) / 2 = 4: u = √(0.04 + 4), U = 2u
    assert agg.mean.tolist() == [3.0] and agg.n.tolist() == [3]
    assert agg.s[0] == pytest.approx(2.0, rel=1e-15)
    assert agg.expanded_uncertainty[0] == pytest.approx(2 * math.sqrt(4.04), rel=1e-15)


def test_a_single_result_has_no_spread():
    agg = aggregate_moments(moments([7.0], [0.5], Groups.from_index([0], 1)))
    assert (agg.s[0], agg.standard_uncertainty[0]) == (0.0, 0.5)


def test_moments_need_every_group_filled():
    with pytest.raises(CoreInputError, match="at least one result"):
        moments([1.0], [0.1], Groups.from_index([0], 2))


def random_round(seed: int = 3):
    """Points over device × axis × frequency × bench × direction; 1 to 9 labs each."""
    rng = np.random.default_rng(seed)
    keys = list(itertools.product(("D1", "D2", "D3"), ("X", "Y"), (5.0, 10.0, 80.0, 160.0),
                                  ("linear", "curvilinear"), ("+", "-")))  # fmt: skip
    n = rng.integers(1, 10, len(keys))
    point = np.repeat(np.arange(len(keys)), n)
    x = 420 + rng.normal(0, 2, point.size) + rng.normal(0, 1, len(keys))[point]
    u = rng.uniform(0.5, 3, point.size)
    cols = list(zip(*keys, strict=True))
    names = ("device", "axis", "frequency_hz", "bench", "direction")
    per_point = {c: np.array(v) for c, v in zip(names, cols, strict=True)}
    rows = {c: v[point] for c, v in per_point.items()} | {"value": x, "standard_uncertainty": u}
    return rows, per_point, moments(x, u, Groups.from_index(point, len(keys)))


@pytest.mark.parametrize(
    ("factor", "by"),
    [("axis", None), ("frequency", None), ("device", None), ("bench", None),
     ("direction", None), ("bench", ("device", "axis", "frequency"))],
)  # fmt: skip
def test_pooled_matrices_equal_the_matrices_of_the_rows(factor, by):
    rows, per_point, parts = random_round()
    direct = compatibility_matrices(rows, factor, by, limit=1.0)
    pooled = compatibility_matrices_pooled(per_point, parts, factor, by, limit=1.0)
    assert [(m.group, m.levels) for m in pooled] == [(m.group, m.levels) for m in direct]
    for p, d in zip(pooled, direct, strict=True):
        assert p.n.tolist() == d.n.tolist()
        np.testing.assert_allclose(p.value, d.value, rtol=1e-14)
        np.testing.assert_allclose(p.expanded_uncertainty, d.expanded_uncertainty, rtol=1e-12)
        np.testing.assert_allclose(p.en, d.en, rtol=1e-10, atol=1e-13)
        assert p.incompatible_pairs == d.incompatible_pairs


def test_pooling_in_parts_equals_pooling_at_once():
    """The parallel-variance identity: the moments of a union from its parts."""
    rows, _, _ = random_round(5)
    x, u = rows["value"], rows["standard_uncertainty"]
    halves = Groups.from_index((np.arange(x.size) >= x.size // 3).astype(int), 2)
    whole = moments(x, u, Groups.from_index(np.zeros(x.size, dtype=int), 1))
    joined = pool(moments(x, u, halves), Groups.from_index([0, 0], 1))
    assert joined.n.tolist() == whole.n.tolist()
    np.testing.assert_allclose(joined.sum_x, whole.sum_x, rtol=1e-15)
    np.testing.assert_allclose(joined.m2, whole.m2, rtol=1e-12)
    assert whole.m2[0] == pytest.approx(((x - x.mean()) ** 2).sum(), rel=1e-12)
