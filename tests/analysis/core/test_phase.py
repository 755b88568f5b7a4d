"""Phases on the circle (docs/domain.md §12): the wrap into (−180°, 180°] and the circular
consensus against hand cases, scipy's circmean and a brute-force search of the centre."""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import stats

from analysis.core import phase
from analysis.core.assigned import weighted_mean
from analysis.core.groups import CoreInputError, Groups
from common import quantities


@pytest.mark.parametrize(
    ("angle", "wrapped"),
    [(0.0, 0.0), (180.0, 180.0), (-180.0, 180.0), (190.0, -170.0), (-190.0, 170.0),
     (360.0, 0.0), (540.0, 180.0), (-540.0, 180.0), (359.5, -0.5), (720.25, 0.25),
     (-0.0, 0.0), (179.999, 179.999)],
)  # fmt: skip
def test_wrap_hand_cases(angle, wrapped):
    assert phase.wrap(angle) == pytest.approx(wrapped, abs=1e-12)


@settings(max_examples=300, deadline=None)
@given(st.floats(min_value=-1e6, max_value=1e6, allow_nan=False))
def test_wrap_is_in_range_and_the_same_angle(angle):
    w = float(phase.wrap(angle))
    assert -180.0 < w <= 180.0
    turns = (angle - w) / 360.0
    assert turns == pytest.approx(round(turns), abs=1e-9)


def _exact_wrap(angle: float) -> float:
    """The wrap in exact rational arithmetic: angle − 360·n, which a double holds exactly."""
    r = Fraction(angle) % 360
    return float(r - 360 if r > 180 else r)


@settings(max_examples=500, deadline=None)
@given(st.one_of(st.floats(allow_nan=False, allow_infinity=False),
                 st.floats(min_value=-1e3, max_value=1e3),
                 st.sampled_from([0.1, -0.1, 179.9, -179.9, 1e-30, -1e-300, 5e-324, 1e22,
                                  1e30, 359.99999999999994, -180.00000000000003])))  # fmt: skip
def test_wrap_is_exact_and_an_angle_in_range_comes_back_bit_for_bit(angle):
    """Shifting by 180° before the remainder rounded: 0.1 came back 0.0999999999999943, 1e-30
    came back 0 and 1e22 came back 100 (it is −80): every digit of a stored phase matters."""
    expected = _exact_wrap(angle)
    assert float(phase.wrap(angle)) == expected == quantities.wrap_degrees(angle)
    if -180.0 < angle <= 180.0:
        assert float(phase.wrap(angle)) == angle
    assert np.copysign(1.0, phase.wrap(angle)) == 1.0 or expected != 0.0  # −0 is 0


def test_an_infinite_phase_is_refused_nan_passes():
    with pytest.raises(CoreInputError, match="finite"):
        phase.wrap([1.0, np.inf])
    assert np.isnan(phase.wrap(np.nan))


def test_difference_is_the_short_way_round():
    assert phase.difference(-179.0, 179.0) == pytest.approx(2.0)
    assert phase.difference(179.0, -179.0) == pytest.approx(-2.0)
    assert phase.difference(10.0, -170.0) == pytest.approx(180.0)  # exactly opposite: +180


def test_circular_mean_agrees_with_scipy_circmean():
    rng = np.random.default_rng(7)
    centres = np.array([-178.0, 0.0, 95.0, 179.5])
    x = np.concatenate([phase.wrap(c + rng.normal(0, 3, 9)) for c in centres])
    groups = Groups.from_index(np.repeat(np.arange(4), 9))
    got = phase.circular_mean(x, groups)
    for g in range(4):
        ref = stats.circmean(x[groups.index == g], high=180.0, low=-180.0)
        assert phase.difference(got.mean[g], ref) == pytest.approx(0.0, abs=1e-9)
        ref_r = 1 - stats.circvar(np.deg2rad(x[groups.index == g]))
        assert got.resultant_length[g] == pytest.approx(ref_r, rel=1e-12)


def test_a_consensus_across_plus_minus_180_is_near_180_not_near_0():
    """Two labs at ±179°, one at 178°: the linear mean would say 59°."""
    x = np.array([179.0, -179.0, 178.0])
    u = np.array([0.5, 0.5, 0.5])
    groups = Groups.from_index([0, 0, 0])
    unwrapped, _ = phase.unwrap_groups(x, groups)
    assert unwrapped.tolist() == pytest.approx([179.0, 181.0, 178.0])
    av = weighted_mean(unwrapped, u, groups)
    assert float(phase.wrap(av.value[0])) == pytest.approx((179 + 181 + 178) / 3)
    d = phase.difference(x, phase.wrap(av.value[0]))
    assert d.tolist() == pytest.approx([-0.3333333, 1.6666667, -1.3333333], abs=1e-6)
    assert float(np.sum(d)) == pytest.approx(0.0, abs=1e-9)  # the wrapped D sum to zero


def test_the_unwrapped_centre_minimises_the_squared_wrapped_deviations():
    """Brute force over the circle (0.001° grid): the mean of the unwrapped phases is the
    angle with the least Σ wrap(x − c)², as far as a half circle holds the results."""
    rng = np.random.default_rng(3)
    for centre in (-179.9, -90.0, 0.5, 179.0):
        x = phase.wrap(centre + rng.uniform(-40, 40, 12))
        unwrapped, _ = phase.unwrap_groups(x, Groups.from_index(np.zeros(12, dtype=int)))
        grid = np.arange(-180.0, 180.0, 0.001)
        cost = (phase.difference(x[None, :], grid[:, None]) ** 2).sum(axis=1)
        best = grid[np.argmin(cost)]
        assert phase.difference(unwrapped.mean(), best) == pytest.approx(0.0, abs=1e-3)


def test_phases_in_every_direction_have_no_consensus():
    x = np.array([0.0, 90.0, 180.0, -90.0])
    with pytest.raises(CoreInputError, match="every direction"):
        phase.unwrap_groups(x, Groups.from_index([0, 0, 0, 0]))


def test_weights_steer_the_circular_mean():
    groups = Groups.from_index([0, 0])
    got = phase.circular_mean([170.0, -170.0], groups, weights=[3.0, 1.0])
    s, c = (
        3 * np.sin(np.deg2rad(170)) + np.sin(np.deg2rad(-170)),
        3 * np.cos(np.deg2rad(170)) + np.cos(np.deg2rad(-170)),
    )
    assert got.mean[0] == pytest.approx(np.rad2deg(np.arctan2(s, c)))
    with pytest.raises(CoreInputError, match="weights"):
        phase.circular_mean([1.0, 2.0], groups, weights=[1.0, -1.0])
