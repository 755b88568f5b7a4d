"""Homogeneity (ISO 13528:2022 B.3) against pt13528 and hand-checked edge cases."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from pt13528 import homogeneity as oracle

from analysis.core.groups import CoreInputError
from analysis.core.homogeneity import homogeneity

values = st.floats(100.0, 110.0, allow_nan=False)


@settings(max_examples=100, deadline=None)
@given(
    st.integers(2, 12).flatmap(
        lambda g: st.integers(2, 4).flatmap(
            lambda m: st.lists(
                st.lists(st.lists(values, min_size=m, max_size=m), min_size=g, max_size=g),
                min_size=1,
                max_size=4,
            )
        )
    ),
    st.floats(0.01, 10.0),
)
def test_matches_pt13528_point_by_point(data: list[list[list[float]]], sigma: float) -> None:
    h = homogeneity(data, sigma)
    for p, items in enumerate(data):
        ref = oracle.homogeneity(items, sigma_pt=sigma)
        for ours, theirs in (
            (h.mean[p], ref.mean), (h.s_x[p], ref.s_x), (h.s_w[p], ref.s_w),
            (h.s_s[p], ref.s_s), (h.criterion[p], ref.criterion),
            (h.expanded_criterion[p], ref.expanded_criterion),
        ):  # fmt: skip
            assert ours == pytest.approx(theirs, rel=1e-9, abs=1e-12)
        assert h.sufficient[p] == ref.sufficient
        assert h.sufficient_expanded[p] == ref.sufficient_expanded
        if ref.f_statistic is None:
            assert np.isnan(h.f_statistic[p])
        else:
            assert h.f_statistic[p] == pytest.approx(ref.f_statistic, rel=1e-9)


def test_identical_items_have_no_between_item_spread() -> None:
    # every item reads 1.0 then 3.0: s_w = sqrt(2), item means equal, s_s = 0
    h = homogeneity([[1.0, 3.0]] * 5, 1.0)
    assert h.s_s[0] == 0.0 and h.s_x[0] == 0.0
    assert h.s_w[0] == pytest.approx(np.sqrt(2.0))
    assert h.sufficient[0]


def test_bad_input_says_where() -> None:
    with pytest.raises(CoreInputError, match="point 0, item 2, replicate 1: not finite"):
        homogeneity([[1.0, 2.0], [np.nan, 2.0]], 1.0)
    with pytest.raises(CoreInputError, match="g items x m replicates"):
        homogeneity([[1.0], [2.0]], 1.0)
    with pytest.raises(CoreInputError, match="sigma_pt"):
        homogeneity([[1.0, 2.0], [1.0, 2.0]], 0.0)
