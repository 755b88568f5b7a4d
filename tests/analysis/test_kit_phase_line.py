"""A kit round's phase observations on a line (docs/domain.md §14, analysis/kit_phase.py):
unwrapped about their common circular mean, the spread measured there, a point spread over
more than 90° or pointing every way refused with its reason; other points untouched."""

from __future__ import annotations

import numpy as np
import pytest

from analysis.kit_link import PointLink
from analysis.kit_phase import on_line, wrap_link


def test_results_and_measurements_share_one_centre_and_others_stay_as_given():
    results = np.array([179.0, -179.5, 418.25, 178.5])
    measurements = np.array([-178.0, 419.0])
    line = on_line(results, np.array([0, 0, 1, 0]), measurements, np.array([0, 1]),
                   np.array([True, False]))  # fmt: skip
    assert line.results.tolist() == pytest.approx([179.0, 180.5, 418.25, 178.5], abs=1e-12)
    assert line.results[2] == 418.25 and line.measurements[1] == 419.0  # bit for bit
    assert line.measurements[0] == pytest.approx(182.0, abs=1e-12)
    assert line.spread[0] == pytest.approx(3.5, abs=1e-12) and np.isnan(line.spread[1])
    assert line.refused.tolist() == [False, False]
    assert line.note(0, 2) is None


def test_a_spread_over_90_or_no_centre_is_refused_and_said():
    results = np.array([10.0, 12.0, 0.0, 120.0, -120.0])
    line = on_line(results, np.array([0, 0, 1, 1, 1]), np.array([110.0]), np.array([0]),
                   np.array([True, True]))  # fmt: skip
    assert line.spread[0] == pytest.approx(100.0, abs=1e-12)
    assert line.refused.tolist() == [True, True]
    assert line.note(0, 2) == (
        "its phases spread over 100° about their circular mean, more than 90°: on a line "
        "they need not be the same angles, so the point is not drift-corrected nor linked "
        "across kits; its scores are against the round's assigned value"
    )
    assert line.note(1, 1) == (
        "its phases point in every direction (mean resultant length 0), so the point is not "
        "drift-corrected; its scores are against the round's assigned value"
    )


def test_the_link_is_wrapped_back_onto_the_circle():
    linked = PointLink(d=[None, 181.0, -0.5], kit_values=[{"kit": "Kit A", "value": 180.5,
                                                          "u": 0.1}])  # fmt: skip
    wrap_link(linked)
    assert linked.d == [None, -179.0, -0.5]
    assert linked.kit_values == [{"kit": "Kit A", "value": -179.5, "u": 0.1}]
